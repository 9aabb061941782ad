"""The light the photo shows on one face, measured once in its box (docs/relighting.md, "The light the photo
shows"): its skin, the fitted shading with the room's light, the skin's expected albedo and the photo's own
shadows (``evidence``), handed on as ``lift.photo_light``; with how well each pixel's light is known and the
photo's shine.
"""
from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from ..photo.align import normals_to_input, scalar_to_input
from ..photo.encoding import linear_to_srgb
from ..photo.skin import MAX_CHROMA_DISTANCE, skin_distance, strands
from .albedo import expected_albedo, smooth_coarse
from .evidence import ShadowEvidence, shadow_evidence, shadow_gate
from .face_box import FaceBox
from .fields import blur, brightness, grow
from .foreign import foreign_shadows
from .lift import LIT_SHADING, exposure_target, photo_light, precision, signal, usable
from .shading import AMBIENT_RIM, AMBIENT_SIGMA, Shading, fit_ambient
from .shine import SHEEN_SCALE, glints, sheen

MATCH_SIGMA = 0.08  # the expected albedo is matched to the lit skin over this many interocular distances
# the fit's albedo map is smoothed over this many model pixels before it is brought to the photo (``smooth_coarse``)
COARSE_SMOOTH = 1.5
# what is dark by its make and never read as shadow: the eyes and brows grown by this many interocular distances
# (their ring of lids, lashes and socket), the lips and mouth by this
EYE_MARGIN = 0.1
MOUTH_MARGIN = 0.03
# how rough skin may be, against the lit skin's median (``skin.strands``), before it is taken for hair's strands or a
# beard
ROUGH = 2.5
# ... and what the fit took for hair over the forehead is skin in a shadow when no rougher than this (hair is strands)
COVER_SMOOTH = 1.5
ROUGH_FLOOR = 0.01  # the least texture (log brightness) lit skin is taken to have (a render's has none)
STRAND_FLOOR = 0.05  # of the skin's typical brightness, added before the log (``skin.strands``' floor)
# a dark pixel's colour is told over a Gaussian of this many interocular distances (it is noisy)
COLOUR_SCALE = 0.02
# on faces fewer photo pixels than this between the eyes, colour and strands are not resolved (a JPEG's colour at
# half resolution): all of the face is read as skin there
SKIN_MIN_IOD = 60.0
# the face's skin the photo shows lit, where the expected albedo is measured: at least this direct light, and out
# of the photo's shadows grown by this many interocular distances (their soft edges)
MEASURE_DIRECT = 0.5
MEASURE_CLEAR = 0.03
# a pixel's signal and whether it may be painted are told over this many interocular distances (a region's)
REGION_SIGMA = 0.02
# a face pixel the photo shows in shadow (``shadow.png``): in the photo's shadows this far, or turned from the light
SHADOW_MEMBERSHIP = 0.5
# a glint is this near a pixel with the skin's colour under its white; the eyes, brows, lips and mouth grown by
# this many interocular distances are theirs, not glints; nor is anything this near the face's edge
GLINT_REACH = 0.1
GLINT_FEATURE_MARGIN = 0.05
GLINT_EDGE = 0.1
# the model's normals take over where a shadow from elsewhere falls, fading out over this many interocular distances
FOREIGN_NORMALS = 0.03
# a shadow from elsewhere is followed into the fitted shape's gate no nearer the face's rim than this many
# interocular distances (``_foreign``)
FOREIGN_RIM = 0.15


