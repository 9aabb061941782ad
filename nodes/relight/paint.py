"""What a fill paints where the photo holds nothing, measured once for one face (docs/relighting.md, "Where the
photo holds nothing: painting"): the albedo it paints with, where it may paint, an eye's detail, and the face's
albedo (``albedo.png``).
"""
from __future__ import annotations

import numpy as np

from .albedo import mirror_map, mirrored, mirrored_detail, reflection_map
from .eyes import EyeDetail
from .face_box import FaceBox
from .fields import blur, local_average, smoothstep
from .shown_light import EYE_MARGIN, MATCH_SIGMA, REGION_SIGMA, ShownLight

# the expected albedo is matched to the skin beside a fill within this range (over ``MATCH_SIGMA``)
MATCH_RANGE = (0.67, 1.5)
# a painted pixel takes the face's albedo seen across its midline at this strength (``MethodOptions.fill_detail``),
# fading in between these distances from its mirror (interocular distances: beside the axis a pixel's mirror is its
# neighbour)
FILL_DETAIL = 1.0
FILL_DETAIL_AXIS = (0.1, 0.4)  # (the old axis distances 0.05-0.2, doubled)
# ... on skin, only the band of it between these scales, in model pixels (finer is the other side's own pores)
FILL_DETAIL_BAND = (0.6, 1.5)
# an eye is painted (with the lit eye's detail) when the median of its opening's ``lift.precision`` is past this
DEEP_EYE = 0.15


class Paint:
    """What a fill paints on one face, in its box ``at`` (``FaceBox``; (h, w) its pixels), off the light the photo
    shows there (``shown``). eyes: (2, 2) the eyes' centres in photo pixels where a face mesh found them, else None
    (no eye detail in a fill), put in at ``eye_contrast``; midline: (2, 2) two points of the face's vertical
    symmetry axis in photo pixels, or None; mirror: (N,) int a turned model's mirror map (``ShapeModel.mirror``), or
    None: how the face is seen across itself (neither: not at all); fill_detail: how far a fill takes what is seen
    so (0: none).

    ``eyes`` (``EyeDetail`` or None); ``fill`` (h, w, C) the albedo a fill paints with; ``seen`` (h, w) how far
    each pixel's mirror is known; ``paintable`` (h, w) bool and ``paintable_share`` (h, w) what may be painted, as
    a region's; ``albedo`` (h, w, C) the face's albedo, NaN off the face.
    """

    def __init__(self, at: FaceBox, shown: ShownLight, eyes: np.ndarray | None, eye_contrast: float,
                 midline: np.ndarray | None, mirror: np.ndarray | None, fill_detail: float, iod_px: float):
        self.at, self.shown, self.iod = at, shown, iod_px
        y0, _, x0, _ = at.box
        self.eyes = None if eyes is None else EyeDetail(at.photo, shown.direct, np.asarray(eyes) - [x0, y0],
                                                         eye_contrast)
        self.fill = self._fill_albedo(self._matched(shown.expected), midline, mirror, fill_detail)
        # a fill paints the skin, an eye in a shadow as deep as the noise floor (with the lit eye's detail), and what the
        # face shows of itself across its midline (its own detail, mirrored); never a nostril, a pupil, a brow, lips or
        # a beard the photo does not show lit elsewhere: they are dark by their make, and lifted as the skin is
        self.paintable = shown.skin | self._deep_eyes(iod_px) | (self.seen > 0.5)
        self.paintable_share = blur(self.paintable.astype(np.float32), max(REGION_SIGMA * iod_px, 1.0)) * at.face
        self.albedo = self._albedo()

    def _deep_eyes(self, iod_px: float) -> np.ndarray:
        """(h, w) bool: the eyes (grown by ``EYE_MARGIN``) deep in a shadow (``deep_eyes``), where a face mesh drew
        them and the lit eye's detail is known."""
        if self.eyes is None:
            return np.zeros(self.at.shape, bool)
        at = self.at
        regions = [at.outlined([eye], EYE_MARGIN * iod_px) & at.face for eye in at.features.eyes]
        openings = [at.outlined([eye], 0.0) & at.face for eye in at.features.eyes]
        return deep_eyes(self.shown.relative, regions, openings)

    def _matched(self, expected: np.ndarray) -> np.ndarray:
        """(h, w, C) the ``expected`` albedo brought to the level and colour the photo's own skin shows around it where
        it holds signal (``usable``), the photo over the light it shows, averaged over ``MATCH_SIGMA``: a fill meets
        the lifted photo beside it without a seam."""
        shown = self.shown
        rho = np.maximum(np.nan_to_num(expected), np.float32(1e-4))
        ratio = self.at.photo / shown.photo_lighting / rho
        # on the skin the photo shows well and out of its shadows (their edges are where its light is least known)
        use = (shown.skin & (shown.usable > 0.9) & (shown.evidence.membership < 0.2)).astype(np.float32)
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
        at, shown = self.at, self.shown
        a = np.nan_to_num(expected).astype(np.float32)
        self.seen = np.zeros(at.shape, np.float32)  # how far each pixel's mirror is known
        if strength <= 0 or (midline is None and mirror is None):
            return a
        if midline is not None:
            y0, _, x0, _ = at.box
            across = reflection_map(at.shape, np.asarray(midline, np.float64) - [x0, y0])
        else:
            across = mirror_map(at.mask, mirror, at.al, at.shape)
        measured = at.photo / shown.photo_lighting
        trust = np.where(at.face, shown.usable, 0.0).astype(np.float32)
        px = max(at.al.scale, 1.0)
        detail, seen = mirrored_detail(measured, trust, across, FILL_DETAIL_BAND[0] * px, FILL_DETAIL_BAND[1] * px)
        yy, xx = np.mgrid[0:at.shape[0], 0:at.shape[1]].astype(np.float32)
        apart = np.hypot(across[0] - xx, across[1] - yy) / np.float32(self.iod)
        self.seen = (seen * smoothstep(apart, *FILL_DETAIL_AXIS) * at.face).astype(np.float32)
        painted = a * detail
        strands = ~shown.skin & ~shown.dark_by_make  # a beard, stubble, hair: the whole of it, at the fill's level
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
        measured = self.at.photo / self.shown.photo_lighting
        u = self.shown.usable[..., None]
        return np.where(self.at.face[..., None], u * measured + (1.0 - u) * self.fill, np.nan).astype(np.float32)


def deep_eyes(relative: np.ndarray, regions: list[np.ndarray], openings: list[np.ndarray]) -> np.ndarray:
    """(h, w) bool: the union of the eyes' ``regions`` ((h, w) bool each: an eye grown over its lids and lashes) whose
    own opening (``openings``, (h, w) bool each, as the face mesh drew it) holds no signal for the most part: its
    median ``relative`` (``lift.precision``, (h, w)) past ``DEEP_EYE`` (the region's, for an opening under 20 pixels).
    Judged on the band grown around it, an eye the photo shows (a socket's shade, hair over a brow beside it) was
    taken for deep and came back pasted over with the lit eye's detail."""
    out = np.zeros(np.shape(relative), bool)
    for region, opening in zip(regions, openings):
        judged = opening if opening.sum() >= 20 else region
        if region.any() and float(np.median(relative[judged])) > DEEP_EYE:
            out |= region
    return out
