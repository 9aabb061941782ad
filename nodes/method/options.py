"""``MethodOptions``: everything that changes what the method computes, and each option's rule, stated once
here (``CHOICES``, ``RANGES``) for the API, the command line and the nodes to read."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.integrate import frankot_chellappa, masked_least_squares
from ..geometry.reflectance import light_tag
from ..photo.encoding import ENCODINGS
from ..photo.loader import MAX_WORK_PIXELS
from .relight import FRONTAL
from .robust_fit import FitConfig

INTEGRATORS = {"lsq": masked_least_squares, "fc": frankot_chellappa}
# novel_view.png's largest side (``--view-size``): the surface it shows is the fit's (128^2 by default, at most the
# largest model grid's 512^2), and rendering it costs memory and time with the square of the side, every face of a
# photo (one face at 2048: +1 GB and 10 s; a photo of 49 faces at 1024: 116 s, 1.0 GB; docs/faults.md)
MAX_VIEW_SIZE = 512


@dataclass(frozen=True)
class Range:
    """A numeric option's rule: ``lo`` to ``hi`` inclusive (None allowed when ``optional``); ``flag`` is the
    command line's name of it and ``says`` the rule in its words; the command line counts ``per`` of the
    option's units as one (``--max-megapixels``: 1e6 pixels)."""

    lo: float
    hi: float
    flag: str
    says: str
    per: float = 1.0
    optional: bool = False

    def check(self, name: str, value) -> None:
        """``ValueError`` naming the option and its flag when ``value`` breaks the rule."""
        if value is None and self.optional:
            return
        if isinstance(value, str) or not (self.lo <= float(value) <= self.hi):
            shown = value if isinstance(value, str) else f"{float(value) / self.per:g}"
            raise ValueError(f"{self.flag} {self.says}, not {shown} ({name})")


# every option of ``MethodOptions`` that is one of a few names, and those names, the default first: the
# options check against them and the command line offers them
CHOICES: dict[str, tuple[str, ...]] = {
    "integrator": tuple(INTEGRATORS),
    "remap": ("ratio", "peak"),
    "shadows": ("confirmed", "geometric"),
    "albedo_fill": ("ceiling", "mirror"),
    "encoding": ENCODINGS,
    "arrays": ("grid", "photo"),
}


# every numeric option of ``MethodOptions`` and its rule; the command line's flags and messages are these
RANGES: dict[str, Range] = {
    "eye_contrast": Range(0.0, 1.0, "--eye-contrast", "is between 0 (off) and 1"),
    "fill_detail": Range(0.0, 1.0, "--fill-detail", "is between 0 (off) and 1"),
    "mirror_lift": Range(0.0, 1.0, "--mirror-lift", "is between 0 (off) and 1"),
    "novel_yaw_deg": Range(-90.0, 90.0, "--view-angle", "turns the face by -90 to 90 degrees"),
    "novel_size": Range(32, MAX_VIEW_SIZE, "--view-size", f"is a side of 32 to {MAX_VIEW_SIZE} pixels (the fit's "
                        "surface holds no more detail)", optional=True),
    "max_pixels": Range(100_000, 40_000_000, "--max-megapixels", "is 0 (never reduce) or 0.1 to 40", per=1e6,
                        optional=True),
}
# ``face_length``: "auto", "off", or a stretch factor within this
FACE_LENGTH = Range(0.5, 2.0, "--face-length", "takes auto, off or a factor between 0.5 and 2")