class ShownLight:
    """The light the photo shows on one face, in its box ``at`` (``FaceBox``; (h, w) its pixels). normals: (Hm, Wm,
    3) the normals that explain the photo's shading (model camera frame, NaN off the face); lit: (Hm, Wm) bool, not
    in the fit's shadows; albedo: (Hm, Wm) the fit's albedo map; light: (3,) the photo's light, camera frame;
    iod_px: the face's interocular distance in photo pixels; encoding: the photo's file's ("srgb" or "linear"): its
    noise floor is read in it; hair: (Hm, Wm) bool, what the fit left out as covering the face's upper part, or
    None; hair_matte: the face's box ``(y0, y1, x0, x1)`` of the photo -> (h, w) how sure a hair segmentation is that
    each pixel there is hair, or None; model_normals: (Hm, Wm, 3) the fitted model's own normals (model camera
    frame), or None: given, the shadows the face does not cast are looked for against their shading, and they take
    the place of ``normals`` in them (None: none are looked for).

    ``normals`` (h, w, 3), ``light`` (3,) unit, ``direct`` (h, w) its direct light; ``skin`` and ``dark_by_make``
    (h, w) bool; ``shading`` (``Shading``), ``fitted`` (h, w) its lighting; ``expected`` (h, w, C) the skin's
    expected albedo; ``evidence`` (``ShadowEvidence``); ``photo_lighting`` (h, w, C) the light the photo shows;
    ``relative`` and ``usable`` (h, w) how well each pixel's light is known; ``lit_skin`` (h, w) bool and ``want``
    its exposure; ``shine`` (h, w, C); ``shadow`` (h, w) bool, the photo's shadows (``shadow.png``).
    """

    def __init__(self, at: FaceBox, normals: np.ndarray, lit: np.ndarray, albedo: np.ndarray, light: np.ndarray,
                 iod_px: float, encoding: str, hair: np.ndarray | None,
                 hair_matte: Callable[[tuple], np.ndarray] | None, model_normals: np.ndarray | None = None):
        self.at, self.iod = at, iod_px
        self.normals = np.nan_to_num(normals_to_input(normals, at.mask, at.al, at.shape)).astype(np.float32)
        s = np.asarray(light, np.float64)
        self.light = s / np.linalg.norm(s)
        self.direct = direct = np.clip(self.normals @ self.light.astype(np.float32), 0.0, None)
        self.skin = self._skin(hair, hair_matte, direct, iod_px)
        coarse = smooth_coarse(scalar_to_input(albedo, at.mask, at.al, at.shape), at.face,
                               COARSE_SMOOTH * max(at.al.scale, 1.0))
        fit_shadow = at.on_photo(~np.asarray(lit, bool))
        ambient = self._ambient(direct)
        model_n = None if model_normals is None else np.nan_to_num(
            normals_to_input(model_normals, at.mask, at.al, at.shape)).astype(np.float32)
        foreign = np.zeros(at.shape, bool) if model_n is None else self._foreign(model_n, fit_shadow, ambient)
        if foreign.any():
            # what the fit took for hair but is smooth skin in such a shadow (a brim's at the hairline) is read as skin
            self.skin = self.skin | (self.covered_smooth & grow(foreign, MEASURE_CLEAR * iod_px))
            # where a shadow from elsewhere falls, the normals that explained its darkness turned from the light to do
            # so: the model's own normals there say how the face is shaped
            self.normals = _blended(self.normals, model_n, foreign, FOREIGN_NORMALS * iod_px)
            self.direct = direct = np.clip(self.normals @ self.light.astype(np.float32), 0.0, None)
        gate = shadow_gate(fit_shadow, direct, at.face, iod_px)
        self.shading = Shading(self.normals, ambient, self.light)
        lighting = self.shading.lighting()
        self.expected, self.evidence = self._shadows(coarse, lighting, direct, gate, foreign)
        # the light the photo shows: the fitted shading, its shadows and its errors as the photo's skin shows them
        self.fitted = lighting
        self.photo_lighting = photo_light(self.evidence.lighting(lighting))
        self.encoding = encoding
        # how well each pixel's light is known, as a region's: a fill is a region's, not a speckle's (dark hairs among
        # lit skin left a lifted skin's pores beside painted ones)
        self.relative = precision(blur(_file_values(at.photo, encoding), max(REGION_SIGMA * iod_px, 1.0)), encoding)
        self.usable = signal(self.relative)
        self.lit_skin = self.skin & (direct >= LIT_SHADING) & (self.evidence.membership < SHADOW_MEMBERSHIP)
        self.foreign_lift = foreign_lift(self.evidence, lighting, self.photo_lighting)
        self.want = exposure_wanted(self, direct)
        self.shine = self._shine(iod_px)
        # the photo's shadows: the fitted shape's own under the photo's light (attached and cast: geometry, never a
        # beard's darkness) and those the photo shows beyond them (``evidence``)
        self.shadow = at.face & ((self.evidence.membership >= SHADOW_MEMBERSHIP) | fit_shadow)

    def _skin(self, hair: np.ndarray | None, hair_matte: Callable[[tuple], np.ndarray] | None,
              direct: np.ndarray, iod_px: float) -> np.ndarray:
        """(h, w) bool: the face's pixels whose darkness may be a shadow's: off the eyes, brows, lips and mouth, off
        hair (the fit's cover, the hair matte), smooth as skin is, of the skin's colour (in its shade too)."""
        at, f = self.at, self.at.features
        # (h, w) bool what the fit took for hair yet is skin-like, where the face is large enough to tell
        self.covered_smooth = None
        dark_by_make = at.outlined([*f.eyes, *f.brows], EYE_MARGIN * iod_px) | at.outlined(
            [*f.lips, *f.nostrils], MOUTH_MARGIN * iod_px)
        self.dark_by_make = dark_by_make
        out = at.face & ~dark_by_make & ~np.any(at.photo >= 0.995, axis=-1)
        covered = np.zeros(out.shape, bool)
        if hair is not None:
            covered = grow(at.on_photo(hair), max(at.al.scale, 1.0)) & out
            out &= ~covered
        if hair_matte is not None:
            out &= hair_matte(at.box) < 0.5
        if iod_px < SKIN_MIN_IOD:
            return out
        texture = _roughness(at.photo, out, iod_px)
        out &= texture <= ROUGH
        # what the fit took for hair coming in over the forehead, yet is as smooth as the skin: a brim's shadow may
        # be (``_foreign`` reads it; the rest of the relighting does not)
        self.covered_smooth = covered & (texture <= COVER_SMOOTH)
        if at.photo.shape[-1] == 3:
            blurred = cv2.GaussianBlur(at.photo, (0, 0), max(COLOUR_SCALE * iod_px, 1.0))
            lit = out & (direct >= MEASURE_DIRECT)  # the skin's colour is the lit skin's
            of_skin = skin_distance(blurred, at.face, shade=True, keep_out=dark_by_make,
                                    reference=lit) < MAX_CHROMA_DISTANCE
            out &= of_skin
            self.covered_smooth &= of_skin
        return out

    def _foreign(self, normals: np.ndarray, fit_shadow: np.ndarray, ambient: float) -> np.ndarray:
        """(h, w) bool the shadows the face does not cast (``foreign.foreign_shadows``), read against the model's own
        normals' shading (``normals`` (h, w, 3)): the normals that explain the photo's shading explain part of such a
        shadow as the face turning from the light."""
        at = self.at
        if self.covered_smooth is None:  # a face too small to tell skin's texture from a beard's: none told
            return np.zeros(at.shape, bool)
        direct = np.clip(normals @ self.light.astype(np.float32), 0.0, None)
        # out of the fitted shape's own shadows and their margin (by its terminator and its nose's shadow the model's
        # shape is off, and its shading with it)
        gate = shadow_gate(fit_shadow, direct, at.face, self.iod)
        lighting = Shading(normals, ambient, self.light).lighting()
        # a region runs on into the gate, but not into the shape's own shadows nor along the face's rim, where the
        # fitted normals graze the view and the photo mixes in what is beyond
        rim = at.inside_distance < FOREIGN_RIM * self.iod
        return foreign_shadows(at.photo, lighting, self.skin | self.covered_smooth, gate, at.face,
                               self.iod, own=fit_shadow | rim)

    def _shadows(self, coarse: np.ndarray, lighting: np.ndarray, direct: np.ndarray, gate: np.ndarray,
                 foreign: np.ndarray) -> tuple[np.ndarray, ShadowEvidence]:
        """The skin's expected albedo (h, w, C) and the photo's shadows (``ShadowEvidence``; ``foreign`` (h, w) bool
        those the face does not cast, found already: a matched albedo follows them), twice: the second time the albedo
        is measured off the first time's shadows, whose darkness had pulled it down."""
        photo, face = self.at.photo, self.at.face
        if foreign.any():  # the fit's albedo map took their darkness for the skin's: the lit skin's there instead
            coarse = np.where(grow(foreign, MEASURE_CLEAR * self.iod), np.float32(np.nan), coarse)
        clear = self.skin & (direct >= MEASURE_DIRECT) & ~gate & ~grow(foreign, MEASURE_CLEAR * self.iod)
        expected = evidence = None
        for _ in range(2):
            measured = clear if evidence is None else clear & ~grow(evidence.membership > 0.5,
                                                                    MEASURE_CLEAR * self.iod)
            if measured.sum() < 50:  # a face lit all from the side: its lit skin, wherever it is
                measured = self.skin & (direct >= MEASURE_DIRECT)
            expected = expected_albedo(photo, lighting, measured, coarse, face, MATCH_SIGMA * self.iod)
            evidence = shadow_evidence(photo, expected, lighting, direct, self.skin, gate, face, self.iod, foreign)
            if not evidence.found:
                break
        return expected, evidence

    def _ambient(self, direct: np.ndarray) -> float:
        """The room's share of the light (``shading.fit_ambient``), on the skin more than ``AMBIENT_RIM`` inside the
        face (at its rim the fitted normals graze the view and the photo mixes in what is beyond)."""
        core = self.skin & (self.at.inside_distance > AMBIENT_RIM * self.iod)
        return fit_ambient(self.at.photo, direct, core, AMBIENT_SIGMA * self.iod)

    def _shine(self, iod_px: float) -> np.ndarray:
        """(h, w, C) the photo's shine, in light: on the skin and its glints, what rises over its local level."""
        at = self.at
        albedo = at.photo / self.photo_lighting
        white = np.zeros(at.shape, bool)
        if at.features.all:
            inside = at.inside_distance > GLINT_EDGE * iod_px
            white = glints(at.photo, self.skin, at.face & inside, SHEEN_SCALE * iod_px,
                           at.outlined(at.features.all, GLINT_FEATURE_MARGIN * iod_px), GLINT_REACH * iod_px)
        excess = sheen(albedo, self.skin | white, self.usable > 0.5, SHEEN_SCALE * iod_px)
        return (excess * self.photo_lighting).astype(np.float32)


