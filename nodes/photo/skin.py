"""What a face's skin looks like in a photo: its colour (and the colour it takes in its shade), and how rough it
is (hair and a beard are strands; skin is smooth, in its shade too).

Arrays are on the photo's pixel grid (H, W[, C]), linear RGB (C = 3) or grey (C = 1).
"""
from __future__ import annotations

import cv2
import numpy as np

MAX_CHROMA_DISTANCE = 0.08  # chromaticity (r, g, b) / (r + g + b) this far from the face's median: not skin
# the skin's colour followed into its shade (``skin_locus``): fitted at this share of the lit skin's brightness,
# its slope (chromaticity per e-fold of brightness) held to this, and followed down to this share
SHADE_FIT = (0.3, 0.6)
SHADE_MAX_SLOPE = 0.12
SHADE_FLOOR = 0.1
# strands are told from skin with this many pixels between the eyes (``strands``)
STRAND_IOD = 120.0


def skin(photo: np.ndarray, where: np.ndarray) -> np.ndarray:
    """(H, W) bool: ``where`` the photo has the face's skin colour (a chromaticity within
    ``MAX_CHROMA_DISTANCE`` of the median over the inner half of ``where``: its border may be hair or
    background); all of ``where`` for a grey photo. The fill's level and colour are matched on skin
    only: eyes, lips, brows and hair would tint it."""
    return skin_distance(photo, where) < MAX_CHROMA_DISTANCE


def skin_distance(photo: np.ndarray, where: np.ndarray, shade: bool = False,
                  keep_out: np.ndarray | None = None, reference: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32: how far each pixel's chromaticity is from the face's skin colour (the median over the inner
    half of ``where`` (H, W) bool, or over ``reference`` (H, W) bool when given: the skin the photo shows lit); inf
    off ``where``, 0 on it for a grey photo (or too few pixels to tell).

    shade: from the skin's colour at the pixel's brightness instead where that is nearer: below the lit skin's
    level along ``skin_locus`` (darker skin is redder in an ordinary photo; a shadow under the nose was taken for
    something else and kept as it was, a brown patch on a face relit from the front), above it toward white (the
    light's own reflection whitens skin: a shiny forehead is skin); not on ``keep_out`` (H, W) bool, e.g. the eyes
    and lips."""
    img = np.atleast_3d(photo)
    where = np.asarray(where, bool)
    if img.shape[-1] != 3 or where.sum() <= 50:
        return np.where(where, np.float32(0.0), np.float32(np.inf))
    brightness = _channel_sum(img)
    chroma = img / np.maximum(brightness, 1e-6)[..., None]
    depth = cv2.distanceTransform(where.astype(np.uint8), cv2.DIST_L2, 3)
    inner = where & (depth >= 0.5 * depth.max())
    inner = inner if inner.sum() > 50 else where
    if reference is not None and (np.asarray(reference, bool) & where).sum() > 50:
        inner = np.asarray(reference, bool) & where
    median = np.median(chroma[inner], axis=0).astype(np.float32)
    distance = _chroma_distance(chroma, median)
    if shade:
        use = where if keep_out is None else where & ~keep_out
        slope, log_level = skin_locus(chroma, brightness, use & inner & (distance < MAX_CHROMA_DISTANCE), use, median)
        if slope is not None:
            # below the lit level, the locus: median + slope ln(b / level), down to SHADE_FLOOR
            depth_below = np.clip(np.log(np.maximum(brightness, 1e-6)) - log_level, np.log(SHADE_FLOOR), 0.0)
            along = _chroma_distance(chroma, median, slope, depth_below.astype(np.float32))
            above = _toward_white(chroma, median)
            along = np.where(brightness > np.exp(log_level), np.minimum(along, above), along)
            distance = np.where(use, np.minimum(distance, along), distance)
    return np.where(where, distance, np.float32(np.inf)).astype(np.float32)


def _toward_white(chroma: np.ndarray, median: np.ndarray) -> np.ndarray:
    """(H, W) float32 the distance of ``chroma`` (H, W, 3) from the segment between the skin's ``median`` (3,) and
    white (1/3, 1/3, 1/3): skin with some of the light's white reflection on it."""
    d = np.float32(1.0 / 3.0) - median
    v = chroma - median
    t = np.clip((v @ d) / max(float(d @ d), 1e-9), 0.0, 1.0)
    return np.sqrt(np.sum(np.square(v - t[..., None] * d), axis=-1)).astype(np.float32)


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


def strands(photo: np.ndarray, iod_px: float, floor: float = 1e-3) -> np.ndarray:
    """(H, W) float32: how much of the photo's local contrast is strands (hair, a beard, stubble, lashes) rather than
    skin or an edge: ``ln(I + floor)`` (``I`` the sum of its channels) less its median over 5 x 5 pixels (a median
    keeps a shadow's edge and a face's contour, and takes out what is thinner than two pixels), its RMS over a
    Gaussian of 1.5 pixels; all of it seen with ``STRAND_IOD`` pixels between the eyes (a larger face is reduced, so a
    strand is a pixel or two wide whatever the photo's size), brought back to the photo's. photo (H, W, C) linear;
    iod_px: the face's eyes' distance in its pixels; floor: what is added to ``I`` first (a deep shadow's noise, in
    log, is as rough as hair: a few per cent of the skin's lit level keeps it smooth)."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    h, w = img.shape[:2]
    log = np.log(_channel_sum(img) + np.float32(max(floor, 1e-3)))
    k = min(1.0, STRAND_IOD / max(iod_px, 1.0))
    small = log if k == 1.0 else cv2.resize(log, (max(5, round(w * k)), max(5, round(h * k))),
                                            interpolation=cv2.INTER_AREA)
    residual = small - cv2.medianBlur(np.ascontiguousarray(small, np.float32), 5)
    rms = np.sqrt(cv2.GaussianBlur(residual * residual, (0, 0), 1.5))
    return rms if k == 1.0 else cv2.resize(rms, (w, h), interpolation=cv2.INTER_LINEAR)


def _channel_sum(values: np.ndarray) -> np.ndarray:
    """(H, W) float32 the sum over the channels of (H, W, C) values (numpy's sum over a last axis of 3 is slow)."""
    out = np.array(values[..., 0], np.float32, copy=True)
    for c in range(1, values.shape[-1]):
        out += values[..., c]
    return out