@dataclass(frozen=True)
class MethodOptions:
    """Everything that changes what the method computes.

    light: "auto" | "yaleb" | a (3,) vector (input camera frame); a sidecar light wins.
    eyes: (2, 2) eye centres of the one face of every input, or None: a sidecar's, else every face
    found (``find_faces``, see ``photo.placement``), else (``find_faces`` False) the photo is taken
    as one frontal face framed like the model grid.
    """

    fit: FitConfig = field(default_factory=FitConfig)
    integrator: str = "lsq"
    remap: str = "ratio"  # brightness scale: "ratio" (median ratio to the mean face) or "peak" (the paper)
    shadows: str = "confirmed"  # "geometric": traced only (the paper); "confirmed": checked against the image
    # "ceiling": filled albedo no brighter than the face's typical measured albedo (``albedo.FILL_CEILING``);
    # "mirror": the paper's, mirrored values as measured
    albedo_fill: str = "ceiling"
    light: str | np.ndarray = "auto"
    eyes: np.ndarray | None = None
    find_faces: bool = True
    # the face's length (eye-to-mouth distance) against the model's: "auto" measures it from a found face's
    # landmarks when the model knows its mouth; "off" keeps the model's; a number is the stretch itself
    face_length: str | float = "auto"
    relight_light: np.ndarray = field(default_factory=lambda: FRONTAL.copy())  # input camera frame
    extra_lights: tuple[np.ndarray, ...] = ()  # more relit photos (``--relight``), input camera frame
    novel_yaw_deg: float = 45.0
    novel_size: int | None = None  # the novel view's side in pixels (None: the model grid's)
    # the lit eye's detail put into an eye a fill paints, at this contrast (``relight.eyes``); 0: off
    eye_contrast: float = 1.0
    # the detail the lit side of a frontal face shows, seen across its midline, put into the fill of its shadowed
    # side at this strength (``relight.face.FaceRelight``'s fill); 0: the fit's smooth map alone
    fill_detail: float = 1.0
    # the side of a frontal face its light reaches less: its albedo raised toward its mirror's level, at this
    # strength (``relight.albedo.mirror_raise``); 0: measured as it is
    mirror_lift: float = 1.0
    # shadows the face does not cast (a hat's brim, leaves, a hand) found and lifted under any light
    # (``relight.foreign``); off by default: on ordinary photos a smile's cheeks, a temple and stubble were taken for
    # them (docs/relighting.md, "Shadows from elsewhere")
    foreign_shadows: bool = False
    # larger photos are reduced to this many pixels when read (memory and time stay bounded); None: never
    max_pixels: int | None = MAX_WORK_PIXELS
    # how the photo's values relate to light (``photo.encoding``): "auto" (colour sRGB, grey linear), "srgb",
    # "linear"; the method works on linear light and writes images back in the photo's encoding
    encoding: str = "auto"
    # where a run writes the fit's arrays (normals.npy, weights.npy, depth.npy): "grid", the fit's model grid
    # with grid.json placing it on the photo, or "photo", the photo's pixel grid (what the method computes is
    # the same; the files differ, so a resumed run redoes its frames when this changes)
    arrays: str = "grid"
    # a clip's frames: each frame's own files written too (OUT/<stem>/frames/<index>/), not only the relit clips
    # and frames.jsonl (``--frames``)
    frames: bool = False

    @classmethod
    def paper(cls, **overrides) -> "MethodOptions":
        """The paper's variant, defined here once: its fit (``FitConfig.paper()``), its brightness scale
        (``remap="peak"``) and its albedo fill (``albedo_fill="mirror"``); ``overrides`` change any field.
        Cast shadows and the integrator keep their own switches (the paper's are ``shadows="geometric"``
        and ``integrator="fc"``)."""
        return cls(**{"fit": FitConfig.paper(), "remap": "peak", "albedo_fill": "mirror", **overrides})

    def __post_init__(self) -> None:
        """Every rule checked where it is stated (``CHOICES``, ``RANGES``): a bad option raises ``ValueError``
        naming it and its command-line flag, from the API as from the command line."""
        for name, allowed in CHOICES.items():
            if getattr(self, name) not in allowed:
                raise ValueError(f"{name} {getattr(self, name)!r}: choose from {', '.join(allowed)}")
        for name, rule in RANGES.items():
            rule.check(name, getattr(self, name))
        if self.face_length not in ("auto", "off"):
            FACE_LENGTH.check("face_length", self.face_length)
        self._check_lights()

    def _check_lights(self) -> None:
        if isinstance(self.light, str) and self.light not in ("auto", "yaleb"):
            raise ValueError(f"light {self.light!r}: auto, yaleb, two angles or a vector")
        tags = [light_tag(light) for light in self.extra_lights]
        for tag in set(tags):
            if tags.count(tag) > 1:
                raise ValueError(f"two relight lights are both {tag} (whole degrees): each writes relit_{tag}.png; "
                                 "give them a degree apart")
