"""One face of a photo relit in the box around it (plus the feather), as a function of arrays.

``FaceRelight`` measures once what every light shares (the box's photo, face, normals, shading,
shadows, room light and albedo) and gives ``layer(light)`` for each light, a ``FaceLayer`` for
``photo_relight.compose``. Two boxes: the face's own (``box``: the face and ``INNER_MARGIN``), where
the albedo, shadows and relit face are made, and the layer's (``layer_box``: the face and its feather),
where only the relit face's light is carried into the photo around it (``outside_gain``). A large
photo's background costs nothing, and the photo outside the layer's box is not touched. The steps are ``photo_relight``'s; this module says
which arrays go where.
"""
from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

from ..geometry.integrate import harmonic_fill
from ..geometry.raster import polygon_mask
from ..photo.align import Alignment, face_box, mask_to_input, normals_to_input, scalar_to_input, to_model_grid
from .eye_detail import CONTRAST as EYE_CONTRAST
from .eye_detail import EyeDetail
from .live_relight import live_relight_data
from .photo_relight import (
    AMBIENT_RIM,
    CLIPPED,
    LIFT_AXIS,
    LIFT_SIGMA,
    LIT_SHADING,
    MAX_CHROMA_DISTANCE,
    SHEEN_SCALE,
    FaceLayer,
    axis_distance,
    brightened_as_around,
    clipped_floor,
    exposure_target,
    fine_texture,
    glints,
    grow,
    inner_alpha,
    kept_cap,
    lit_weight,
    mirror_lift,
    mirrored_detail,
    outside_gain,
    photo_albedo,
    photo_ambient,
    reflection_map,
    shading_trust,
    sheen,
    shine_kept,
    shine_lobe,
    skin,
    skin_distance,
    skin_exposure,
    smooth_coarse,
    smoothstep,
    with_ambient,
    without_sheen,
)
from .shadow import cast_margin, photo_shadows, soft_cast

MATCH_SIGMA = 0.08  # the photo albedo's level is matched over this many interocular distances
FEATHER = 0.3  # the relit face's light fades into the photo over this many interocular distances
# the fit's albedo map is smoothed over this many model pixels before it fills the photo (``smooth_coarse``):
# the staircase seams where its mirrored and measured parts meet go (figures: docs/accuracy.md)
COARSE_SMOOTH = 1.5
# a filled pixel takes the band of the measured albedo's detail seen across the face (``mirrored_detail``) between
# these scales, in model pixels, at this strength (``MethodOptions.fill_detail``): the fit's map holds the coarse
# one, and pores and noise are the other side's own (docs/relighting.md, "Relighting the photo")
FILL_DETAIL_BAND = (0.6, 1.5)
FILL_DETAIL = 1.0
# ... fading in between these distances from the face's vertical axis, in interocular distances
FILL_DETAIL_AXIS = (0.05, 0.2)
# everything but the feather is computed in the face's own box, grown by this many photo pixels (the feather's
# ring, two thirds of the layer's box at a portrait's size, needs only the photo and the relit face's border)
INNER_MARGIN = 4
# the photo's shadows smaller than this many model pixels' area are dropped (``photo_shadows``' min_area)
SHADOW_SPECK = 1.0
# the face mesh's brows grown by this many interocular distances are dark by their albedo, never shadow on the
# photo; a brow keeps its own pixels (as what is not skin does) where the lighting is above this ramp, and follows
# the skin's trust below it, where the light grazes it (docs/relighting.md, "Held-out photos")
BROW_MARGIN = 0.02
BROW_KEPT = (0.25, 0.4)
# skin in its shade (``_shaded_skin``): off the lips, and the eyes and brows, grown by these many interocular
# distances, and no rougher than this many times the lit skin's median texture at this scale (interocular distances)
SHADE_FEATURE_MARGIN = 0.02
SHADE_EYE_MARGIN = 0.1
SHADE_TEXTURE = 2.5
SHADE_TEXTURE_SCALE = 0.01
# ... and only on a face this many photo pixels between the eyes or more: on smaller ones a photo's colour (a JPEG's
# at half resolution) and hair's strands are not resolved, and the shadows so found took hairlines, a cartoon's
# cheek and annotated faces' skin (opencv-doc's faces 19-37 px between the eyes; docs/relighting.md)
SHADE_MIN_IOD = 60.0
# on skin the fit shades at least this much (its lit side: a shape's cast shadow falls on skin turned further from
# the light), what is as rough as hair's strands (``SHADE_TEXTURE``) is not a shadow, whatever its colour: dark brown
# hair over a cheek in a warm shade has the skin's colour and was filled as shadow with a flat patch of skin. At 0.3 the
# noses' cast shadows on tinted Yale B faces at +-50 lost their sharp edges to it (docs/relighting.md, "Hair's strands")
STRAND_SHADING = 0.5
# the least texture (``fine_texture``, log brightness) lit skin is taken to have: held-out portraits' is 0.02-0.08
ROUGH_FLOOR = 0.01
# the fit's albedo map is filled again (harmonic) where the grid measured it lit but the photo finds shadow over
# more than this share of a model pixel: its value there holds that shadow (an eye socket under a light from above,
# deeper than the model's, came back a dark patch of fill)
SHADOWED_ON_PHOTO = 0.5