def _blended(normals: np.ndarray, model_normals: np.ndarray, where: np.ndarray, sigma_px: float) -> np.ndarray:
    """(h, w, 3) float32 unit ``normals`` turned to ``model_normals`` (h, w, 3) on ``where`` (h, w) bool, fading out
    over ``sigma_px`` beyond it."""
    b = np.clip(2.0 * blur(where.astype(np.float32), max(sigma_px, 1.0)), 0.0, 1.0)[..., None]
    mixed = (np.float32(1.0) - b) * normals + b * model_normals
    length = np.linalg.norm(mixed, axis=-1, keepdims=True)
    return np.where(length > 1e-6, mixed / np.maximum(length, 1e-6), normals).astype(np.float32)


def _roughness(photo: np.ndarray, smooth_guess: np.ndarray, iod_px: float) -> np.ndarray:
    """(h, w) float32: how rough ``photo`` (h, w, C) is (``skin.strands``) against the median of the ``smooth_guess``
    (h, w) bool skin's: hair's strands and a beard are over ``ROUGH``."""
    lit_level = float(np.median(photo[smooth_guess].sum(axis=-1))) if smooth_guess.sum() > 50 else 1.0
    texture = strands(photo, iod_px, STRAND_FLOOR * lit_level)
    typical = float(np.median(texture[smooth_guess])) if smooth_guess.sum() > 50 else ROUGH_FLOOR
    return (texture / np.float32(max(typical, ROUGH_FLOOR))).astype(np.float32)


