"""Relighting at the photo's own resolution, in colour, put back into the photo.

The fit lives on the coarse model grid, but the photo holds more: where the face is lit, its
albedo is measured pixel by pixel as ``I / S`` (``S = n . s`` the fitted shading, per colour
channel), which keeps the photo's own detail; where it is in shadow, too dark or clipped, the
albedo comes from the fit's albedo map (mirrored and filled on the model grid), brought to the
measured albedo's local level and colour so that no seam shows where the two meet. The face is
then ``albedo x S'`` under the new light ``S'`` (with the new light's cast shadows) and is
feathered back into the photo, which is untouched outside the face.

Everything here is on the photo's pixel grid (H, W); ``C`` is 1 (grey) or 3 (RGB).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

# Shading below which I / S is not trusted at all, and above which it is trusted fully (between: a
# smooth ramp), as the model grid's albedo (``albedo.MIN_SHADING``): the division amplifies the normals'
# errors (docs/tuning.md, "Relighting the photo")
TRUST_SHADING = (0.4, 0.6)
# where the new light changes the shading little, S' / S under this ramp, I / S is trusted down to
# MIN_SHADING (``shading_trust``): the division's errors are not amplified by the relighting
MAX_AMPLIFICATION = (1.1, 1.5)
MIN_SHADING = (0.08, 0.15)
CLIPPED = 0.995  # brightness at or above this in any channel: the skin's value is unknown
# a clipped pixel's bound divides by the photo's shading, at least this (``clipped_floor``)
CLIP_RATIO_FLOOR = 0.05
LIT_SHADING = 0.3  # skin with at least this shading (n . s) is lit: the relit face's exposure is matched on it
MAX_CHROMA_DISTANCE = 0.08  # chromaticity (r, g, b) / (r + g + b) this far from the face's median: not skin
# the skin's colour followed into its shade (``skin_locus``): fitted at this share of the lit skin's brightness,
# its slope (chromaticity per e-fold of brightness) held to this, and followed down to this share
SHADE_FIT = (0.3, 0.6)
SHADE_MAX_SLOPE = 0.12
SHADE_FLOOR = 0.1
# the share of the light a face's shadowed side keeps (ambient, fill): a face relit from the side has its shadowed
# side this bright, as a photo's is, not black. Measured from the photo's attached shadow when it shows one
# (a dark room: a few per cent), else the default, a room's fill light (docs/tuning.md, "Relighting the photo")
DEFAULT_AMBIENT = 0.15
AMBIENT_RANGE = (0.0, 0.5)
# ... measured on the face's core, this far inside its border (interocular distances), when at least this share
# of the face shows it there (``photo_ambient``)
AMBIENT_RIM = 0.15
AMBIENT_MIN_SHARE = 0.003
# a filled pixel's detail seen across the face is kept within this range of its local level (``mirrored_detail``)
DETAIL_RANGE = (0.5, 2.0)
# the albedo of the side the light reaches less is raised toward its mirror's (``mirror_lift``), both averaged
# over this many interocular distances, by at most this factor, where the trusted skin around either covers
# this share (a ramp); not within this many interocular distances of the face's midline; as far as a new light
# brightens the pixel, S' / S over this ramp (docs/relighting.md)
LIFT_SIGMA = 0.06
LIFT_CAP = 1.6
LIFT_SUPPORT = (0.2, 0.4)
LIFT_AXIS = 0.05
LIFT_AMPLIFICATION = (1.0, 1.2)
LIFT_STEP = 4.0  # the lift is computed on a grid of sigma / this pixels (at least the box's)
# the relit face fades into the photo over this share of the feather inside its border (``inner_alpha``): a
# wider fade costs the relit face (docs/tuning.md, "Relighting the photo")
INNER_FEATHER = 0.12
# outside the face the photo follows the face's change of light within this range: up to 1.6x (a face's shadowed
# side brightened 5x would otherwise light its dark background up as a halo), down to 0.15x (a face relit into
# shadow darkens its ear, hair and neck with it: held at 0.5, its dark border met a brighter ring on the face's edge)
RATIO_OUTSIDE = (0.15, 1.6)
# ... but on the face's own skin beyond the model (inside the face mesh's outline, past the model's mask: the jaw
# and cheeks of a face the model does not reach) up to this: it is the face, lit as its rim is, and a jaw in
# shadow held at 1.6x stayed a dark wedge beside a face relit 5x brighter (Yale B at +-70). What bounds it is the
# relit rim's level beside it (``beyond_ratio``); this only keeps a black pixel's gain finite: at 8x a jaw in deep
# shadow (3 grey levels of 255, Yale B's subjects at -70) stayed a dark wedge at a quarter of the frontal photo's level
RATIO_BEYOND = 64.0
# what keeps its own pixels (hair over the face) is brightened up to this at a feather inside the face (``kept_cap``)
RATIO_KEPT = 8.0
# ... that reach fading back to ``RATIO_OUTSIDE`` over this share of the feather either side of that skin's border
BEYOND_EDGE = 0.25
# a gain past ``RATIO_OUTSIDE`` lifts the photo's detail (finer than this share of the change of light's blur) by
# ``RATIO_OUTSIDE`` only, the rest of it its smooth part (``quieted``): a shadowed jaw's noise brightened 5-8x
# came back as grain
DETAIL_SHARE = 1.0 / 6.0
# the face's change of light at its border is measured on its rim, this share of the feather wide (``face_rim``):
# averaged over the whole face, the interior's light came through, and a side light's dark rim met a brighter ring
RIM_SHARE = 0.35
# shine: a skin pixel's measured albedo above this x its local skin level (averaged over ``SHEEN_SCALE``
# interocular distances) is the photo's specular shine, not the skin's colour (``sheen``)
SHEEN_MARGIN = 1.1
SHEEN_SCALE = 0.15
# a glint (``glints``): skin's colour plus white to within this share of the pixel's colour, with at least this
# share of the skin's level around it under the white
GLINT_FIT = 0.05
GLINT_DIFFUSE = 0.4
# how sharp skin's shine is (``shine_lobe``): the Blinn-Phong exponent 2 / m^2 - 2 of the Beckmann roughness
# m = 0.35 measured on faces (Weyrich et al. 2006): the peak of a highlight keeps 13 % of itself under a light
# moved by 60 degrees, a cheek's shine beside it under 1 %
SHINE_LOBE = 14.0


def smoothstep(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """0 below ``lo``, 1 above ``hi``, a smooth (C1) ramp between."""
    t = np.clip((np.asarray(x, np.float32) - np.float32(lo)) / np.float32(hi - lo), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def blur(values: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur of (H, W[, C]) float values, edges replicated. A wide blur is taken on a grid
    shrunk so that it is 2 pixels wide there, then brought back (bilinear): a smooth field needs
    no more, and a 12-megapixel photo's wide blurs take milliseconds instead of seconds."""
    v = np.asarray(values, np.float32)
    h, w = v.shape[:2]
    k = int(sigma // 2)
    if k <= 1:
        return cv2.GaussianBlur(v, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE).reshape(v.shape)
    small = cv2.resize(v, (max(1, round(w / k)), max(1, round(h / k))), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma / k, borderType=cv2.BORDER_REPLICATE)
    out = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
    return out.reshape(v.shape)


def grow(mask: np.ndarray, radius: float) -> np.ndarray:
    """(H, W) bool ``mask`` grown by a disc of ``radius`` pixels (at least 1)."""
    r = max(1, int(round(radius)))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    return cv2.dilate(mask.astype(np.uint8), disc) > 0


def weighted_blur(values: np.ndarray, weights: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Normalised Gaussian average of ``values`` (H, W[, C]) with ``weights`` (H, W): ``(average,
    the weight around each pixel)``; the average is meaningless where that weight is ~0."""
    w = np.asarray(weights, np.float32)
    v = np.asarray(values, np.float32)
    den = blur(w, sigma)
    num = blur(v * (w[..., None] if v.ndim == 3 else w), sigma)
    safe = np.maximum(den, 1e-12)
    return num / (safe[..., None] if v.ndim == 3 else safe), den


def lit_weight(photo: np.ndarray, lit: np.ndarray, face: np.ndarray, feather_px: float) -> np.ndarray:
    """(H, W) in [0, 1], whatever the light: how far the photo's own ``I / S`` is kept: zero off the
    face, in cast or attached shadow (``lit`` False) and where any channel is clipped; feathered
    over ``feather_px`` so the blend has no edge. Whatever the photo shows there is kept, skin or not
    (eyes, teeth, lips, brows, hair over the forehead, glasses): the relighting is a ratio of
    shadings on its own pixels, and only what is in shadow is filled."""
    img = np.atleast_3d(photo)
    clipped = np.any(img >= CLIPPED, axis=-1)
    hard = face & lit
    # feather inward only, from the shadows: not from the face's edge, where the relit face fades into the photo
    # anyway (``inner_alpha``), and where a fill half-trusted drew a line of skin over the hair beside the face;
    # clipped pixels (specks of shine, mostly) are cut out without a feather of their own (their own feather
    # changed nothing measurable)
    soft = blur((hard | ~face).astype(np.float32), feather_px)
    soft = np.where(hard & ~clipped, soft, 0.0)
    return np.clip(2.0 * soft - 0.5, 0.0, 1.0)


def skin(photo: np.ndarray, where: np.ndarray) -> np.ndarray:
    """(H, W) bool: ``where`` the photo has the face's skin colour (a chromaticity within
    ``MAX_CHROMA_DISTANCE`` of the median over the inner half of ``where``: its border may be hair or
    background); all of ``where`` for a grey photo. The fill's level and colour are matched on skin
    only: eyes, lips, brows and hair would tint it."""
    return skin_distance(photo, where) < MAX_CHROMA_DISTANCE


def skin_distance(photo: np.ndarray, where: np.ndarray, shade: bool = False,
                  keep_out: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32: how far each pixel's chromaticity is from the face's skin colour (the median over the inner
    half of ``where`` (H, W) bool); inf off ``where``, 0 on it for a grey photo (or too few pixels to tell).

    shade: from the skin's colour at the pixel's brightness instead where that is nearer (``skin_locus``: darker
    skin is redder in an ordinary photo; a shadow under the nose was taken for something else and kept as it was,
    a brown patch on a face relit from the front); not on ``keep_out`` (H, W) bool, e.g. the eyes and lips."""
    img = np.atleast_3d(photo)
    where = np.asarray(where, bool)
    if img.shape[-1] != 3 or where.sum() <= 50:
        return np.where(where, np.float32(0.0), np.float32(np.inf))
    brightness = _channel_sum(img)
    chroma = img / np.maximum(brightness, 1e-6)[..., None]
    depth = cv2.distanceTransform(where.astype(np.uint8), cv2.DIST_L2, 3)
    inner = where & (depth >= 0.5 * depth.max())
    inner = inner if inner.sum() > 50 else where
    median = np.median(chroma[inner], axis=0).astype(np.float32)
    distance = _chroma_distance(chroma, median)
    if shade:
        use = where if keep_out is None else where & ~keep_out
        slope, log_level = skin_locus(chroma, brightness, use & inner & (distance < MAX_CHROMA_DISTANCE), use, median)
        if slope is not None:
            # below the lit level, the locus: median + slope ln(b / level), down to SHADE_FLOOR
            depth_below = np.clip(np.log(np.maximum(brightness, 1e-6)) - log_level, np.log(SHADE_FLOOR), 0.0)
            along = _chroma_distance(chroma, median, slope, depth_below.astype(np.float32))
            distance = np.where(use, np.minimum(distance, along), distance)
    return np.where(where, distance, np.float32(np.inf)).astype(np.float32)


def _chroma_distance(chroma: np.ndarray, median: np.ndarray, slope: np.ndarray | None = None,
                     depth: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32 the distance of ``chroma`` (H, W, 3) from ``median`` (3,), or from ``median + slope depth``
    (slope (3,), depth (H, W)), channel by channel (``np.linalg.norm`` over the last axis is slow)."""
    out = np.zeros(chroma.shape[:2], np.float32)
    for c in range(chroma.shape[-1]):
        ref = median[c] if slope is None else median[c] + slope[c] * depth
        out += np.square(chroma[..., c] - ref)
    return np.sqrt(out)


def skin_locus(chroma: np.ndarray, brightness: np.ndarray, lit_skin: np.ndarray, where: np.ndarray,
               median: np.ndarray) -> tuple[np.ndarray | None, float]:
    """The chromaticity skin has below the lit skin's level: ``(k, ln level)``, skin at brightness ``b`` under the
    level having ``median + k ln(b / level)`` (``median`` (3,) at and above it; ``skin_distance`` follows it down to
    ``SHADE_FLOOR`` of the level). ``level``: the median ``brightness`` (H, W) of ``lit_skin`` (H, W) bool; ``k`` (3,):
    the median chromaticity of the pixels of ``where`` at ``SHADE_FIT`` of the level (where skin is most of a face),
    less ``median``, over their median ``ln(b / level)``, held to ``SHADE_MAX_SLOPE``; None when too few pixels tell.
    In held-out photos skin at a fifth to a third of its lit level is 0.09-0.14 from the lit skin's chromaticity,
    redder (docs/relighting.md, "Skin in its shade")."""
    if lit_skin.sum() < 50:
        return None, 0.0
    log_level = float(np.log(max(float(np.median(brightness[lit_skin])), 1e-6)))
    band = (brightness > SHADE_FIT[0] * np.exp(log_level)) & (brightness < SHADE_FIT[1] * np.exp(log_level))
    fit = where & band
    if fit.sum() < 50:
        return None, log_level
    x = np.log(np.maximum(brightness[fit], 1e-6)) - log_level
    k = (np.median(chroma[fit], axis=0) - median) / float(np.median(x))
    k *= min(1.0, SHADE_MAX_SLOPE / max(float(np.linalg.norm(k)), 1e-9))
    return k.astype(np.float32), log_level


def fine_texture(photo: np.ndarray, sigma_px: float) -> np.ndarray:
    """(H, W) float32: the photo's local contrast finer than ``sigma_px`` photo pixels: ``log I`` (``I`` the sum of
    its channels) less its Gaussian blur over ``sigma_px``, its RMS over a Gaussian of ``2 sigma_px`` around each
    pixel. photo (H, W, C) linear. Hair and a beard are strands, skin
    is smooth, in its shade too (at a hundredth of the eyes' distance, held-out portraits: lit skin's median
    0.02-0.08, a goatee's 0.2)."""
    log = np.log(np.maximum(_channel_sum(np.atleast_3d(np.asarray(photo, np.float32))), np.float32(1e-3)))
    fine = log - cv2.GaussianBlur(log, (0, 0), sigma_px)
    return np.sqrt(cv2.GaussianBlur(fine * fine, (0, 0), 2.0 * sigma_px)).astype(np.float32)


def shading_trust(shading: np.ndarray, new_shading: np.ndarray | None = None) -> np.ndarray:
    """(H, W) in [0, 1]: zero where the fitted shading ``S`` is under ``TRUST_SHADING``, one above.

    new_shading (H, W): the new light's ``S'``, for the albedo one relit image uses. An error
    ``e`` in the fitted ``S`` reaches the relit pixel as ``rho S' e / S``: where the light changes
    the shading little (``S' / S`` under ``MAX_AMPLIFICATION``), ``I / S`` is trusted down to
    ``MIN_SHADING`` even where ``S`` is small. A photo relit with its own light then keeps its
    own detail everywhere it is lit."""
    trust = smoothstep(shading, *TRUST_SHADING)
    if new_shading is not None:
        s = np.asarray(shading, np.float32)
        amplification = np.asarray(new_shading, np.float32) / np.maximum(s, np.float32(1e-3))
        kept = (1.0 - smoothstep(amplification, *MAX_AMPLIFICATION)) * smoothstep(s, *MIN_SHADING)
        trust = np.maximum(trust, kept)
    return trust


def smooth_coarse(coarse: np.ndarray, face: np.ndarray, sigma_px: float) -> np.ndarray:
    """(H, W) the fit's albedo map ``coarse`` (on the photo grid, NaN off ``face``) averaged over a
    Gaussian of ``sigma_px`` photo pixels within ``face`` (normalised there, so a constant stays
    constant up to the face's edge); NaN off ``face``.

    The fit's map lives on the model grid, whose pixels are 1-3 photo pixels on a portrait. Brought
    to the photo as it is, the steps where its measured, mirrored and filled parts meet show in the
    fill as a staircase of the model grid's pixels (about a model pixel is what it takes; its detail
    is no finer than that anyway, and the photo's own detail is kept where it is measured)."""
    f = np.asarray(face, bool)
    values = np.where(f, np.nan_to_num(np.asarray(coarse, np.float32)), np.float32(0.0))
    average, _ = weighted_blur(values, f.astype(np.float32), sigma_px)
    return np.where(f, average, np.nan).astype(np.float32)


def local_average(values: np.ndarray, weight: np.ndarray, sigma_px: float, fallback: np.ndarray) -> np.ndarray:
    """(H, W[, C]) float32 the ``weight`` (H, W)-weighted average of ``values`` (H, W[, C]) around each pixel,
    coarse to fine: over ``4 sigma_px``, then over ``sigma_px`` photo pixels, each scale overriding the last
    where its weight has support (a ramp), ``fallback`` (H, W[, C]) where neither has."""
    out = np.array(fallback, np.float32, copy=True)
    for s in (4.0 * sigma_px, sigma_px):
        average, support = weighted_blur(values, weight, s)
        k = smoothstep(support, 0.02, 0.1)
        if out.ndim == 3:
            k = k[..., None]
        out = k * average + (1.0 - k) * out
    return out.astype(np.float32)


def _channel_sum(values: np.ndarray) -> np.ndarray:
    """(H, W) float32 the sum over the channels of (H, W, C) values."""
    out = np.array(values[..., 0], np.float32, copy=True)
    for c in range(1, values.shape[-1]):
        out += values[..., c]
    return out


def brightened_as_around(albedo: np.ndarray, photo: np.ndarray, lighting: np.ndarray, new_lighting: np.ndarray,
                         skin: np.ndarray, kept: np.ndarray, sigma_px: float,
                         cap: np.ndarray | None = None) -> np.ndarray:
    """(H, W, C) float32 ``albedo`` with the pixels ``kept`` (H, W) in [0, 1] (not skin, their own pixels kept:
    eyes, brows, hair, glasses, a red nose) relit by the new lighting no brighter than the ``skin`` (H, W) bool
    around them: ``I x min(S' / S, R)``, with ``R`` the skin's relit over photo brightness (``albedo x S' / I``)
    averaged around (``local_average`` over ``sigma_px``; their own ``S' / S`` where no skin is near).

    The photo's shading ``S`` at such a pixel is the fitted normals', which there (a nostril's wing, an eye's
    socket, hair over the face) can lean far from the light: divided by, it brightened them 3-5x under a
    frontal light and a red nose glowed orange, clipped. Capped at their own ratio, a photo relit by its own
    light keeps them as they are, and a new light's cast shadow stays sharp on them.
    albedo (H, W, C); photo (H, W, C) linear; lighting, new_lighting (H, W): ``S``, ``S'`` with the room's
    light (``with_ambient``). cap (H, W) or None: a bound on each pixel's ``S' / S`` besides (``kept_cap``)."""
    w = np.asarray(kept, np.float32)
    ys, xs = np.nonzero(w > 0)
    if not ys.size:
        return np.asarray(albedo, np.float32)
    img = np.atleast_3d(np.asarray(photo, np.float32))
    new = np.asarray(new_lighting, np.float32)
    grey = _channel_sum(img)  # (sums: the ratio is the same, and numpy's mean over 3 channels is slow)
    use = np.asarray(skin, bool) & (grey > 3e-3)
    relit_ratio = np.where(use, np.nan_to_num(_channel_sum(np.atleast_3d(albedo))) * new / np.maximum(grey, 3e-3),
                           np.float32(0.0)).astype(np.float32)
    own = new / np.maximum(np.asarray(lighting, np.float32), np.float32(1e-3))
    around = local_average(relit_ratio, use.astype(np.float32), sigma_px, own)
    # only the kept pixels change: a colour portrait's box is megapixels, they a fifth of it
    ratio = np.minimum(around[ys, xs], own[ys, xs])
    if cap is not None:
        ratio = np.minimum(ratio, np.asarray(cap, np.float32)[ys, xs])
    ratio = ratio / np.maximum(new[ys, xs], np.float32(1e-3))
    out = np.array(albedo, np.float32, copy=True)
    wk = w[ys, xs][:, None]
    out[ys, xs] = wk * img[ys, xs] * ratio[:, None] + (np.float32(1.0) - wk) * out[ys, xs]
    return out


def kept_cap(inside: np.ndarray, feather_px: float) -> np.ndarray:
    """(H, W) float32: how far what keeps its own pixels (hair over the face, a beard) may be brightened, by its
    distance ``inside`` (H, W) the face (as ``inner_alpha`` takes it): ``RATIO_OUTSIDE``'s top at the face's edge, as
    the photo just beyond it (``outside_gain``), rising to ``RATIO_KEPT`` at ``feather_px`` inside, unbounded
    further in. Brightened as the skin around it up to the edge, hair over a temple relit into the light came back a
    pale ghost of hair, cut at the outline from the same hair beyond it."""
    hi = np.float32(RATIO_OUTSIDE[1])
    cap = hi + np.float32(RATIO_KEPT - RATIO_OUTSIDE[1]) * smoothstep(inside, 0.0, max(feather_px, 1.0))
    return np.where(inside >= feather_px, np.float32(np.inf), cap).astype(np.float32)


def photo_albedo(photo: np.ndarray, shading: np.ndarray, weight: np.ndarray, coarse: np.ndarray,
                 face: np.ndarray, sigma_px: float, skin_only: np.ndarray | None = None) -> np.ndarray:
    """(H, W, C) albedo at the photo's resolution.

    photo (H, W, C) in [0, 1]; shading (H, W) the fitted ``n . s``; weight (H, W) from
    ``trusted_weight``; coarse (H, W) the fit's albedo map brought to the photo grid (smooth, known
    over the whole face); face (H, W) bool; sigma_px: the scale, in photo pixels, over which the
    coarse map is matched to the measured albedo's level and colour (a fraction of the face).
    ``albedo = w I / S + (1 - w) coarse g``, with ``g`` (H, W, C) the local ratio of measured to
    coarse albedo over trusted pixels (wider averages where the shadow is large, the face's median
    where nothing near is trusted), of those only the ``skin_only`` (H, W) bool ones when given.
    """
    img = np.atleast_3d(np.asarray(photo, np.float32))  # float32 throughout: a large photo's arrays are many
    measured = img / np.maximum(np.asarray(shading, np.float32), np.float32(1e-3))[..., None]
    w = np.where(face, np.asarray(weight, np.float32), np.float32(0.0))
    fill = float(np.nanmedian(coarse[face])) if face.any() else 1.0
    base = np.maximum(np.nan_to_num(np.asarray(coarse, np.float32), nan=fill), np.float32(1e-3))
    ratio = measured / base[..., None]
    wg = w if skin_only is None else np.where(skin_only, w, np.float32(0.0))  # what the fill is matched on
    trusted = wg > 0.5
    if trusted.sum() < 20:
        gain = np.ones_like(ratio)
    else:
        gain = local_average(ratio, wg, sigma_px, np.broadcast_to(np.median(ratio[trusted], axis=0), ratio.shape))
    filled = base[..., None] * gain
    out = w[..., None] * measured + (1.0 - w[..., None]) * filled
    return np.where(face[..., None], np.clip(out, 0.0, None), np.nan).astype(np.float32)


def glints(photo: np.ndarray, skin: np.ndarray, where: np.ndarray, sigma_px: float,
           features: np.ndarray | None = None, reach_px: float | None = None) -> np.ndarray:
    """(H, W) bool: the pixels of ``where`` (H, W) bool that are skin with the light's white reflection on it, too
    white to pass ``skin``'s colour test. Each is brighter than the skin's level around it (the average over
    ``sigma_px`` of ``skin`` (H, W) bool) and its colour ``c`` (linear RGB) is the skin's median colour ``m`` times
    ``a`` plus white ``k (1, 1, 1)``, ``k > 0``, to within ``GLINT_FIT`` of ``|c|``; and its patch of such pixels
    holds one with skin under the white, at least ``GLINT_DIFFUSE`` of that level in ``a`` (a highlight's core is
    white, the skin's colour showing at its rim), within ``reach_px`` of it when given (a highlight is small: white
    hair or a wall that one touches is not taken whole). Not in ``features`` (H, W) bool (eyes, teeth, lips, brows:
    white or bright, and theirs). A grey photo has no colour to tell by: ``skin`` is all of it there, and none are.

    A highlight on a forehead or a cheek is whiter than the skin around it; told apart from the skin by its colour
    alone it was kept as the photo shows it, like an eye, and stayed as a pale patch on a cheek relit into shadow.
    A grey wall or white hair (no skin under the white at its rim) and a lip (not the skin's colour) are not."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    out = np.zeros(where.shape, bool)
    if img.shape[-1] != 3 or skin.sum() <= 50:
        return out
    m = np.median(img[skin], axis=0).astype(np.float64)
    m = m / max(float(m.mean()), 1e-6)  # the skin's colour at brightness 1 (mean of the channels)
    basis = np.stack([m, np.ones(3)], axis=1)  # (3, 2): skin, white
    cand = where & ~skin
    if features is not None:
        cand &= ~features
    if not cand.any():
        return out
    c = img[cand].astype(np.float64)  # (n, 3)
    ak = c @ np.linalg.pinv(basis).T  # (n, 2) least squares: c ~ a m + k 1
    fit_error = np.linalg.norm(c - ak @ basis.T, axis=1) / np.maximum(np.linalg.norm(c, axis=1), 1e-6)
    level, _ = weighted_blur(img.mean(axis=-1), skin.astype(np.float32), sigma_px)
    lv = level[cand].astype(np.float64)
    white = (fit_error < GLINT_FIT) & (ak[:, 1] > 0.0) & (c.mean(axis=1) > lv)
    patches = np.zeros(where.shape, np.uint8)
    patches[cand] = white
    seeds = np.zeros(where.shape, bool)
    seeds[cand] = white & (ak[:, 0] >= GLINT_DIFFUSE * lv)
    count, labels = cv2.connectedComponents(patches, connectivity=8)
    keep = np.zeros(count, bool)
    keep[np.unique(labels[seeds])] = True
    keep[0] = False
    out = keep[labels]
    if reach_px is not None and seeds.any():
        out &= cv2.distanceTransform((~seeds).astype(np.uint8), cv2.DIST_L2, 3) <= reach_px
    return out


def sheen(albedo: np.ndarray, skin: np.ndarray, trusted: np.ndarray, sigma_px: float,
          margin: float = SHEEN_MARGIN) -> np.ndarray:
    """(H, W, C) float32 >= 0: the photo's shine in its measured albedo: on ``skin`` (H, W) bool, how far the
    albedo (H, W, C) rises above ``margin`` x its local level (the average over ``sigma_px`` of the ``trusted``
    (H, W) bool skin around it); 0 elsewhere. A highlight on a cheek, read as albedo, stays where it is whatever
    the new light, and glowed on a cheek relit into shadow (``without_sheen``)."""
    a = np.nan_to_num(np.atleast_3d(np.asarray(albedo, np.float32)))
    w = (skin & trusted).astype(np.float32)
    level, _ = weighted_blur(a, w, sigma_px)
    # again with the shine held down to the margin: a highlight would otherwise raise the level it is measured on
    level, _ = weighted_blur(np.minimum(a, np.float32(margin) * level), w, sigma_px)
    excess = np.clip(a - np.float32(margin) * level, 0.0, None)
    return np.where(skin[..., None], excess, np.float32(0.0)).astype(np.float32)


def shine_kept(lighting: np.ndarray, new_lighting: np.ndarray, lobe: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32 in [0, 1]: the share of the photo's shine a new light keeps: ``S'/S`` (a pixel going into
    shadow loses it) and at most ``lobe`` (``shine_lobe``: its highlight moves away). lighting, new_lighting (H, W)
    the photo's and the new light's."""
    keep = np.asarray(new_lighting, np.float32) / np.maximum(np.asarray(lighting, np.float32), np.float32(1e-3))
    if lobe is not None:
        keep = np.minimum(keep, lobe)
    return np.clip(keep, 0.0, 1.0).astype(np.float32)


def without_sheen(albedo: np.ndarray, shine: np.ndarray, lighting: np.ndarray, new_lighting: np.ndarray,
                  lobe: np.ndarray | None = None) -> np.ndarray:
    """(H, W, C) the albedo a new light sees: the photo's shine (``sheen``) taken out as far as the new light
    darkens the pixel, ``1 - S'/S`` (the photo's own light keeps it all; a pixel going into shadow loses it, a
    highlight being the light's own reflection), and as far as the highlight moves away from it (``lobe``, what
    ``shine_lobe`` keeps, None: all). lighting, new_lighting (H, W) the photo's and the new light's."""
    drop = np.float32(1.0) - shine_kept(lighting, new_lighting, lobe)
    return np.clip(np.asarray(albedo, np.float32) - shine * drop[..., None], 0.0, None).astype(np.float32)


def shine_lobe(normals: np.ndarray, light: np.ndarray, new_light: np.ndarray,
               exponent: float = SHINE_LOBE) -> np.ndarray:
    """(H, W) float32 in [0, 1]: how much of the photo's shine stays where it is under a new light. A highlight is
    the light's reflection toward the camera, brightest where the normal is halfway between the light and the
    view (Blinn-Phong: ``(n . h)^k``); under the new light that place moves to the new halfway vector ``h'``,
    and a pixel keeps ``((n . h') / (n . h))^k`` of its shine, at most all of it (no shine is made where the
    photo shows none). The photo's own light keeps it all. normals (H, W, 3), light and new_light (3,) unit,
    camera frame (the view, toward the camera, is +z)."""
    n = np.asarray(normals, np.float32)
    view = np.array([0.0, 0.0, 1.0])
    h = np.asarray(light, np.float64) + view
    h_new = np.asarray(new_light, np.float64) + view
    old = n @ (h / max(np.linalg.norm(h), 1e-9)).astype(np.float32)
    new = n @ (h_new / max(np.linalg.norm(h_new), 1e-9)).astype(np.float32)
    ratio = np.clip(new, 0.0, None) / np.maximum(old, np.float32(1e-3))
    return np.where(old > 1e-3, np.minimum(ratio, np.float32(1.0)) ** np.float32(exponent), np.float32(1.0)
                    ).astype(np.float32)


def reflection_map(shape: tuple[int, int], midline: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(map_x, map_y), each (H, W) float32: where each pixel of an (H, W) box falls when mirrored across the
    line through the two points ``midline`` (2, 2) ``[x, y]`` of the box (a face's vertical symmetry axis),
    for ``cv2.remap``."""
    a = np.asarray(midline[0], np.float64)
    d = np.asarray(midline[1], np.float64) - a
    d /= max(float(np.linalg.norm(d)), 1e-9)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    px, py = xx - a[0], yy - a[1]
    t = px * d[0] + py * d[1]
    return (a[0] + 2.0 * t * d[0] - px).astype(np.float32), (a[1] + 2.0 * t * d[1] - py).astype(np.float32)


def axis_distance(shape: tuple[int, int], axis: np.ndarray) -> np.ndarray:
    """(H, W) float32: each pixel's distance, in pixels, from the line through the two points ``axis``
    (2, 2) ``[x, y]`` of an (H, W) box."""
    a = np.asarray(axis[0], np.float64)
    d = np.asarray(axis[1], np.float64) - a
    d /= max(float(np.linalg.norm(d)), 1e-9)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    return np.abs((xx - a[0]) * d[1] - (yy - a[1]) * d[0]).astype(np.float32)


def mirrored_detail(measured: np.ndarray, weight: np.ndarray, mirror: tuple[np.ndarray, np.ndarray],
                    fine_px: float, coarse_px: float) -> tuple[np.ndarray, np.ndarray]:
    """The measured albedo's detail seen across the face, for a fill that has none of its own.

    measured (H, W, C) ``I / lighting``; weight (H, W) in [0, 1] how far it is trusted; mirror: the
    ``reflection_map`` of the box. The detail is a band of the measured albedo, its average over
    ``fine_px`` over its average over ``coarse_px`` (trusted pixels only; the coarse scale is what the
    fit's map already holds, the fine one leaves out pores and noise, which a mirror would only add to the
    other side's own), in [``DETAIL_RANGE``]; 1 where nothing is trusted. Returns (detail (H, W, C) of the
    mirror pixel, its trust (H, W): the mirror pixel's weight, as a ramp from 0.5 to 1)."""
    w = np.asarray(weight, np.float32)
    coarse, _ = weighted_blur(measured, w, coarse_px)
    fine = weighted_blur(measured, w, fine_px)[0] if fine_px > 0 else np.asarray(measured, np.float32)
    band = np.where((w > 0.5)[..., None], fine / np.maximum(coarse, np.float32(1e-4)), np.float32(1.0))
    band = np.clip(band, *DETAIL_RANGE).astype(np.float32)
    seen = cv2.remap(band, mirror[0], mirror[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=1.0).reshape(band.shape)
    trust = cv2.remap(w, mirror[0], mirror[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return seen, np.clip(2.0 * trust - 1.0, 0.0, 1.0).astype(np.float32)


def mirror_lift(albedo: np.ndarray, weight: np.ndarray, axis: np.ndarray, shading: np.ndarray, sigma_px: float,
                reach: np.ndarray, amplification: np.ndarray | None = None) -> np.ndarray:
    """(H, W, C) float32 >= 1: how much the albedo of the side a photo's light reaches less is raised
    toward its mirror pixel's across the face's ``axis`` (2, 2) ``[x, y]`` (``reflection_map``), both averaged
    over ``sigma_px`` (``weighted_blur`` by ``weight`` (H, W), the trusted skin) and the raise at most
    ``LIFT_CAP``.

    An error ``e`` in the fitted shading ``S`` leaves ``e / S`` in ``I / S``, and the fitted normals of the
    far flank of the nose and the cheek beyond it lean toward the light (the model's surface is smoother
    than a face): their albedo holds a shadow the relighting then brightens by ``S' / S``. A face's albedo
    is nearly symmetric at this scale, and the mirror pixel, lit more, is measured with a smaller error.
    The raise's exponent is how much less lit the pixel is than its mirror, ``(S_m - S) / S_m``, times
    ``reach`` (H, W) in [0, 1] (0 where the mirror says nothing: near the midline, off the face), times
    how much the new light brightens the pixel (``amplification`` ``S' / S`` (H, W) over
    ``LIFT_AMPLIFICATION``; None: fully): a photo relit with its own light keeps its own pixels.
    albedo (H, W, C); shading (H, W) ``S`` with the room's light. A smooth field: computed on a grid
    ``LIFT_STEP`` times finer than ``sigma_px`` (a 4-megapixel face's box a ninth of its pixels), then
    brought back (bilinear)."""
    a = np.nan_to_num(np.asarray(albedo, np.float32))  # NaN off the face
    h, w = a.shape[:2]
    step = max(1, int(sigma_px // LIFT_STEP))
    hs, ws = h // step, w // step
    if min(hs, ws) < 2:
        step, hs, ws = 1, h, w

    def small(v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, np.float32)[:hs * step, :ws * step]
        return v if step == 1 else cv2.resize(v, (ws, hs), interpolation=cv2.INTER_AREA).reshape((hs, ws) + v.shape[2:])

    wt = small(weight)
    mean = small(a * np.asarray(weight, np.float32)[..., None]) / np.maximum(wt, np.float32(1e-12))[..., None]
    level, around = weighted_blur(mean, wt, sigma_px / step)
    # pixel centres: a small pixel's is (i + 0.5) step - 0.5 of the box's
    mirror = reflection_map((hs, ws), (np.asarray(axis, np.float64) + 0.5) / step - 0.5)

    def across(v: np.ndarray) -> np.ndarray:
        return cv2.remap(v, mirror[0], mirror[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                         borderValue=0.0).reshape(v.shape)

    s = small(shading)
    s_seen = across(s)
    strength = np.clip((s_seen - s) / np.maximum(s_seen, np.float32(1e-3)), 0.0, 1.0) * small(reach)
    # measured on both sides: the trusted skin around the pixel and around its mirror
    strength *= smoothstep(around, *LIFT_SUPPORT) * smoothstep(across(around), *LIFT_SUPPORT)
    if amplification is not None:
        strength *= smoothstep(small(amplification), *LIFT_AMPLIFICATION)
    ratio = np.clip(across(level) / np.maximum(level, np.float32(1e-4)), 1.0, LIFT_CAP)
    lift = np.power(ratio, strength[..., None]).astype(np.float32)
    if step > 1:
        lift = cv2.resize(lift, (ws * step, hs * step), interpolation=cv2.INTER_LINEAR).reshape(
            (hs * step, ws * step, lift.shape[2]))
    if lift.shape[:2] != (h, w):  # the last few rows and columns past a whole step: the edge's own
        lift = np.pad(lift, ((0, h - lift.shape[0]), (0, w - lift.shape[1]), (0, 0)), mode="edge")
    return lift


def clipped_floor(face_image: np.ndarray, photo: np.ndarray, shading: np.ndarray, new_shading: np.ndarray,
                  gain: float, face: np.ndarray, diffuse: np.ndarray | None = None,
                  keep: np.ndarray | None = None, clipped: np.ndarray | None = None) -> np.ndarray:
    """(H, W, C) ``face_image`` (the relit face, exposed by ``gain``) raised, where the photo is
    clipped, to what the clipping proves: a clipped pixel's true brightness is at least the top of
    the range, so under the new light (Lambertian) it is at least ``S' / S`` of it, ``gain x S' / S``
    exposed. Otherwise unknown: the fill (``photo_albedo``) stays where it is brighter. With the
    photo's own light (``S' = S``) a clipped pixel comes back clipped, as in the photo; a highlight
    relit away from its light (``S' < S``) may come back darker, never brighter than its bound says.
    A pixel clipped in some channels is bounded in all: its others hold their own values, ``I_c S' / S``
    (each channel bounded alone, a near-white highlight clipped in red and blue came back magenta: its
    green, just under the top, took the skin's fill).
    diffuse (H, W, C), keep (H, W): the albedo there without the photo's shine (the fill less ``sheen``'s shine: at
    most ``SHEEN_MARGIN`` x the skin around it) and the share of the shine the new light keeps (``shine_kept``), or
    None (all of the top is diffuse): of the top's albedo ``1 / S``, what is over ``diffuse`` is shine, and only
    ``keep`` of it stays. A clipped highlight kept its whole top and came back a bright blotch beside the same
    highlight's unclipped rim, whose shine had left with the light (Yale B at +-70, relit frontally).
    photo (H, W, C) in [0, 1]; shading, new_shading (H, W) ``n . s`` and ``n . s'`` (0 in the new
    light's cast shadow); face (H, W) bool; clipped (H, W, C) bool: the photo's clipped channels, when known
    otherwise than from ``photo`` (the live preview's, measured on the photo before it was scaled), else None."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    clipped = img >= CLIPPED if clipped is None else np.asarray(clipped, bool)
    bounded = clipped.any(axis=-1) & face
    if not bounded.any():
        return face_image
    old = np.maximum(np.asarray(shading, np.float32), np.float32(CLIP_RATIO_FLOOR))
    top = np.where(clipped, np.float32(1.0), img) / old[..., None]  # the top's albedo: 1 where clipped, else its own
    if diffuse is not None and keep is not None:
        base = np.minimum(top, np.nan_to_num(np.asarray(diffuse, np.float32)))
        top = base + (top - base) * np.clip(np.asarray(keep, np.float32), 0.0, 1.0)[..., None]
    bound = np.float32(gain) * np.asarray(new_shading, np.float32)[..., None] * top
    return np.where(bounded[..., None], np.maximum(face_image, bound), face_image).astype(np.float32)


def photo_ambient(intensity: np.ndarray, coarse: np.ndarray, shading: np.ndarray, face: np.ndarray,
                  rim_px: float = 0.0, skin_only: np.ndarray | None = None) -> float:
    """The share of the light that reaches what the light itself does not: how bright the photo's
    attached shadow is against the face's albedo there, the lower quartile of ``I / coarse`` where the fitted
    shape faces away from the light (``n . s <= 0.02``), within ``AMBIENT_RANGE``; ``DEFAULT_AMBIENT``
    when the photo shows too little of it (a face lit from the front).

    Measured on the face's core when it shows enough (``AMBIENT_MIN_SHARE`` of the face): more than
    ``rim_px`` inside the face's border, of which the ``skin_only`` (H, W) bool pixels when given. Its rim
    is where a face turns from a side light first, and where its outline meets hair, ears or the
    background, whose brightness says nothing of the room's light: a shadow seen only there is taken
    as no brighter than the default. intensity, coarse (the fit's albedo on the photo grid), shading
    (H, W); face (H, W) bool."""
    usable = face & (np.asarray(shading) <= 0.02) & np.isfinite(coarse) & (np.nan_to_num(coarse) > 1e-3)
    if skin_only is not None:
        usable &= skin_only
    core = usable
    if rim_px > 0:  # the border of the box counts as face: a face cut by the photo's frame goes on beyond it
        inside = np.pad(face, 1, mode="edge").astype(np.uint8)
        core = usable & (cv2.distanceTransform(inside, cv2.DIST_L2, 5)[1:-1, 1:-1] > rim_px)
    enough = max(50.0, AMBIENT_MIN_SHARE * float(face.sum()))
    if core.sum() >= enough:
        return _ambient(intensity, coarse, core)
    if usable.sum() >= 50:  # the rim alone
        return min(_ambient(intensity, coarse, usable), DEFAULT_AMBIENT)
    return DEFAULT_AMBIENT


def _ambient(intensity: np.ndarray, coarse: np.ndarray, away: np.ndarray) -> float:
    # the lower quartile: where the fitted shape turns from the light too soon the photo is still lit
    ratio = np.asarray(intensity)[away] / np.asarray(coarse)[away]
    return float(np.clip(np.percentile(ratio, 25), *AMBIENT_RANGE))


def with_ambient(shading: np.ndarray, ambient: float) -> np.ndarray:
    """(H, W) float32 the light a surface gets from a point light (``shading``, ``n . s`` clipped at
    0) and the room around it: ``a + (1 - a) S``."""
    return (np.float32(ambient) + np.float32(1.0 - ambient) * np.asarray(shading, np.float32)).astype(np.float32)


def exposure_target(photo: np.ndarray, lit_skin: np.ndarray) -> float | None:
    """The median brightness (mean over channels) of the skin the photo shows lit (``lit_skin`` (H, W)
    bool): what a relit face is exposed to (``skin_exposure``); None when that skin is nearly empty."""
    if lit_skin.sum() < 50:
        return None
    return float(np.median(np.atleast_3d(photo).mean(axis=-1)[lit_skin]))


def skin_exposure(photo: np.ndarray, relit: np.ndarray, lit_skin: np.ndarray, relit_skin: np.ndarray) -> float:
    """The factor that gives a relit face the exposure of the photo's own lit skin: the median
    brightness of the skin the photo shows lit (``lit_skin``, ``exposure_target``) over the median of
    the relit face's lit skin (``relit_skin``). Relit by the photo's own light it is 1 (the photo
    comes back as it was); a face lit from 70 deg relit frontally would otherwise be three times as
    bright as the skin the photo shows, the lamp being the same. photo, relit (H, W, C); lit_skin,
    relit_skin (H, W) bool; 1 when either is nearly empty."""
    return exposure_gain(exposure_target(photo, lit_skin), relit, relit_skin)


def exposure_gain(want: float | None, relit: np.ndarray, relit_skin: np.ndarray) -> float:
    """``want`` (``exposure_target``) over the median brightness of ``relit`` (H, W, C) on
    ``relit_skin`` (H, W) bool; 1 when either is unknown or nearly empty."""
    if want is None or relit_skin.sum() < 50:
        return 1.0
    have = float(np.median(np.atleast_3d(relit).mean(axis=-1)[relit_skin]))
    return want / have if have > 1e-6 else 1.0


@dataclass(frozen=True)
class FaceLayer:
    """One relit face, to be put into its photo (``compose``). box: ``(y0, y1, x0, x1)`` the photo
    pixels it covers; inside: (h, w) bool the face; relit: (h, w, C) the relit face (used inside);
    gain: (h, w, C) the factor the photo is multiplied by outside the face (exactly 1 beyond the
    feather, so the photo there is untouched)."""

    box: tuple[int, int, int, int]
    inside: np.ndarray
    relit: np.ndarray
    gain: np.ndarray
    alpha: np.ndarray | None = None


def inner_alpha(face: np.ndarray, feather_px: float, inside: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32: how much of the relit face a face pixel shows, 1 beyond ``INNER_FEATHER`` x
    ``feather_px`` from the face's border and falling smoothly to 0 at it; the rest is the photo
    times the face's change of light there (``outside_gain``). A face relit far brighter than its
    shadowed border in the photo (the jaw at +-70) fades into it instead of ending on a cut. inside (H, W): each
    pixel's distance inside ``face`` when the caller has it (``cv2.distanceTransform``, precise), else measured."""
    if inside is None:
        inside = cv2.distanceTransform(face.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return smoothstep(inside, 0.0, max(INNER_FEATHER * feather_px, 1.0))


def face_rim(face: np.ndarray, width_px: float) -> np.ndarray:
    """(H, W) bool: the pixels of ``face`` (H, W) bool within ``width_px`` of its border (at least one)."""
    inside = cv2.distanceTransform(face.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return face & (inside <= max(width_px, 1.0))


def _padded_box(rows: np.ndarray, cols: np.ndarray, pad: int, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """``(y0, y1, x0, x1)``: the box of pixels ``rows``, ``cols`` (non-empty) grown by ``pad``, within ``shape``."""
    return (max(0, int(rows.min()) - pad), min(shape[0], int(rows.max()) + 1 + pad),
            max(0, int(cols.min()) - pad), min(shape[1], int(cols.max()) + 1 + pad))


def beyond_reach_box(beyond: np.ndarray | None, feather_px: float) -> tuple[np.ndarray, int, int] | None:
    """How far the face's change of light may exceed ``RATIO_OUTSIDE`` (up to ``RATIO_BEYOND``), in the box of
    ``beyond`` (H, W) bool, the face's own skin past the model's face, grown by the reach: ``(reach (h, w) float32
    in [0, 1], y0, x0)``, 1 on that skin and falling to 0 within ``BEYOND_EDGE`` of the feather ``feather_px`` of
    it; None when there is none. A 4-megapixel photo's layer is 2 megapixels; this box, a ring's, is less."""
    if beyond is None or not beyond.any():
        return None
    edge = max(BEYOND_EDGE * feather_px, 1.0)
    y0, y1, x0, x1 = _padded_box(np.nonzero(beyond.any(axis=1))[0], np.nonzero(beyond.any(axis=0))[0],
                                 int(np.ceil(edge)) + 1, beyond.shape)
    distance = cv2.distanceTransform((~beyond[y0:y1, x0:x1]).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return (1.0 - smoothstep(distance, 0.0, edge)).astype(np.float32), y0, x0


def beyond_reach(beyond: np.ndarray | None, feather_px: float) -> np.ndarray | None:
    """(H, W) float32 in [0, 1]: ``beyond_reach_box`` on the whole of ``beyond``'s grid (0 outside its box)."""
    box = beyond_reach_box(beyond, feather_px)
    if box is None:
        return None
    crop, y0, x0 = box
    reach = np.zeros(beyond.shape, np.float32)
    reach[y0:y0 + crop.shape[0], x0:x0 + crop.shape[1]] = crop
    return reach


def beyond_ratio(ratio: np.ndarray, photo: np.ndarray, level: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """The face's change of light ``ratio`` (..., C) held within ``RATIO_OUTSIDE``, or up to ``RATIO_BEYOND``
    as far as ``reach`` (..., 1) allows (geometrically: ``hi (RATIO_BEYOND / hi) ** reach``, so the photo just past
    that skin, where the reach fades, is lifted little more than ``RATIO_OUTSIDE`` allows); past ``RATIO_OUTSIDE``
    no brighter than the relit rim's ``level`` (..., C) beside it (the ratio is the rim's average: a jaw brighter
    in the photo than its rim would overshoot it). Where the ratio is within ``RATIO_OUTSIDE`` it is kept as it is.
    Any leading shape: images or pixel lists."""
    lo, hi = RATIO_OUTSIDE
    r = np.clip(ratio, lo, np.float32(hi) * np.float32(RATIO_BEYOND / hi) ** reach)
    return np.minimum(r, np.maximum(np.float32(hi), level / np.maximum(photo, np.float32(1e-6)))).astype(np.float32)


def quieted(gain: np.ndarray, photo: np.ndarray, smooth: np.ndarray) -> np.ndarray:
    """(..., C) float32: ``gain`` (..., C) on ``photo`` (..., C) with what it has past ``RATIO_OUTSIDE`` applied
    to the photo's ``smooth`` part only (its detail, ``photo - smooth``, lifted ``RATIO_OUTSIDE``'s top at most),
    as a gain on the photo; elsewhere ``gain`` itself. Any leading shape: images or pixel lists."""
    hi = np.float32(RATIO_OUTSIDE[1])
    detail = np.minimum(gain, hi)
    out = gain * smooth + detail * (photo - smooth)
    return np.where(gain > hi, np.maximum(out, 0.0) / np.maximum(photo, np.float32(1e-4)), gain).astype(np.float32)


def outside_gain(photo: np.ndarray, face_image: np.ndarray, face: np.ndarray, feather_px: float,
                 beyond: np.ndarray | None = None, person: np.ndarray | None = None) -> np.ndarray:
    """(H, W, C) the factor that carries a face's change of light into the photo around it: the
    face's relighting ratio (relit / photo, averaged over the face's rim, ``RIM_SHARE`` of the feather
    wide, within ``RATIO_OUTSIDE``) fading to exactly 1 over ``feather_px`` from the face, so the change runs on
    into the hair and neck without a seam and the photo beyond is untouched; inside the face, the
    ratio itself (what ``inner_alpha`` blends toward at the border). photo, face_image (H, W, C);
    face (H, W) bool; beyond (H, W) bool or None: the face's own skin past ``face`` (its outline beyond the
    model), which takes the ratio itself, up to ``RATIO_BEYOND`` (``beyond_reach``), the fade running from its
    edge; person (H, W) float in [0, 1]
    or None: how sure a segmentation is that each pixel is the person, not the background: the change of light
    around the face reaches only as far (hair and neck follow the face, the wall behind it keeps its light)."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    relit = np.nan_to_num(np.atleast_3d(np.asarray(face_image, np.float32)))
    sigma = max(feather_px / 2.0, 1.0)
    rim = face_rim(face, RIM_SHARE * feather_px).astype(np.float32)
    w = rim[..., None]
    support = blur(rim, sigma)
    num = blur(relit * w, sigma)
    ratio = num / np.maximum(blur(img * w, sigma), np.maximum(1e-3 * support, 1e-12)[..., None])
    box = beyond_reach_box(beyond, feather_px)
    if box is not None:  # the face's own skin and the reach beyond it, pixel by pixel (a thin ring)
        reach, y0, x0 = box
        ry, rx = np.nonzero(reach > 0)
        at = (ry + y0, rx + x0)
        beyond_at = beyond_ratio(ratio[at], img[at], num[at] / np.maximum(support[at], 1e-12)[:, None],
                                 reach[ry, rx][:, None])
    np.clip(ratio, *RATIO_OUTSIDE, out=ratio)
    if box is not None:
        ratio[at] = beyond_at
    whole = face if box is None else face | beyond  # where the ratio itself applies
    # the fade runs from the face's own outline: run from the model's face, it had ended where that outline lies a
    # feather beyond it (a portrait's cheek), and the skin relit into shadow met the photo's lit edge of the cheek
    distance = cv2.distanceTransform((~whole).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    fade = (1.0 - smoothstep(distance, 0.0, feather_px))[..., None] * (support[..., None] > 1e-3)
    if person is not None:  # a wall lit up or darkened around a relit face is a halo
        fade *= np.asarray(person, np.float32)[..., None]
    gain = np.where(whole[..., None], ratio, np.where(fade > 0, 1.0 + fade * (ratio - 1.0), np.float32(1.0))
                    ).astype(np.float32)
    if box is None:
        return gain
    hot = np.any(gain[at] > RATIO_OUTSIDE[1], axis=-1)  # past RATIO_OUTSIDE only where the reach lets it
    over = (at[0][hot], at[1][hot])
    if over[0].size:  # past RATIO_OUTSIDE: the photo's smooth part, in those pixels' box
        fine = sigma * DETAIL_SHARE
        y0, y1, x0, x1 = _padded_box(*over, int(np.ceil(3.0 * fine)) + 1, img.shape)
        smooth = blur(img[y0:y1, x0:x1], fine)
        gain[over] = quieted(gain[over], img[over], smooth[over[0] - y0, over[1] - x0])
    return gain


def compose(photo: np.ndarray, layers: list[FaceLayer]) -> np.ndarray:
    """(H, W, C) float32 ``photo`` with every face of ``layers`` put back: first each face's
    ``gain`` on the photo around it (overlapping feathers multiply), then each face's own relit
    pixels, which no other face's feather touches. Pixels no layer changes are the photo's, bit for bit."""
    source = np.atleast_3d(photo)
    out = np.array(source, np.float32, copy=True)
    for layer in layers:
        y0, y1, x0, x1 = layer.box
        region = out[y0:y1, x0:x1]
        changed = np.any(layer.gain != 1.0, axis=-1) & ~layer.inside
        region[changed] = np.clip(region[changed] * layer.gain[changed], 0.0, 1.0)
    for layer in layers:
        y0, y1, x0, x1 = layer.box
        relit = layer.relit
        if layer.alpha is not None:  # the face's border fades into the photo, its light changed as around it
            a = layer.alpha[..., None]
            relit = a * relit + (1.0 - a) * source[y0:y1, x0:x1] * layer.gain
        out[y0:y1, x0:x1][layer.inside] = np.clip(relit[layer.inside], 0.0, 1.0)
    return out


def composite(photo: np.ndarray, face_image: np.ndarray, face: np.ndarray, feather_px: float) -> np.ndarray:
    """(H, W, C) the photo with one relit face put back (``compose`` of its one layer)."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    relit = np.atleast_3d(np.asarray(face_image, np.float32))
    layer = FaceLayer((0, img.shape[0], 0, img.shape[1]), np.asarray(face, bool), relit,
                      outside_gain(img, relit, face, feather_px))
    return compose(img, [layer])
