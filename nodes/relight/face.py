"""One face of a photo relit in the box around it (plus the feather), as a function of arrays.

``FaceRelight`` measures once what every light shares: where the face is (``face_box.FaceBox``: the box's photo and
face, and the layer's box around it), the light the photo shows there (``shown_light.ShownLight``: the skin, the
fitted shading, the photo's shadows and the light it shows) and what a fill paints (``paint.Paint``: the albedo it
paints with, and where); and gives ``layer(light)`` for each light, a ``compose.FaceLayer``. The steps are the
modules of this package; this one says which arrays go where for one light.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..method.shadow import cast_margin, soft_cast
from ..photo.align import Alignment, scalar_to_input
from .albedo import LIFT_AXIS, LIFT_SIGMA, axis_distance, lifted, mirror_raise
from .compose import FaceLayer, inner_alpha
from .eyes import CONTRAST as EYE_CONTRAST
from .face_box import FaceBox, Features
from .fields import brightness, smoothstep
from .lift import (
    LIT_SHADING,
    brightened,
    exposure_gain,
    fill_weight,
    held_to_skin,
    relit_face,
    shadows_kept,
    smooth_change,
    usable,
)
from .light_colour import TINT_SIGMA, light_tint, tinted
from .live import LiveArrays, LiveFace, live_relight_data
from .paint import FILL_DETAIL, Paint
from .shine import shine_kept, shine_lobe
from .shown_light import ShownLight

FEATHER = 0.3  # the relit face's light fades into the photo over this many interocular distances
# what is not skin is brightened no more than the skin within this many interocular distances (``lift.held_to_skin``)
HELD_SIGMA = 0.05
# the fitted shape's change of light is averaged over this many interocular distances (``lift.smooth_change``)
CHANGE_SIGMA = 0.03


class FaceRelight:
    """One face relit in its box.

    photo: (H, W, C) float32 linear RGB (C = 3) or grey (C = 1) in [0, 1]; encoding: the photo's file's
    ("srgb" or "linear"): its noise floor is read in it. alignment: model pixel -> photo pixel. mask: (Hm, Wm)
    bool, the model's face. normals: (Hm, Wm, 3) the normals that explain the photo's shading (model camera frame,
    NaN off the face); lit: (Hm, Wm) bool, not in the fit's shadows; albedo: (Hm, Wm) the fit's albedo map;
    depth: (Hm, Wm) heights in model pixels. light: (3,) unit, the photo's light, camera frame. iod_px: the face's
    interocular distance in photo pixels. outline: (n, 2) the face's own outline in photo pixels, or None.
    eyes: (2, 2) the eyes' centres in photo pixels where a face mesh found them, else None (no eye detail in a
    fill). midline: (2, 2) two points of the face's vertical symmetry axis in photo pixels, or None; mirror: (N,) int
    a turned model's mirror map (``ShapeModel.mirror``), or None: how the face is seen across itself (neither: not
    at all); fill_detail: how far a fill takes what is seen so (0: none). features: the face's parts
    (``Features``), or None. segment: (h, w, C) linear photo -> (h, w) how sure a segmentation is that each pixel
    is the person, or None (the whole feather). hair: (Hm, Wm) bool, what the fit left out as covering the face's
    upper part, or None. hair_matte: the face's box ``(y0, y1, x0, x1)`` of the photo -> (h, w) how sure a hair
    segmentation is that each pixel there is hair, or None (no such model here). model_normals: (Hm, Wm, 3) the
    fitted model's own normals, or None (``shown_light.ShownLight``: they tell the shadows the face does not cast).

    Measured once: where the face is (``at``, a ``FaceBox``: ``box``, ``face``, ``layer_box``, ``layer_face``,
    ``layer_photo`` are its), the light the photo shows there (``shown_light``, a ``ShownLight``: ``shadow`` is its)
    and what a fill paints (``paint``, a ``Paint``: ``albedo``, ``seen`` are its).
    """

    def __init__(self, *, photo: np.ndarray, alignment: Alignment, mask: np.ndarray, normals: np.ndarray,
                 lit: np.ndarray, albedo: np.ndarray, depth: np.ndarray, light: np.ndarray, iod_px: float,
                 encoding: str = "linear", outline: np.ndarray | None = None, eyes: np.ndarray | None = None,
                 eye_contrast: float = EYE_CONTRAST, midline: np.ndarray | None = None,
                 fill_detail: float = FILL_DETAIL, mirror_lift: float = 1.0, mirror: np.ndarray | None = None,
                 features: Features | None = None,
                 segment: Callable[[np.ndarray], np.ndarray] | None = None, hair: np.ndarray | None = None,
                 hair_matte: Callable[[tuple], np.ndarray] | None = None,
                 model_normals: np.ndarray | None = None):
        self.mask, self.depth, self.iod = mask, depth, iod_px
        self.feather = FEATHER * iod_px
        self.made: dict[tuple, tuple] = {}  # per ``light_key`` relit: (h, w) its shading, (h, w) how far painted
        self.at = at = FaceBox(photo, alignment, mask, outline, segment, self.feather, features)
        self.box, self.face, self.layer_box, self.layer_face, self.layer_photo = (
            at.box, at.face, at.layer_box, at.layer_face, at.layer_photo)
        self.shown_light = sl = ShownLight(at, normals, lit, albedo, light, iod_px, encoding, hair, hair_matte,
                                           model_normals)
        self.paint = Paint(at, sl, eyes, eye_contrast, midline, mirror, fill_detail, iod_px)
        # (ratio, strength): how far the side lit less may be raised toward its mirror
        self.mirror_raise = _mirror_raise(at, sl, midline, mirror_lift, iod_px)
        self.shadow, self.seen, self.albedo = sl.shadow, self.paint.seen, self.paint.albedo
        # the colour of the light the photo shows against the lamp's (the room's in the shade): the light a change adds
        # is the lamp's
        self.tint = light_tint(at.photo, sl.skin & at.face, sl.photo_lighting, TINT_SIGMA * iod_px)
        self.alpha = inner_alpha(at.face, self.feather, at.inside_distance)
        self.layer_alpha = at.in_layer(self.alpha)
        self.report: dict[str, float] = {}

    def foreign_lift(self) -> np.ndarray | None:
        """(h, w, C) float32 on the layer's box: how much the shadows the face does not cast are lifted under any
        light (``ShownLight.foreign_lift``), 1 elsewhere; None without such shadows."""
        lift = self.shown_light.foreign_lift
        if lift is None:
            return None
        return self.at.in_layer(np.where(self.at.face[..., None], lift, np.float32(1.0)) - 1.0) + np.float32(1.0)

    def new_lighting(self, light: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(S', L'_u, k')`` (h, w) each for ``light`` (3,): the direct light less its cast shadow traced on the fit's
        surface, the lighting (with the room's light) without that shadow, and the share of it the shadow leaves."""
        at, shading = self.at, self.shown_light.shading
        s = np.asarray(light, np.float64) / np.linalg.norm(light)
        # the ray's margin under the surface, interpolated from the model grid and thresholded on the photo's, so the
        # shadow's edge runs smoothly between model pixels
        margin = cast_margin(self.depth, at.al.vector_to_model(s))
        cast = soft_cast(scalar_to_input(margin, self.mask, at.al, at.shape))
        unshadowed = shading.lighting(s)
        shadowed = shading.lighting(s, cast)
        return (np.float32(1.0) - cast) * shading.direct(s), unshadowed, shadowed / unshadowed

    def relit(self, light: np.ndarray) -> np.ndarray:
        """(h, w, C) the face's box relit by ``light`` (3,), camera frame, exposed as the photo's lit skin: the photo
        times the change of light (``lift``): the new light's over the light the photo shows, its coarse part
        smoothed, its fine part the photo's own (a shadow's edge as the photo has it), and the new light's cast
        shadow; under nearly the photo's own light, the photo as it is (``lift.shadows_kept``)."""
        at, sl, p = self.at, self.shown_light, self.paint
        s = np.asarray(light, np.float64) / np.linalg.norm(light)
        direct, unshadowed, cast_share = self.new_lighting(s)
        new = brightened(unshadowed, sl.fitted, sl.evidence.correction)
        shown = sl.photo_lighting
        # the coarse part of the change averaged, the fine part the photo's own (a shadow's edge as the photo has it)
        smooth = smooth_change(shown, at.face, CHANGE_SIGMA * self.iod)
        change = smooth_change(new / smooth, at.face, CHANGE_SIGMA * self.iod) * (smooth / shown)
        same = np.float32(shadows_kept(sl.light, s))
        # kept as it is under the photo's own light but for the shadows the face does not cast, lifted under any
        kept = np.float32(1.0) if sl.foreign_lift is None else sl.foreign_lift
        g = same * kept + (np.float32(1.0) - same) * change * cast_share[..., None] * self._lifted(new)
        keep = shine_kept(brightness(shown), brightness(new) * cast_share, shine_lobe(sl.normals, sl.light, s))
        no_fill = np.zeros(at.shape, np.float32)
        unexposed = relit_face(at.photo, g, g, no_fill, sl.shine, keep)
        # the exposure (the photo's lit skin's, ``ShownLight.want``) is met on skin the new light lights and the photo
        # shows well enough to lift (a painted shadow's side is no level the photo measured)
        shown_well = usable(sl.relative, brightness(g), sl.encoding) > 0.9
        gain = exposure_gain(sl.want, unexposed, sl.skin & (direct >= LIT_SHADING) & shown_well)
        g = np.float32(gain) * g
        held = held_to_skin(brightness(g), at.photo, sl.skin, HELD_SIGMA * self.iod)
        g = g * held[..., None]
        lift = brightness(g)
        weight = fill_weight(usable(sl.relative, lift, sl.encoding), p.paintable_share)
        fill = p.fill if p.eyes is None else p.eyes.apply(p.fill, 1.0 - weight)
        self.made[light_key(s)] = (unshadowed * cast_share, weight)
        painted = np.float32(gain) * fill * new * (same + (np.float32(1.0) - same) * cast_share[..., None])
        self.report = {"exposure": gain, "painted": float(weight[at.face].mean()) if at.face.any() else 0.0,
                       "lift_p95": float(np.percentile(lift[at.face], 95)) if at.face.any() else 1.0}
        return relit_face(at.photo, tinted(g, self.tint), painted, weight, sl.shine, keep, fill)

    def _lifted(self, new: np.ndarray) -> np.ndarray | float:
        """(h, w, C) how much the side of the face the photo's light reaches less is raised toward its mirror's
        level (``albedo.mirror_raise``) as far as the new lighting ``new`` (h, w, C) brightens it; 1 without a
        midline."""
        if self.mirror_raise is None:
            return 1.0
        return lifted(*self.mirror_raise, brightness(new) / brightness(self.shown_light.photo_lighting))

    def layer(self, light: np.ndarray) -> FaceLayer:
        """The face relit by ``light`` (3,), camera frame, as a layer of the photo."""
        at = self.at
        relit = at.in_layer(np.clip(self.relit(light), 0.0, 1.0))
        return FaceLayer(at.layer_box, at.layer_face, relit, at.surround.gain(relit), self.layer_alpha)

    def live_data(self) -> LiveFace:
        """What the page needs to relight this face live (``live.live_relight_data``), on the layer's box: the face and
        the feather its change of light is carried over."""
        at, sl, p, in_layer = self.at, self.shown_light, self.paint, self.at.in_layer
        ones = np.ones_like(sl.photo_lighting)
        fill = p.fill if p.eyes is None else p.eyes.apply(p.fill, np.zeros(at.shape, np.float32))
        more = sl.fitted[..., None] * np.maximum(sl.evidence.correction - np.float32(1.0), 0.0)
        arrays = LiveArrays(
            photo=at.layer_photo, shown=in_layer(sl.photo_lighting - ones) + 1.0, more=in_layer(more),
            fill=in_layer(fill), normals=in_layer(sl.normals), relative=in_layer(sl.relative),
            paint=in_layer(p.paintable_share), face=at.layer_face, skin=in_layer(sl.skin) > 0,
            alpha=self.layer_alpha, beyond=at.layer_beyond, person=at.layer_person,
            raise_ratio=None if self.mirror_raise is None else in_layer(self.mirror_raise[0] - 1.0) + 1.0,
            raise_strength=None if self.mirror_raise is None else in_layer(self.mirror_raise[1]),
            shine=in_layer(sl.shine) if sl.shine.any() else None, foreign_lift=self.foreign_lift(),
            tint=None if self.tint is None else in_layer(self.tint - 1.0) + 1.0)
        y0, _, x0, _ = at.box
        ly0, _, lx0, _ = at.layer_box
        to_box = at.al.cropped(lx0 - x0, ly0 - y0).matrix
        return live_relight_data(at.layer_box, arrays, sl.want, sl.shading.ambient, sl.light, self.depth,
                                 self.mask, to_box, sl.encoding, self.feather, CHANGE_SIGMA * self.iod,
                                 HELD_SIGMA * self.iod)


