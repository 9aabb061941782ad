"""The eyes' own detail where the relit face is painted.

Where an eye is in a shadow so deep that the photo holds no signal there, and the new light lifts it, the
relit face is painted with the expected albedo (``lift``, ``albedo.expected_albedo``): smooth skin, so the
relit eye would be a grey blur. The photo
still shows the lit eye (its iris, lids and lashes) against the skin around it. Its pattern is
taken as a ratio to that skin, the fitted shading divided out first (a quadratic fitted over a
ring around the eye takes what is left of the light's gradient across it out), scaled by a
contrast, and put into the filled eye's albedo: the lit eye itself, or its mirror image across
the eyes' bisector for the other eye. Trusted albedo stays.

Arrays are on the photo's pixel grid (H, W[, C]); eye centres are ``[x, y]`` pixels.
"""
from __future__ import annotations

import cv2
import numpy as np

from .fields import smoothstep

# an eye's region: an ellipse of these semi-axes (interocular distances) along and across the eye
# axis; its skin ring runs out to RING times that. The ellipse covers the opening and lids without the brow
EYE_AXES = (0.24, 0.11)
RING = 1.5
# the lit eye's pattern at this contrast (1: as the photo shows it, the shading divided out); the relit
# photo's figures do not tell the contrasts apart, the eyes do (docs/tuning.md, "Eyes")
CONTRAST = 1.0
MAX_RATIO = 1.2  # a lit eye's pixel over its skin: brighter is shine on the cornea, not albedo
MIN_SHADING = 0.1  # the shading divided out is taken as at least this (grazing light: noise, not detail)
TRUSTED = 0.5  # an eye whose region's mean trust is at least this keeps its measured albedo


