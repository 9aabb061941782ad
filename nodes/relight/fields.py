"""Small operations on fields of pixels that every step of the relighting shares.

Arrays are (H, W) or (H, W, C) float32 on a photo's pixel grid unless a docstring says otherwise.
"""
from __future__ import annotations

import cv2
import numpy as np


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
    r = max(1, round(radius))
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


def channel_sum(values: np.ndarray) -> np.ndarray:
    """(H, W) float32 the sum over the channels of (H, W, C) values (numpy's sum over a last axis of 3 is slow)."""
    out = np.array(values[..., 0], np.float32, copy=True)
    for c in range(1, values.shape[-1]):
        out += values[..., c]
    return out


def brightness(values: np.ndarray) -> np.ndarray:
    """(H, W) float32 the mean over the channels of (H, W, C) values."""
    return channel_sum(values) / np.float32(values.shape[-1])


def distance_inside(mask: np.ndarray) -> np.ndarray:
    """(H, W) float32 each pixel's distance inside ``mask`` (H, W) bool to its border, in pixels (0 off it)."""
    return cv2.distanceTransform(np.asarray(mask, np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)


def distance_to(mask: np.ndarray) -> np.ndarray:
    """(H, W) float32 each pixel's distance to the nearest pixel of ``mask`` (H, W) bool (0 on it)."""
    return cv2.distanceTransform((~np.asarray(mask, bool)).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