def light_key(light: np.ndarray) -> tuple:
    """``light`` (3,) as a key: its direction, rounded."""
    return tuple(np.round(np.asarray(light, np.float64) / np.linalg.norm(light), 6))


def _mirror_raise(at: FaceBox, sl: ShownLight, midline: np.ndarray | None, mirror_lift: float,
                  iod_px: float) -> tuple[np.ndarray, np.ndarray] | None:
    """(ratio, strength) (h, w) each: how far the side of the face the photo's light reaches less may be raised toward
    its mirror (``albedo.mirror_raise``), as far as ``mirror_lift``; None without a ``midline`` (2, 2) photo pixels
    or a ``mirror_lift``."""
    if midline is not None and mirror_lift > 0:  # not beside the axis, where a pixel's mirror is its neighbour
        y0, _, x0, _ = at.box
        axis = np.asarray(midline, np.float64) - [x0, y0]
        off_axis = axis_distance(at.shape, axis) / np.float32(iod_px)
        reach = (np.float32(mirror_lift) * smoothstep(off_axis, 0.0, LIFT_AXIS) * at.face).astype(np.float32)
        return mirror_raise(at.photo / sl.photo_lighting, sl.skin.astype(np.float32), axis,
                            brightness(sl.photo_lighting), LIFT_SIGMA * iod_px, reach)
    return None