def _quadratic_fit(values: np.ndarray, where: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(h, w, C) a quadratic in (u, v) fitted to ``values`` (h, w, C) over ``where`` (h, w) bool,
    the darkest 30 % (lashes, a brow's edge) left out, evaluated everywhere; u, v (h, w)."""
    design = np.stack([np.ones_like(u), u, v, u * u, v * v, u * v], axis=-1)
    out = np.empty(values.shape, np.float64)
    for c in range(values.shape[-1]):
        x = values[..., c][where]
        keep = x >= np.percentile(x, 30)
        coef, *_ = np.linalg.lstsq(design[where][keep], x[keep], rcond=None)
        out[..., c] = design @ coef
    return out


def _ring_level(values: np.ndarray, ring: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(h, w, C) the level a ring of skin (``ring`` (h, w) bool) gives the eye inside it: a quadratic in (u, v)
    fitted to the values' brightness (their mean over channels; ``_quadratic_fit``), held within the ring's own
    brightness (5th to 95th percentile), in the ring's median colour. Fitted channel by channel, a ring half
    skin and half hair or a red eye corner extrapolated each channel its own way, and the eye came back a
    red blot (a held-out portrait's eye in the shade)."""
    brightness = values.mean(axis=-1, keepdims=True)
    fitted = _quadratic_fit(brightness, ring, u, v)
    lo, hi = np.percentile(brightness[ring], [5, 95])
    fitted = np.clip(fitted, lo, hi)
    colour = np.median(values[ring] / np.maximum(brightness[ring], 1e-6), axis=0)
    return fitted * colour


def _pattern(photo: np.ndarray, shading: np.ndarray, region: dict, contrast: float) -> np.ndarray:
    """(h, w, C) float32: an eye's pattern in its ``region`` (``EyeDetail``'s), a ratio to the skin around it
    at ``contrast``. The fitted shading is divided out first: the socket's and the lids' own shading under the
    side light is not the eye's albedo (on a render without eye texture it alone made a dark blot)."""
    box = region["box"]
    albedo_seen = photo[box] / np.maximum(np.asarray(shading, np.float64)[box], MIN_SHADING)[..., None]
    skin = _quadratic_fit(albedo_seen, region["ring"], region["u"], region["v"])
    pattern = np.clip(albedo_seen / np.maximum(skin, 1e-3), 0.0, MAX_RATIO)
    return (1.0 + contrast * (pattern - 1.0)).astype(np.float32)


class EyeDetail:
    """The lit eye's pattern in a photo, found once: ``apply`` puts it into an albedo, as often as
    there are trust maps (the output albedo's and each relit light's).

    photo (H, W, C) in [0, 1]; shading (H, W) the fitted ``n . s`` under the photo's light; eyes (2, 2)
    the eye centres, ``[x, y]`` pixels. The source is the eye whose skin ring is brighter, seen in the
    light or in the room's light only. contrast: 0 leaves every albedo as it is.
    """

    def __init__(self, photo: np.ndarray, shading: np.ndarray, eyes: np.ndarray, contrast: float = CONTRAST):
        self.regions: list[dict] = []  # per eye: box, (u, v), ellipse e, ring, and its ratio (None: no detail)
        photo = np.atleast_3d(np.asarray(photo, np.float64))
        eyes = np.asarray(eyes, np.float64)
        axis = eyes[1] - eyes[0]
        iod = float(np.linalg.norm(axis))
        if contrast <= 0 or iod < 8:
            return
        along = axis / iod
        across = np.array([-along[1], along[0]])
        h, w = photo.shape[:2]
        reach = RING * EYE_AXES[0] * iod + 2
        regions = []
        for centre in eyes:
            x0, x1 = int(max(centre[0] - reach, 0)), int(min(centre[0] + reach + 1, w))
            y0, y1 = int(max(centre[1] - reach, 0)), int(min(centre[1] + reach + 1, h))
            if x1 - x0 < 4 or y1 - y0 < 4:
                return  # an eye outside the photo
            yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
            d = np.stack([xx - centre[0], yy - centre[1]], axis=-1)
            u, v = d @ along / iod, d @ across / iod
            e = (u / EYE_AXES[0]) ** 2 + (v / EYE_AXES[1]) ** 2
            ring = (e > 1.0) & (e < RING**2)
            if ring.sum() < 30:
                return
            box = (slice(y0, y1), slice(x0, x1))
            regions.append({"box": box, "u": u, "v": v, "e": e, "ring": ring, "bright": float(np.mean(photo[box][ring]))})
        # the source is the brighter eye, in the light or not: with none when its ring lay under a quarter out of the
        # photo's shadows, a dark film still's eyes (its ring 18 % out of them) came back as flat patches of skin, a
        # glint for the iris; each eye its own source, the darker one came back in coloured speckle
        source = int(np.argmax([r["bright"] for r in regions]))
        src = regions[source]
        pattern = _pattern(photo, shading, src, contrast)
        for k, r in enumerate(regions):
            if k == source:
                r["ratio"] = pattern
                continue
            # the source's pattern mirrored: each pixel's (u, v) about this eye is (-u, v) about the source
            pos = eyes[source] + (-r["u"] * iod)[..., None] * along + (r["v"] * iod)[..., None] * across
            mx = (pos[..., 0] - src["box"][1].start).astype(np.float32)
            my = (pos[..., 1] - src["box"][0].start).astype(np.float32)
            r["ratio"] = np.stack([cv2.remap(np.ascontiguousarray(pattern[..., c]), mx, my, cv2.INTER_LINEAR,
                                             borderMode=cv2.BORDER_CONSTANT, borderValue=1.0)
                                   for c in range(pattern.shape[-1])], axis=-1)
        self.regions = regions

    def apply(self, albedo: np.ndarray, trust: np.ndarray) -> np.ndarray:
        """(H, W, C) ``albedo`` (from ``photo_albedo``) with the pattern put into each eye whose
        region's mean ``trust`` (H, W, in [0, 1], the weight the albedo's measured part had) is under
        ``TRUSTED``; trusted pixels keep their value. Returns a new array (float32)."""
        out = np.array(albedo, np.float32, copy=True)
        for r in self.regions:
            box = r["box"]
            if float(np.mean(trust[box][r["e"] < 1.0])) >= TRUSTED:
                continue
            known = r["ring"] & np.isfinite(out[box][..., 0])
            if known.sum() < 30:
                continue
            level = _ring_level(np.nan_to_num(out[box]).astype(np.float64), known, r["u"], r["v"])
            blend = (smoothstep(1.0 - r["e"], 0.0, 0.35) * (1.0 - trust[box]))[..., None]
            region = out[box]
            detail = blend * level * r["ratio"] + (1.0 - blend) * region
            out[box] = np.where(np.isfinite(region), detail, region).astype(np.float32)
        return out