def foreign_lift(evidence: ShadowEvidence, lighting: np.ndarray, shown: np.ndarray) -> np.ndarray | None:
    """(h, w, C) float32: the light the photo would show without the shadows the face does not cast over the light it
    shows (``shown`` (h, w, C); ``lighting`` (h, w) the fitted shading); None without such shadows."""
    return evidence.without_foreign(lighting) / shown if evidence.foreign.any() else None


def exposure_wanted(shown: ShownLight, direct: np.ndarray) -> float | None:
    """The exposure a relit face takes (``lift.exposure_target``): the level of the photo's lit skin (``shown``'s
    ``lit_skin``); with shadows from elsewhere lifted (its ``foreign_lift``), at least that of the photo without them
    on the skin the light reaches (``direct`` (h, w) its direct light) lifted no further than the photo shows well
    (``lift.usable``), as a relit face's is met (``FaceRelight.relit``). A shade left unfound pulls the lit skin's
    level down with it (a face under leaves at 25 deg came back a fifth darker than the same photo without them), and
    darkens only: of the two, the brighter."""
    photo, lift = shown.at.photo, shown.foreign_lift
    want = exposure_target(photo, shown.lit_skin)
    if lift is None:
        return want
    shown_well = usable(shown.relative, brightness(lift), shown.encoding) > 0.9
    without = exposure_target(photo * lift, shown.skin & (direct >= LIT_SHADING) & shown_well)
    return max((v for v in (want, without) if v is not None), default=None)


def _file_values(photo: np.ndarray, encoding: str) -> np.ndarray:
    """(h, w) the brightness of ``photo`` (h, w, C) as its file holds it (encoded for an sRGB photo)."""
    grey = brightness(photo)
    return linear_to_srgb(grey) if encoding == "srgb" else grey