# the face mesh's eyes, brows, lips and mouth grown by this many interocular distances are theirs, not glints; nor is
# anything this near the face's edge; and a glint is this near a pixel with the skin's colour under its white
GLINT_FEATURE_MARGIN = 0.05
GLINT_EDGE = 0.1
GLINT_REACH = 0.1


class FaceRelight:
    """One face relit in its box.

    photo: (H, W, C) float32 linear RGB (C = 3) or grey (C = 1) in [0, 1]; grey: (H, W) its brightness.
    alignment: model pixel -> photo pixel. mask: (Hm, Wm) bool, the model's face. normals: (Hm, Wm, 3)
    the normals that explain the photo's shading (model camera frame, NaN off the face); lit:
    (Hm, Wm) bool, not in the fit's shadows; albedo: (Hm, Wm) the fit's albedo map; depth: (Hm, Wm)
    heights in model pixels. light: (3,) unit, the photo's light, camera frame. iod_px: the face's
    interocular distance in photo pixels. outline: (n, 2) the face's own outline in photo pixels,
    or None. eyes: (2, 2) the eyes' centres in photo pixels where a face mesh found them, else None
    (no eye detail: a render without eye texture has no eye to show). midline: (2, 2) two points of the
    face's vertical symmetry axis in photo pixels, or None (no detail seen across the face in the fill, as
    for a turned face); fill_detail: that detail's strength (0: none); mirror_lift: how far the albedo of the
    side the photo's light reaches less is raised toward its mirror's (``photo_relight.mirror_lift``; 0: not, 1:
    fully). features: the outlines (n, 2) of the eyes, brows, lips and mouth in photo pixels where a face mesh drew
    them, or None (no glints told in colour).
    segment: (h, w, C) linear photo -> (h, w) how sure a segmentation is that each pixel is the person
    (``mediapipe.person_share``), or None (the whole feather). hair: (Hm, Wm) bool, what the fit left out as
    covering the face's upper part (``photo.cover``: hair over it), or None; a grey photo tells hair from skin by it.
    near: (Hm, Wm) bool, the part of the fit's shadows found from rays the surface nearly blocks (``ShadowMaps.near``),
    or None: dark pixels there are shadow, but no shadow grows from them across the photo's dark pixels.
    brows: the brows' outlines (n, 2) in photo pixels where a face mesh drew them, or None: dark by their albedo,
    they are no shadow, and keep their own pixels where lit (``BROW_MARGIN``, ``BROW_KEPT``).
    eye_outlines: the eyes' outlines (n, 2) in photo pixels where a face mesh drew them, or None: the skin around them
    is never taken for skin in shade (``SHADE_EYE_MARGIN``).
    """

    def __init__(self, *, photo: np.ndarray, grey: np.ndarray, alignment: Alignment, mask: np.ndarray,
                 normals: np.ndarray, lit: np.ndarray, albedo: np.ndarray, depth: np.ndarray, light: np.ndarray,
                 iod_px: float, outline: np.ndarray | None = None, eyes: np.ndarray | None = None,
                 eye_contrast: float = EYE_CONTRAST, midline: np.ndarray | None = None,
                 fill_detail: float = FILL_DETAIL, mirror_lift: float = 1.0, features: list[np.ndarray] | None = None,
                 segment: Callable[[np.ndarray], np.ndarray] | None = None, hair: np.ndarray | None = None,
                 near: np.ndarray | None = None, brows: list[np.ndarray] | None = None,
                 eye_outlines: list[np.ndarray] | None = None):
        self.mask, self.depth, self.light = mask, depth, np.asarray(light, np.float64)
        self.feather = FEATHER * iod_px
        self._boxes(photo, alignment, mask, outline, segment)
        y0, y1, x0, x1 = self.box
        self.al = al = alignment.cropped(x0, y0)
        self.photo = photo = photo[y0:y1, x0:x1]
        self.shape = shape = photo.shape[:2]
        self.face = face = self.layer_face[self.inner]
        # each face pixel's distance inside it, once: the relit face's fade at its border and the kept pixels' bound
        inside = cv2.distanceTransform(face.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        self.normals = np.nan_to_num(normals_to_input(normals, mask, al, shape)).astype(np.float32)
        self.shading = shading = np.clip(self.normals @ self.light.astype(np.float32), 0.0, None)
        box_grey = grey[y0:y1, x0:x1]
        # in colour, a shadow is on skin (in its shade too, ``_shaded_skin``): dark hair, brows and eyes are not shadow;
        # in grey, ``hair`` is told from skin by that alone (taken for shadow, a fringe was filled with a flat patch of
        # skin; not in colour: there it took the darkness drawn around a composite's crop, 0.1-0.5 dB lost)
        hair_px = self._hair(hair, mask) if photo.shape[-1] == 1 else np.zeros_like(face)
        brow = self._features(brows, BROW_MARGIN * iod_px)
        face_skin = skin(photo, face) & ~hair_px
        # in colour, how rough the photo is tells hair's strands from skin in its shade and from shadow on lit skin
        rough, keep_out = self._roughness(photo, face_skin, features, (eye_outlines or []) + (brows or []), iod_px)
        shaded = strands = np.zeros_like(face)
        if rough is not None:
            shaded = self._shaded_skin(photo, face_skin, rough, keep_out, iod_px)
            strands = (rough >= SHADE_TEXTURE) & (shading >= STRAND_SHADING) & ~keep_out
        self.shadow = self._shadows(box_grey, mask, lit, near, ((face_skin & ~strands) | shaded) & ~brow)
        px = max(al.scale, 1.0)  # photo pixels per model pixel
        face_lit = face & ~grow(self.shadow, 1.5 * px)  # a shadow's soft edge (penumbra) is not lit skin either
        self.coarse = coarse = self._coarse(albedo, mask, lit, px)
        self.measured = lit_weight(photo, face_lit, face, 1.5 * px)  # the light-independent part of the trust
        self.skin_only = skin(photo, face & face_lit) & ~hair_px
        self.lit_skin = self.skin_only & (shading >= LIT_SHADING)  # what the relit face's exposure is matched to
        self.match_px = MATCH_SIGMA * iod_px
        self.eyes = None if eyes is None else EyeDetail(photo, shading, np.asarray(eyes) - [x0, y0],
                                                        eye_contrast)
        # the albedo divides out the light the photo's face had, the room's included (``with_ambient``)
        self.ambient = photo_ambient(box_grey, coarse, shading, face, AMBIENT_RIM * iod_px, face_skin)
        self.lighting = with_ambient(shading, self.ambient)
        # how far I / lighting is trusted: the lighting with the room's light in it is never darker than the
        # ambient, so a photo with fill light keeps its own pixels further round the face; what is not skin
        # (hair, eyes, teeth, glasses) keeps its own pixels wherever it is lit, whatever the fitted shading
        # says: the fill is skin, and a fitted normal gone wrong under hair made a skin patch there
        # ... but a highlight too white to pass as skin is skin and its shine (``glints``), which a new light moves
        self.glints = self._glints(features, face_lit, iod_px)
        not_skin = face_lit & ~face_skin & ~self.glints if photo.shape[-1] == 3 else face_lit & hair_px
        # how far each pixel keeps its own I / lighting whatever the new light: what is not skin, and a lit brow
        self.kept = np.maximum(not_skin, (face_lit & brow) * smoothstep(self.lighting, *BROW_KEPT))
        self.kept_measured, self.kept_cap = self.kept * self.measured, kept_cap(inside, self.feather)
        self.fill_detail = fill_detail if midline is not None else 0.0
        # the face seen across its midline: its detail for the fill, its level for the side lit less
        self.lift_sigma = LIFT_SIGMA * iod_px
        self.axis, self.mirror, off_axis, self.lift_reach = self._across(midline, iod_px, mirror_lift)
        # the detail seen across the face and its trust, once, from the light-independent trust
        self.detail = self._mirrored_detail(off_axis, iod_px) if self.fill_detail > 0 else None
        self.albedo = self.albedo_for(self.trust_for())
        # the photo's shine, which a new light takes out where it darkens the skin (``without_sheen``)
        self.shine = sheen(self.albedo, self.skin_only | self.glints, self.measured > 0.5, SHEEN_SCALE * iod_px)
        self.alpha = inner_alpha(face, self.feather, inside)
        self.layer_alpha = self._in_layer(self.alpha)  # every light's layer shares it

    def _boxes(self, photo: np.ndarray, alignment: Alignment, mask: np.ndarray, outline: np.ndarray | None,
               segment: Callable[[np.ndarray], np.ndarray] | None) -> None:
        """The layer's box (the face and its feather: ``layer_box``, ``layer_photo``, ``layer_face``, its own skin
        beyond the model ``layer_beyond``, the person around it ``layer_person``) and, in it, the face's own box
        (``inner``; ``box`` in the photo), where the albedo, shadows and relit face are computed."""
        ly0, ly1, lx0, lx1 = face_box(mask, alignment, photo.shape[:2], margin=2.5 * self.feather + 4)
        self.layer_box = (ly0, ly1, lx0, lx1)
        self.layer_photo = photo[ly0:ly1, lx0:lx1]
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

    def _roughness(self, photo: np.ndarray, lit: np.ndarray, features: list[np.ndarray] | None,
                   eyes_and_brows: list[np.ndarray], iod_px: float) -> tuple[np.ndarray | None, np.ndarray | None]:
        """In colour, on a face ``SHADE_MIN_IOD`` or more between the eyes: (h, w) float32 how rough the photo is, its
        ``fine_texture`` over the median of ``lit`` (h, w) bool skin's (hair and a beard are strands, skin is smooth,
        in its shade too), and (h, w) bool the eyes, brows and lips, which are rough and dark by their make
        (``SHADE_FEATURE_MARGIN``; ``SHADE_EYE_MARGIN`` around the eyes and brows: their ring of lids and lashes).
        (None, None) in grey or on a smaller face: there a photo's colour (a JPEG's at half resolution) and hair's
        strands are not resolved (opencv-doc's faces 19-37 px between the eyes: hairlines, a cartoon's cheek and
        annotated faces' skin were taken for shadow; docs/relighting.md)."""
        if photo.shape[-1] != 3 or lit.sum() <= 50 or iod_px < SHADE_MIN_IOD:
            return None, None
        keep_out = (self._features(features, SHADE_FEATURE_MARGIN * iod_px)
                    | self._features(eyes_and_brows, SHADE_EYE_MARGIN * iod_px))
        texture = fine_texture(photo, max(SHADE_TEXTURE_SCALE * iod_px, 1.0))
        # a photo's lit skin is never smoother than ROUGH_FLOOR (a render's can be, and against it every edge is rough)
        return texture / np.float32(max(float(np.median(texture[lit])), ROUGH_FLOOR)), keep_out

    def _shaded_skin(self, photo: np.ndarray, lit: np.ndarray, rough: np.ndarray, keep_out: np.ndarray,
                     iod_px: float) -> np.ndarray:
        """(h, w) bool: in colour, the face's skin in its shade beside ``lit`` (h, w) bool, its skin by its colour
        (``skin``): redder than lit skin as it darkens (``skin_distance``), smooth as skin is (``rough`` under
        ``SHADE_TEXTURE``: hair and a beard are strands), and off ``keep_out`` (the eyes, brows and lips, which are
        dark and red too; ``_roughness``).

        Only the photo's shadows are found on it (a shadow under a nose, redder than the skin, was neither skin nor
        shadow, kept as it was: a brown patch on a face relit from the front); skin the fit already shades dark keeps
        its own pixels as what is not skin does (filled, a film still's shaded cheek came back flat)."""
        scale = max(SHADE_TEXTURE_SCALE * iod_px, 1.0)
        # the colour of a dark pixel is noisy: told over a few pixels, or a shadow came back as speckles of both
        blurred = cv2.GaussianBlur(photo, (0, 0), 2.0 * scale)
        shaded = skin_distance(blurred, self.face, shade=True, keep_out=keep_out) < MAX_CHROMA_DISTANCE
        return shaded & (rough < SHADE_TEXTURE) & ~keep_out & ~lit

    def _coarse(self, albedo: np.ndarray, mask: np.ndarray, lit: np.ndarray, px: float) -> np.ndarray:
        """(h, w) the fit's albedo map (Hm, Wm) on the box's pixels, smoothed (``smooth_coarse``), filled again first
        where the grid took it for lit (``lit``) and the photo's shadows cover it (``SHADOWED_ON_PHOTO``)."""
        shadowed = to_model_grid(self.shadow.astype(np.float32), self.al, mask.shape) > SHADOWED_ON_PHOTO
        held = mask & lit & shadowed
        if held.any() and (mask & ~held).sum() > 20:
            albedo = harmonic_fill(np.where(mask, albedo, np.nan), held).astype(np.float32)
        return smooth_coarse(scalar_to_input(albedo, mask, self.al, self.shape), self.face, COARSE_SMOOTH * px)

    def _on_photo(self, grid: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(h, w) bool: a (Hm, Wm) bool map on the model grid (``mask``) brought to the box's pixels."""
        return np.nan_to_num(scalar_to_input(grid.astype(np.float32), mask, self.al, self.shape)) >= 0.5

    def _hair(self, hair: np.ndarray | None, mask: np.ndarray) -> np.ndarray:
        """(h, w) bool: the face's pixels under ``hair`` (Hm, Wm) bool on the model grid (``mask``; None: none),
        and its edge, a model pixel wide."""
        if hair is None:
            return np.zeros_like(self.face)
        return self.face & grow(self._on_photo(hair, mask), max(self.al.scale, 1.0))

    def _features(self, outlines: list[np.ndarray] | None, margin_px: float) -> np.ndarray:
        """(h, w) bool: the box's pixels inside the ``outlines`` (n, 2) photo pixels (None: none), grown by
        ``margin_px`` (``grow``: at least a pixel)."""
        if not outlines:
            return np.zeros(self.shape, bool)
        y0, _, x0, _ = self.box
        return grow(np.logical_or.reduce([polygon_mask(np.asarray(o) - [x0, y0], self.shape) for o in outlines]),
                    margin_px)

    def _shadows(self, grey: np.ndarray, mask: np.ndarray, lit: np.ndarray, near: np.ndarray | None,
                 face_skin: np.ndarray) -> np.ndarray:
        """(h, w) bool: the box's shadows at the photo's resolution (``photo_shadows``) from the fit's, ``lit``
        (Hm, Wm) bool, on the model grid (``mask``); those found from rays nearly blocked (``near``, or None) are
        taken where the box's ``grey`` (h, w) is dark, not grown across it."""
        coarse_lit = self._on_photo(lit, mask)
        near_px = None
        if near is not None and near.any():
            near_px = self._on_photo(near, mask)
            coarse_lit = coarse_lit | near_px
        px = max(self.al.scale, 1.0)
        return photo_shadows(grey, self.shading, self.face & ~coarse_lit, face_skin, near=near_px,
                             min_area=SHADOW_SPECK * px * px)

    def _glints(self, features: list[np.ndarray] | None, face_lit: np.ndarray, iod_px: float) -> np.ndarray:
        """(h, w) bool: the box's highlights too white to pass as skin (``glints``), off the face mesh's eyes, brows,
        lips and mouth (``features``, photo pixels; None: none told) and off the face's edge, where skin blends
        into a bright wall or white hair as skin and white do."""
        if not features:
            return np.zeros_like(face_lit)
        inside = cv2.distanceTransform(self.face.astype(np.uint8), cv2.DIST_L2, 3) > GLINT_EDGE * iod_px
        return glints(self.photo, self.skin_only, face_lit & inside, SHEEN_SCALE * iod_px,
                      self._features(features, GLINT_FEATURE_MARGIN * iod_px), GLINT_REACH * iod_px)

    def _across(self, midline: np.ndarray | None, iod_px: float, lift: float):
        """The face seen across its ``midline`` (2, 2) photo pixels: that line in the box's pixels, its
        ``reflection_map``, each pixel's distance from it (h, w) in interocular distances, and how far the side lit
        less is raised toward its mirror's level (``mirror_lift``'s reach (h, w), ``lift`` at most; None at 0).
        Nones without a midline."""
        if midline is None:
            return None, None, None, None
        y0, _, x0, _ = self.box
        axis = np.asarray(midline, np.float64) - [x0, y0]
        off_axis = axis_distance(self.shape, axis) / np.float32(iod_px)
        reach = None
        if lift > 0:
            reach = (np.float32(lift) * smoothstep(off_axis, 0.0, LIFT_AXIS) * self.face).astype(np.float32)
        return axis, reflection_map(self.shape, axis), off_axis, reach

    def _mirrored_detail(self, off_axis: np.ndarray, iod_px: float) -> tuple[np.ndarray, np.ndarray]:
        """The measured albedo's detail seen across the face's midline, and its trust (``mirrored_detail``),
        faded out near the midline (``off_axis`` (h, w): each pixel's distance from it, interocular distances)."""
        px = max(self.al.scale, 1.0)
        measured = np.atleast_3d(self.photo) / np.maximum(self.lighting, np.float32(1e-3))[..., None]
        detail, seen = mirrored_detail(measured, np.where(self.face, self.trust_for(), np.float32(0.0)),
                                       self.mirror, FILL_DETAIL_BAND[0] * px, FILL_DETAIL_BAND[1] * px)
        # near the axis a pixel's mirror is its neighbour: the detail there meets its own reflection as a
        # symmetric pattern (a glabella's lines lit from the side came back as a "Y" at +-70)
        near = smoothstep(off_axis, *FILL_DETAIL_AXIS)
        return detail, (seen * near).astype(np.float32)

    def albedo_for(self, trust: np.ndarray, new: np.ndarray | None = None) -> np.ndarray:
        """(h, w, C) the box's albedo where I / lighting is trusted by ``trust`` (h, w), the fit's elsewhere, with
        the detail the face shows across its midline where it is the fit's (``mirrored_detail``), and the side
        the photo's light reaches less raised toward its mirror's level as far as the new lighting ``new`` (h, w)
        brightens it (``mirror_lift``; None: any light), and what keeps its own pixels (``kept``: what is not skin,
        a lit brow) relit by ``new`` no brighter than the skin around it (``brightened_as_around``)."""
        a = photo_albedo(self.photo, self.lighting, trust, self.coarse, self.face, self.match_px, self.skin_only)
        if new is not None:  # what is not skin: relit no brighter than the skin around it (before the fill's detail)
            a = brightened_as_around(a, self.photo, self.lighting, new, self.skin_only, self.kept_measured,
                                     self.match_px, self.kept_cap)
        if self.detail is not None:
            detail, seen = self.detail
            weight = np.where(self.face, trust, np.float32(0.0))
            fill = (np.float32(self.fill_detail) * (np.float32(1.0) - weight) * seen)[..., None]
            a = (a * (np.float32(1.0) + fill * (detail - np.float32(1.0)))).astype(np.float32)
        if self.lift_reach is not None:
            amplification = None if new is None else new / np.maximum(self.lighting, np.float32(1e-3))
            # the level is the trusted skin's: in shadow, the fill is already the mirror's or the fit's map
            a = a * mirror_lift(a, self.skin_only.astype(np.float32), self.axis, self.lighting,
                                self.lift_sigma, self.lift_reach, amplification)
        return a if self.eyes is None else self.eyes.apply(a, trust)

    def trust_for(self, new: np.ndarray | None = None) -> np.ndarray:
        """(h, w) how far I / lighting is trusted, for a new lighting ``new`` (h, w) (None: any)."""
        return self.measured * (self.kept + (np.float32(1.0) - self.kept) * shading_trust(self.lighting, new))

    def layer(self, light) -> FaceLayer:
        """The face relit by ``light`` (3,), camera frame: its cast shadow traced on the fit's surface."""
        photo, face = self.photo, self.face
        s = np.asarray(light, np.float64) / np.linalg.norm(light)
        # how much of each photo pixel the cast shadow covers: the ray's margin under the surface, interpolated
        # from the model grid and thresholded on the photo's, so the edge runs smoothly between model pixels
        # (the shadow's yes or no, interpolated, made a staircase of them across the cheek)
        margin = cast_margin(self.depth, self.al.vector_to_model(s))
        cast_in = soft_cast(scalar_to_input(margin, self.mask, self.al, self.shape))
        new_shading = (np.float32(1.0) - cast_in) * np.clip(self.normals @ s.astype(np.float32), 0.0, None)
        new_lighting = with_ambient(new_shading, self.ambient)
        # the albedo this light can trust: I / S also where S is small but S' is no larger
        albedo = self.albedo_for(self.trust_for(new_lighting), new_lighting)
        keep = shine_kept(self.lighting, new_lighting, shine_lobe(self.normals, self.light, s))
        light_albedo = without_sheen(albedo, self.shine, self.lighting, new_lighting, keep)  # keep <= S'/S: as is
        # the room's light as the photo has it (``with_ambient``): the photo's own light gives the photo back,
        # a side light leaves the shadowed side dim, not black
        unexposed = light_albedo * new_lighting[..., None]
        gain = skin_exposure(photo, unexposed, self.lit_skin, self.skin_only & (new_shading >= LIT_SHADING))
        face_image = clipped_floor(np.float32(gain) * unexposed, photo, self.lighting, new_lighting, gain, face,
                                   albedo - self.shine, keep)
        # into the layer's box: the relit face's light carried over its border into the photo around it
        relit = self._in_layer(np.clip(face_image, 0.0, 1.0))
        return FaceLayer(self.layer_box, self.layer_face, relit,
                         outside_gain(self.layer_photo, relit, self.layer_face, self.feather, self.layer_beyond,
                                      self.layer_person),
                         self.layer_alpha)

    def _in_layer(self, values: np.ndarray) -> np.ndarray:
        """(h, w[, C]) values on the face's box -> the layer's box, 0 around."""
        out = np.zeros(self.layer_face.shape + values.shape[2:], np.float32)
        out[self.inner] = values
        return out

    def live_data(self, encoding: str) -> dict:
        """What the page needs to relight this face live (``live_relight_data``), on the layer's box: the face
        and the feather its change of light is carried over."""
        photo = self.photo
        return live_relight_data(
            box=self.layer_box, photo=self.layer_photo, albedo=self._in_layer(np.nan_to_num(self.albedo)),
            shine=self._in_layer(self.shine),
            normals=self._in_layer(self.normals), face=self.layer_face, alpha=self.layer_alpha,
            skin=self._in_layer(self.skin_only) > 0, want=exposure_target(photo, self.lit_skin), ambient=self.ambient,
            photo_light=self.light, clipped=(np.atleast_3d(self.layer_photo) >= CLIPPED) & self.layer_face[..., None],
            depth=self.depth, grid_mask=self.mask, to_box=self._layer_alignment().matrix, encoding=encoding,
            feather_px=self.feather, beyond=self.layer_beyond, person=self.layer_person)

    def _layer_alignment(self) -> Alignment:
        """Model pixel -> the layer box's pixel."""
        y0, _, x0, _ = self.box
        ly0, _, lx0, _ = self.layer_box
        return self.al.cropped(lx0 - x0, ly0 - y0)


def albedo_on_grid(albedo: np.ndarray, box: tuple[int, int, int, int], alignment: Alignment,
                   grid: tuple[int, int]) -> np.ndarray:
    """(Hm, Wm, C) a face's albedo measured on the photo (``FaceRelight.albedo``: (h, w, C) in ``box``
    ``(y0, y1, x0, x1)``, NaN off the face) brought to the model grid, area-averaged over what is known;
    NaN where its box knows nothing. alignment: model pixel -> photo pixel (the whole photo's)."""
    y0, _, x0, _ = box
    al = alignment.cropped(x0, y0)
    known = np.isfinite(albedo[..., 0]).astype(np.float32)
    weight = to_model_grid(known, al, grid)
    # (one channel comes back from OpenCV without its axis)
    measured = to_model_grid(np.nan_to_num(albedo).astype(np.float32) * known[..., None], al, grid)
    out = measured.reshape(weight.shape + (albedo.shape[-1],)) / np.maximum(weight, 1e-6)[..., None]
    return np.where((weight > 0.5)[..., None], out, np.nan).astype(np.float32)
