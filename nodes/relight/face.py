"""One face of a photo relit in the box around it (plus the feather), as a function of arrays.

``FaceRelight`` measures once what every light shares (the box's photo, face, shading, the photo's shadows and
the light it shows, the albedo a fill paints with) and gives ``layer(light)`` for each light, a
``compose.FaceLayer``. Two boxes: the face's own (``box``: the face and ``INNER_MARGIN``), where the relit face is
made, and the layer's (``layer_box``: the face and its feather), where only the face's change of light is
carried into the photo around it (``compose.outside_gain``). The steps are the modules of this package; this one
says which arrays go where.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from ..geometry.raster import polygon_mask
from ..method.shadow import cast_margin, soft_cast
from ..photo.align import Alignment, face_box, mask_to_input, normals_to_input, scalar_to_input
from ..photo.encoding import linear_to_srgb
from ..photo.skin import MAX_CHROMA_DISTANCE, skin_distance, strands
from .albedo import (
    LIFT_AXIS,
    LIFT_SIGMA,
    axis_distance,
    expected_albedo,
    lifted,
    mirror_map,
    mirror_raise,
    mirrored,
    mirrored_detail,
    reflection_map,
    smooth_coarse,
)
from .compose import FaceLayer, inner_alpha, outside_gain
from .evidence import ShadowEvidence, shadow_evidence, shadow_gate
from .eyes import CONTRAST as EYE_CONTRAST
from .eyes import EyeDetail
from .fields import blur, brightness, distance_inside, grow, local_average, smoothstep
from .lift import (
    LIT_SHADING,
    brightened,
    exposure,
    exposure_target,
    fill_weight,
    held_to_skin,
    photo_light,
    precision,
    relit_face,
    shadows_kept,
    signal,
    smooth_change,
    usable,
)
from .live import LiveArrays, LiveFace, live_relight_data
from .shading import AMBIENT_RIM, AMBIENT_SIGMA, Shading, fit_ambient
from .shine import SHEEN_SCALE, glints, sheen, shine_kept, shine_lobe

FEATHER = 0.3  # the relit face's light fades into the photo over this many interocular distances
MATCH_SIGMA = 0.08  # the expected albedo is matched to the lit skin over this many interocular distances
MATCH_RANGE = (0.67, 1.5)  # ... and to the skin beside a fill within this range
# the fit's albedo map is smoothed over this many model pixels before it is brought to the photo (``smooth_coarse``)
COARSE_SMOOTH = 1.5
# a painted pixel takes the face's albedo seen across its midline at this strength (``MethodOptions.fill_detail``),
# fading in between these distances from its mirror (interocular distances: beside the axis a pixel's mirror is its
# neighbour)
FILL_DETAIL = 1.0
FILL_DETAIL_AXIS = (0.1, 0.4)  # (the old axis distances 0.05-0.2, doubled)
# ... on skin, only the band of it between these scales, in model pixels (finer is the other side's own pores)
FILL_DETAIL_BAND = (0.6, 1.5)
# everything but the feather is computed in the face's own box, grown by this many photo pixels
INNER_MARGIN = 4
# what is dark by its make and never read as shadow: the eyes and brows grown by this many interocular distances
# (their ring of lids, lashes and socket), the lips and mouth by this
EYE_MARGIN = 0.1
MOUTH_MARGIN = 0.03
# how rough skin may be, against the lit skin's median (``skin.strands``), before it is taken for hair's strands or a
# beard
ROUGH = 2.5
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
# what is not skin is brightened no more than the skin within this many interocular distances (``lift.held_to_skin``)
HELD_SIGMA = 0.05
# the fitted shape's change of light is averaged over this many interocular distances (``lift.smooth_change``)
CHANGE_SIGMA = 0.03
# a pixel's signal and whether it may be painted are told over this many interocular distances (a region's)
REGION_SIGMA = 0.02
# an eye is painted (with the lit eye's detail) when the median of its region's ``lift.precision`` is past this
DEEP_EYE = 0.15
# a face pixel the photo shows in shadow (``shadow.png``): in the photo's shadows this far, or turned from the light
SHADOW_MEMBERSHIP = 0.5
# a glint is this near a pixel with the skin's colour under its white; the eyes, brows, lips and mouth grown by
# this many interocular distances are theirs, not glints; nor is anything this near the face's edge
GLINT_REACH = 0.1
GLINT_FEATURE_MARGIN = 0.05
GLINT_EDGE = 0.1


@dataclass(frozen=True)
class Features:
    """A face's parts the face mesh drew, as photo-pixel outlines ((n, 2) each): ``eyes``, ``brows``, ``lips`` (the
    lips and the mouth's opening), ``nostrils``. Empty lists where no mesh drew them."""

    eyes: list
    brows: list
    lips: list
    nostrils: list = ()

    @property
    def all(self) -> list:
        return [*self.eyes, *self.brows, *self.lips, *self.nostrils]


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
    upper part, or None. hair_matte: (h, w, C) linear photo -> (h, w) how sure a hair segmentation is that each
    pixel is hair, or None (no such model here).
    """

    def __init__(self, *, photo: np.ndarray, alignment: Alignment, mask: np.ndarray, normals: np.ndarray,
                 lit: np.ndarray, albedo: np.ndarray, depth: np.ndarray, light: np.ndarray, iod_px: float,
                 encoding: str = "linear", outline: np.ndarray | None = None, eyes: np.ndarray | None = None,
                 eye_contrast: float = EYE_CONTRAST, midline: np.ndarray | None = None,
                 fill_detail: float = FILL_DETAIL, mirror_lift: float = 1.0, mirror: np.ndarray | None = None,
                 features: Features | None = None,
                 segment: Callable[[np.ndarray], np.ndarray] | None = None, hair: np.ndarray | None = None,
                 hair_matte: Callable[[np.ndarray], np.ndarray] | None = None):
        self.mask, self.depth, self.iod = mask, depth, iod_px
        self.feather = FEATHER * iod_px
        self._boxes(photo, alignment, mask, outline, segment)
        y0, y1, x0, x1 = self.box
        self.al = alignment.cropped(x0, y0)
        self.photo = np.atleast_3d(photo[y0:y1, x0:x1])
        self.shape = self.photo.shape[:2]
        self.face = face = self.layer_face[self.inner]
        self.features = features or Features([], [], [], [])
        self.normals = np.nan_to_num(normals_to_input(normals, mask, self.al, self.shape)).astype(np.float32)
        s = np.asarray(light, np.float64)
        self.light = s / np.linalg.norm(s)
        direct = np.clip(self.normals @ self.light.astype(np.float32), 0.0, None)
        self.skin = self._skin(hair, hair_matte, direct, iod_px)
        coarse = smooth_coarse(scalar_to_input(albedo, mask, self.al, self.shape), face,
                               COARSE_SMOOTH * max(self.al.scale, 1.0))
        fit_shadow = self._on_photo(~np.asarray(lit, bool), mask)
        gate = shadow_gate(fit_shadow, direct, face, iod_px)
        self.shading = Shading(self.normals, self._ambient(direct), self.light)
        lighting = self.shading.lighting()
        self.expected, self.evidence = self._shadows(coarse, lighting, direct, gate)
        # the light the photo shows: the fitted shading, its shadows and its errors as the photo's skin shows them
        self.fitted = lighting
        self.photo_lighting = photo_light(self.evidence.lighting(lighting))
        self.encoding = encoding
        # how well each pixel's light is known, as a region's: a fill is a region's, not a speckle's (dark hairs among
        # lit skin left a lifted skin's pores beside painted ones)
        self.relative = precision(blur(self._file_values(encoding), max(REGION_SIGMA * iod_px, 1.0)), encoding)
        self.usable = signal(self.relative)
        self.lit_skin = self.skin & (direct >= LIT_SHADING) & (self.evidence.membership < SHADOW_MEMBERSHIP)
        self.want = exposure_target(self.photo, self.lit_skin)
        self.shine = self._shine(iod_px)
        self.eyes = None if eyes is None else EyeDetail(self.photo, direct, np.asarray(eyes) - [x0, y0], eye_contrast)
        self.fill = self._fill_albedo(self._matched(self.expected), midline, mirror, fill_detail)
        # a fill paints the skin, an eye in a shadow as deep as the noise floor (with the lit eye's detail), and what the
        # face shows of itself across its midline (its own detail, mirrored); never a nostril, a pupil, a brow, lips or
        # a beard the photo does not show lit elsewhere: they are dark by their make, and lifted as the skin is
        self.paintable = self.skin | self._deep_eyes(iod_px) | (self.seen > 0.5)
        self.paintable_share = blur(self.paintable.astype(np.float32), max(REGION_SIGMA * iod_px, 1.0)) * face
        self.mirror_raise = None  # (ratio, strength): how far the side lit less may be raised toward its mirror
        if midline is not None and mirror_lift > 0:  # not beside the axis, where a pixel's mirror is its neighbour
            axis = np.asarray(midline, np.float64) - [x0, y0]
            off_axis = axis_distance(self.shape, axis) / np.float32(iod_px)
            reach = (np.float32(mirror_lift) * smoothstep(off_axis, 0.0, LIFT_AXIS) * face).astype(np.float32)
            self.mirror_raise = mirror_raise(self.photo / self.photo_lighting, self.skin.astype(np.float32), axis,
                                                  brightness(self.photo_lighting), LIFT_SIGMA * iod_px, reach)
        # the photo's shadows: the fitted shape's own under the photo's light (attached and cast: geometry, never a
        # beard's darkness) and those the photo shows beyond them (``evidence``)
        self.shadow = face & ((self.evidence.membership >= SHADOW_MEMBERSHIP) | fit_shadow)
        self.alpha = inner_alpha(face, self.feather, distance_inside(face))
        self.layer_alpha = self._in_layer(self.alpha)
        self.albedo = self._albedo()
        self.report: dict[str, float] = {}

    # -- what the photo shows --------------------------------------------------------------------------------------

    def _boxes(self, photo: np.ndarray, alignment: Alignment, mask: np.ndarray, outline: np.ndarray | None,
               segment: Callable[[np.ndarray], np.ndarray] | None) -> None:
        """The layer's box (the face and its feather: ``layer_box``, ``layer_photo``, ``layer_face``, its own skin
        beyond the model ``layer_beyond``, the person around it ``layer_person``) and, in it, the face's own box
        (``inner``; ``box`` in the photo), where the relit face is computed."""
        ly0, ly1, lx0, lx1 = face_box(mask, alignment, photo.shape[:2], margin=2.5 * self.feather + 4)
        self.layer_box = (ly0, ly1, lx0, lx1)
        self.layer_photo = np.atleast_3d(photo[ly0:ly1, lx0:lx1])
        layer_face = mask_to_input(mask, alignment.cropped(lx0, ly0), (ly1 - ly0, lx1 - lx0))
        self.layer_beyond = None  # the face's own skin the model does not reach (jaw, cheeks): relit as its rim
        if outline is not None:  # the face's own outline, at the photo's resolution
            own = polygon_mask(np.asarray(outline) - [lx0, ly0], layer_face.shape)
            self.layer_beyond = own & ~layer_face
            layer_face &= own
        self.layer_face = layer_face
        # where the person is around the face (hair, neck), not the background: the change of light reaches that far
        self.layer_person = None if segment is None else segment(self.layer_photo)
        rows, cols = np.nonzero(layer_face.any(axis=1))[0], np.nonzero(layer_face.any(axis=0))[0]
        if not rows.size:
            rows = cols = np.zeros(1, int)
        m = INNER_MARGIN
        iy0, iy1 = max(0, int(rows[0]) - m), min(ly1 - ly0, int(rows[-1]) + 1 + m)
        ix0, ix1 = max(0, int(cols[0]) - m), min(lx1 - lx0, int(cols[-1]) + 1 + m)
        self.inner = (slice(iy0, iy1), slice(ix0, ix1))  # the face's box within the layer's
        self.box = (ly0 + iy0, ly0 + iy1, lx0 + ix0, lx0 + ix1)

    def _on_photo(self, grid: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(h, w) bool: a (Hm, Wm) bool map on the model grid (``mask``) brought to the box's pixels."""
        return np.nan_to_num(scalar_to_input(grid.astype(np.float32), mask, self.al, self.shape)) >= 0.5

    def _outlined(self, outlines: list, margin_px: float) -> np.ndarray:
        """(h, w) bool: the box's pixels inside the ``outlines`` (photo pixels), grown by ``margin_px``."""
        if not outlines:
            return np.zeros(self.shape, bool)
        y0, _, x0, _ = self.box
        return grow(np.logical_or.reduce([polygon_mask(np.asarray(o) - [x0, y0], self.shape) for o in outlines]),
                    margin_px)

    def _skin(self, hair: np.ndarray | None, hair_matte: Callable[[np.ndarray], np.ndarray] | None,
              direct: np.ndarray, iod_px: float) -> np.ndarray:
        """(h, w) bool: the face's pixels whose darkness may be a shadow's: off the eyes, brows, lips and mouth, off
        hair (the fit's cover, the hair matte), smooth as skin is, of the skin's colour (in its shade too)."""
        f = self.features
        dark_by_make = self._outlined([*f.eyes, *f.brows], EYE_MARGIN * iod_px) | self._outlined(
            [*f.lips, *f.nostrils], MOUTH_MARGIN * iod_px)
        self.dark_by_make = dark_by_make
        out = self.face & ~dark_by_make & ~np.any(self.photo >= 0.995, axis=-1)
        if hair is not None:
            out &= ~grow(self._on_photo(hair, self.mask), max(self.al.scale, 1.0))
        if hair_matte is not None:
            out &= hair_matte(self.photo) < 0.5
        if iod_px < SKIN_MIN_IOD:
            return out
        out &= ~self._rough(out, iod_px)
        if self.photo.shape[-1] == 3:
            blurred = cv2.GaussianBlur(self.photo, (0, 0), max(COLOUR_SCALE * iod_px, 1.0))
            lit = out & (direct >= MEASURE_DIRECT)  # the skin's colour is the lit skin's
            out &= skin_distance(blurred, self.face, shade=True, keep_out=dark_by_make, reference=lit) < MAX_CHROMA_DISTANCE
        return out

    def _rough(self, smooth_guess: np.ndarray, iod_px: float) -> np.ndarray:
        """(h, w) bool: what is as rough as hair's strands or a beard (``skin.strands`` over the median of the
        ``smooth_guess`` (h, w) bool skin's, over ``ROUGH``)."""
        lit_level = float(np.median(self.photo[smooth_guess].sum(axis=-1))) if smooth_guess.sum() > 50 else 1.0
        texture = strands(self.photo, iod_px, STRAND_FLOOR * lit_level)
        typical = float(np.median(texture[smooth_guess])) if smooth_guess.sum() > 50 else ROUGH_FLOOR
        return texture > np.float32(ROUGH * max(typical, ROUGH_FLOOR))

    def _shadows(self, coarse: np.ndarray, lighting: np.ndarray, direct: np.ndarray,
                 gate: np.ndarray) -> tuple[np.ndarray, ShadowEvidence]:
        """The skin's expected albedo (h, w, C) and the photo's shadows (``ShadowEvidence``), twice: the second time
        the albedo is measured off the first time's shadows, whose darkness had pulled it down."""
        clear = self.skin & (direct >= MEASURE_DIRECT) & ~gate
        expected = evidence = None
        for _ in range(2):
            measured = clear if evidence is None else clear & ~grow(evidence.membership > 0.5,
                                                                    MEASURE_CLEAR * self.iod)
            if measured.sum() < 50:  # a face lit all from the side: its lit skin, wherever it is
                measured = self.skin & (direct >= MEASURE_DIRECT)
            expected = expected_albedo(self.photo, lighting, measured, coarse, self.face, MATCH_SIGMA * self.iod)
            evidence = shadow_evidence(self.photo, expected, lighting, direct, self.skin, gate, self.face, self.iod)
            if not evidence.found:
                break
        return expected, evidence

    def _ambient(self, direct: np.ndarray) -> float:
        """The room's share of the light (``shading.fit_ambient``), on the skin more than ``AMBIENT_RIM`` inside the
        face (at its rim the fitted normals graze the view and the photo mixes in what is beyond)."""
        core = self.skin & (distance_inside(self.face) > AMBIENT_RIM * self.iod)
        return fit_ambient(self.photo, direct, core, AMBIENT_SIGMA * self.iod)

    def _deep_eyes(self, iod_px: float) -> np.ndarray:
        """(h, w) bool: the eyes (grown by ``EYE_MARGIN``) whose region holds no signal for the most part (its median
        ``precision`` past ``DEEP_EYE``), where a face mesh drew them and the lit eye's detail is known."""
        out = np.zeros(self.shape, bool)
        if self.eyes is None:
            return out
        for eye in self.features.eyes:
            region = self._outlined([eye], EYE_MARGIN * iod_px) & self.face
            if region.any() and float(np.median(self.relative[region])) > DEEP_EYE:
                out |= region
        return out

    def _file_values(self, encoding: str) -> np.ndarray:
        """(h, w) the photo's brightness as its file holds it (encoded for an sRGB photo)."""
        grey = brightness(self.photo)
        return linear_to_srgb(grey) if encoding == "srgb" else grey

    def _shine(self, iod_px: float) -> np.ndarray:
        """(h, w, C) the photo's shine, in light: on the skin and its glints, what rises over its local level."""
        albedo = self.photo / self.photo_lighting
        white = np.zeros(self.shape, bool)
        if self.features.all:
            inside = distance_inside(self.face) > GLINT_EDGE * iod_px
            white = glints(self.photo, self.skin, self.face & inside, SHEEN_SCALE * iod_px,
                           self._outlined(self.features.all, GLINT_FEATURE_MARGIN * iod_px), GLINT_REACH * iod_px)
        excess = sheen(albedo, self.skin | white, self.usable > 0.5, SHEEN_SCALE * iod_px)
        return (excess * self.photo_lighting).astype(np.float32)

    def _matched(self, expected: np.ndarray) -> np.ndarray:
        """(h, w, C) the ``expected`` albedo brought to the level and colour the photo's own skin shows around it where
        it holds signal (``usable``), the photo over the light it shows, averaged over ``MATCH_SIGMA``: a fill meets
        the lifted photo beside it without a seam."""
        rho = np.maximum(np.nan_to_num(expected), np.float32(1e-4))
        ratio = self.photo / self.photo_lighting / rho
        # on the skin the photo shows well and out of its shadows (their edges are where its light is least known)
        use = (self.skin & (self.usable > 0.9) & (self.evidence.membership < 0.2)).astype(np.float32)
        match = local_average(ratio, use, MATCH_SIGMA * self.iod, np.ones_like(ratio))
        return (rho * np.clip(match, *MATCH_RANGE)).astype(np.float32)

    def _fill_albedo(self, expected: np.ndarray, midline: np.ndarray | None, mirror: np.ndarray | None,
                     strength: float) -> np.ndarray:
        """(h, w, C) the albedo a fill paints with: the ``expected`` albedo with, as far as ``strength`` says, what the
        face shows of itself across its midline where the photo has it there (``seen``): a frontal face's across its
        ``midline`` (2, 2) photo pixels, a turned one's through the model's ``mirror`` (N,) (``mirror_map``). On skin
        the band of its detail the fit's map is too coarse to hold (``mirrored_detail``: finer is the other side's own
        pores, which the truth does not share pixel for pixel); elsewhere (an eye, a brow, a beard) the whole of it,
        at the expected albedo's local level (``MATCH_SIGMA``). Beside the axis a pixel's mirror is its neighbour, and
        the fill keeps the expected albedo (``FILL_DETAIL_AXIS``)."""
        a = np.nan_to_num(expected).astype(np.float32)
        self.seen = np.zeros(self.shape, np.float32)  # how far each pixel's mirror is known
        if strength <= 0 or (midline is None and mirror is None):
            return a
        if midline is not None:
            y0, _, x0, _ = self.box
            across = reflection_map(self.shape, np.asarray(midline, np.float64) - [x0, y0])
        else:
            across = mirror_map(self.mask, mirror, self.al, self.shape)
        measured = self.photo / self.photo_lighting
        trust = np.where(self.face, self.usable, 0.0).astype(np.float32)
        px = max(self.al.scale, 1.0)
        detail, seen = mirrored_detail(measured, trust, across, FILL_DETAIL_BAND[0] * px, FILL_DETAIL_BAND[1] * px)
        yy, xx = np.mgrid[0:self.shape[0], 0:self.shape[1]].astype(np.float32)
        apart = np.hypot(across[0] - xx, across[1] - yy) / np.float32(self.iod)
        self.seen = (seen * smoothstep(apart, *FILL_DETAIL_AXIS) * self.face).astype(np.float32)
        painted = a * detail
        strands = ~self.skin & ~self.dark_by_make  # a beard, stubble, hair: the whole of it, at the fill's level
        if (strands & (self.seen > 0.05)).any():
            whole, _ = mirrored(measured, trust, across)
            level = local_average(a / np.maximum(whole, np.float32(1e-4)), (self.seen > 0.05).astype(np.float32),
                                  MATCH_SIGMA * self.iod, np.ones_like(a))
            painted = np.where(strands[..., None], whole * np.clip(level, 0.5, 2.0), painted)
        w = (np.float32(strength) * self.seen)[..., None]
        return (a + w * (painted - a)).astype(np.float32)

    def _albedo(self) -> np.ndarray:
        """(h, w, C) the face's albedo (``albedo.png``): the photo over the light it shows where it holds signal,
        the fill's albedo where not; NaN off the face."""
        measured = self.photo / self.photo_lighting
        u = self.usable[..., None]
        return np.where(self.face[..., None], u * measured + (1.0 - u) * self.fill, np.nan).astype(np.float32)

    # -- one light ---------------------------------------------------------------------------------------------------

    def new_lighting(self, light: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(S', L'_u, k')`` (h, w) each for ``light`` (3,): the direct light less its cast shadow traced on the fit's
        surface, the lighting (with the room's light) without that shadow, and the share of it the shadow leaves."""
        s = np.asarray(light, np.float64) / np.linalg.norm(light)
        # the ray's margin under the surface, interpolated from the model grid and thresholded on the photo's, so the
        # shadow's edge runs smoothly between model pixels
        margin = cast_margin(self.depth, self.al.vector_to_model(s))
        cast = soft_cast(scalar_to_input(margin, self.mask, self.al, self.shape))
        unshadowed = self.shading.lighting(s)
        shadowed = self.shading.lighting(s, cast)
        return (np.float32(1.0) - cast) * self.shading.direct(s), unshadowed, shadowed / unshadowed

    def relit(self, light: np.ndarray) -> np.ndarray:
        """(h, w, C) the face's box relit by ``light`` (3,), camera frame, exposed as the photo's lit skin: the photo
        times the change of light (``lift``): the new light's over the light the photo shows, its coarse part
        smoothed, its fine part the photo's own (a shadow's edge as the photo has it), and the new light's cast
        shadow; under nearly the photo's own light, the photo as it is (``lift.shadows_kept``)."""
        s = np.asarray(light, np.float64) / np.linalg.norm(light)
        direct, unshadowed, cast_share = self.new_lighting(s)
        new = brightened(unshadowed, self.fitted, self.evidence.correction)
        shown = self.photo_lighting
        # the coarse part of the change averaged, the fine part the photo's own (a shadow's edge as the photo has it)
        smooth = smooth_change(shown, self.face, CHANGE_SIGMA * self.iod)
        change = smooth_change(new / smooth, self.face, CHANGE_SIGMA * self.iod) * (smooth / shown)
        same = np.float32(shadows_kept(self.light, s))
        g = same + (np.float32(1.0) - same) * change * cast_share[..., None] * self._lifted(new)
        keep = shine_kept(brightness(shown), brightness(new) * cast_share, shine_lobe(self.normals, self.light, s))
        no_fill = np.zeros(self.shape, np.float32)
        unexposed = relit_face(self.photo, g, g, no_fill, self.shine, keep)
        # the exposure is met on skin the new light lights and the photo shows well enough to lift (a painted shadow's
        # side is no level the photo measured)
        shown_well = usable(self.relative, brightness(g), self.encoding) > 0.9
        gain = exposure(self.photo, unexposed, self.lit_skin, self.skin & (direct >= LIT_SHADING) & shown_well)
        g = np.float32(gain) * g
        held = held_to_skin(brightness(g), self.photo, self.skin, HELD_SIGMA * self.iod)
        g = g * held[..., None]
        lift = brightness(g)
        weight = fill_weight(usable(self.relative, lift, self.encoding), self.paintable_share)
        fill = self.fill if self.eyes is None else self.eyes.apply(self.fill, 1.0 - weight)
        painted = np.float32(gain) * fill * new * (same + (np.float32(1.0) - same) * cast_share[..., None])
        self.report = {"exposure": gain, "painted": float(weight[self.face].mean()) if self.face.any() else 0.0,
                       "lift_p95": float(np.percentile(lift[self.face], 95)) if self.face.any() else 1.0}
        return relit_face(self.photo, g, painted, weight, self.shine, keep, fill)

    def _lifted(self, new: np.ndarray) -> np.ndarray | float:
        """(h, w, C) how much the side of the face the photo's light reaches less is raised toward its mirror's
        level (``albedo.mirror_raise``) as far as the new lighting ``new`` (h, w, C) brightens it; 1 without a
        midline."""
        if self.mirror_raise is None:
            return 1.0
        return lifted(*self.mirror_raise, brightness(new) / brightness(self.photo_lighting))

    def layer(self, light: np.ndarray) -> FaceLayer:
        """The face relit by ``light`` (3,), camera frame, as a layer of the photo."""
        relit = self._in_layer(np.clip(self.relit(light), 0.0, 1.0))
        return FaceLayer(self.layer_box, self.layer_face, relit,
                         outside_gain(self.layer_photo, relit, self.layer_face, self.feather, self.layer_beyond,
                                      self.layer_person),
                         self.layer_alpha)

    def live_data(self) -> LiveFace:
        """What the page needs to relight this face live (``live.live_relight_data``), on the layer's box: the face and
        the feather its change of light is carried over."""
        ones = np.ones_like(self.photo_lighting)
        fill = self.fill if self.eyes is None else self.eyes.apply(self.fill, np.zeros(self.shape, np.float32))
        more = self.fitted[..., None] * np.maximum(self.evidence.correction - np.float32(1.0), 0.0)
        arrays = LiveArrays(
            photo=self.layer_photo, shown=self._in_layer(self.photo_lighting - ones) + 1.0, more=self._in_layer(more),
            fill=self._in_layer(fill), normals=self._in_layer(self.normals), relative=self._in_layer(self.relative),
            paint=self._in_layer(self.paintable_share), face=self.layer_face, skin=self._in_layer(self.skin) > 0,
            alpha=self.layer_alpha, beyond=self.layer_beyond, person=self.layer_person,
            raise_ratio=None if self.mirror_raise is None else self._in_layer(self.mirror_raise[0] - 1.0) + 1.0,
            raise_strength=None if self.mirror_raise is None else self._in_layer(self.mirror_raise[1]),
            shine=self._in_layer(self.shine) if self.shine.any() else None)
        y0, _, x0, _ = self.box
        ly0, _, lx0, _ = self.layer_box
        to_box = self.al.cropped(lx0 - x0, ly0 - y0).matrix
        return live_relight_data(self.layer_box, arrays, self.want, self.shading.ambient, self.light, self.depth,
                                 self.mask, to_box, self.encoding, self.feather, CHANGE_SIGMA * self.iod,
                                 HELD_SIGMA * self.iod)

    def _in_layer(self, values: np.ndarray) -> np.ndarray:
        """(h, w[, C]) values on the face's box -> the layer's box, 0 around."""
        out = np.zeros(self.layer_face.shape + values.shape[2:], np.float32)
        out[self.inner] = values
        return out
