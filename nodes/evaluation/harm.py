"""A no-reference measure of what a relighting did to a face besides changing its light.

A change of light is smooth across a face at the scale of its features: on an evenly lit face relit
frontally, the relit photo over the input is a smooth field. What is not smooth in that ratio is harm:
a beard or a brow taken for shadow and repainted, a pasted patch, a blotch, a hard outline. So, over an
ellipse placed by the eyes (``face_ellipse``):

- ``r = ln(Y_relit + EPS) - ln(Y_input + EPS)``, ``Y`` the linear luminance;
- its high-pass ``r - blur(r)``, the blur Gaussian over ``HIGH_PASS`` eye distances, normalised over the
  ellipse (``r m`` blurred over ``m`` blurred), so the ellipse's edge adds nothing;
- ``H``: the RMS of that high-pass over the ellipse, in % (a log ratio of 0.05 is a 5 % change);
  ``P``: the share of the ellipse where its magnitude exceeds ``BLOTCH`` (20 %).

A strong change of light raises H legitimately (new shadow edges, fine shading), so H judges faces lit
evenly (``halves_ratio`` within ``EVEN``) relit frontally. ``light_move`` says whether a side light
still moved the light: the blurred log ratio, image-left half minus image-right half.

Arrays are (H, W) linear luminance or (H, W, 3) linear RGB on the photo's grid; eyes are (2, 2) photo
pixels ``[[x, y], [x, y]]`` (either order).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..photo.encoding import linear_luminance

# the ellipse: semi-axes across and along the face, and its centre below the eyes' midpoint, in eye distances
ELLIPSE_AXES = (1.0, 1.35)
ELLIPSE_DROP = 0.45
HIGH_PASS = 0.15  # the high-pass's Gaussian, eye distances
BLOTCH = 0.20  # a high-passed log ratio beyond this is a blotch (P)
EVEN = 0.15  # a face is evenly lit when its two halves' mean luminance are within this share of each other
# added to linear luminance before the log: a pixel at a few levels of 255 is noise, and its ratio means nothing
EPS = 2e-3


@dataclass(frozen=True)
class Ellipse:
    """The face's ellipse in a crop: ``mask`` (h, w) bool; ``side`` (h, w) float32, each pixel's signed distance
    from the face's vertical axis (positive toward the image's left); ``box`` ``(y0, y1, x0, x1)`` of the crop
    in the photo; ``iod`` the eyes' distance in pixels."""

    mask: np.ndarray
    side: np.ndarray
    box: tuple[int, int, int, int]
    iod: float


@dataclass(frozen=True)
class Harm:
    """One face's scores: ``h`` and ``p`` in %, ``halves`` the ratio of its halves' mean luminance in the input
    (>= 1), ``move`` the light's move (``light_move``; None when not asked)."""

    h: float
    p: float
    halves: float
    move: float | None = None

    @property
    def even(self) -> bool:
        return self.halves <= 1.0 + EVEN


def face_ellipse(eyes: np.ndarray, shape: tuple[int, int], margin: float = 3.0 * HIGH_PASS) -> Ellipse:
    """The face's ellipse from its eyes (2, 2), in a crop of an (H, W) photo around it grown by ``margin`` eye
    distances (the blur's reach). The ellipse follows the eyes' line (a rolled face's is rolled)."""
    e = np.asarray(eyes, np.float64).reshape(2, 2)
    left, right = (e[0], e[1]) if e[0, 0] <= e[1, 0] else (e[1], e[0])
    across = right - left
    iod = float(np.linalg.norm(across))
    if iod < 1.0:
        raise ValueError(f"eyes {e.tolist()} are less than a pixel apart")
    u = across / iod  # toward the image's right, along the eyes
    down = np.array([-u[1], u[0]])  # image rows grow downward
    centre = (left + right) / 2.0 + ELLIPSE_DROP * iod * down
    reach = (max(ELLIPSE_AXES) + margin) * iod
    x0, x1 = max(0, int(centre[0] - reach)), min(shape[1], int(np.ceil(centre[0] + reach)) + 1)
    y0, y1 = max(0, int(centre[1] - reach)), min(shape[0], int(np.ceil(centre[1] + reach)) + 1)
    yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
    dx, dy = xx - centre[0], yy - centre[1]
    a = (dx * u[0] + dy * u[1]) / (ELLIPSE_AXES[0] * iod)
    b = (dx * down[0] + dy * down[1]) / (ELLIPSE_AXES[1] * iod)
    mid = (left + right) / 2.0
    side = -((xx - mid[0]) * u[0] + (yy - mid[1]) * u[1])  # > 0 on the image's left of the axis
    return Ellipse(a * a + b * b <= 1.0, side.astype(np.float32), (y0, y1, x0, x1), iod)


def luminance(image: np.ndarray) -> np.ndarray:
    """(H, W) float32 linear luminance of (H, W) grey or (H, W, 1 | 3) linear values."""
    img = np.asarray(image, np.float32)
    if img.ndim == 3 and img.shape[-1] == 3:
        return linear_luminance(img)
    return img.reshape(img.shape[:2])


def _masked_blur(values: np.ndarray, mask: np.ndarray, sigma: float) -> np.ndarray:
    """(h, w) the Gaussian average of ``values`` over ``mask`` (normalised there)."""
    m = mask.astype(np.float32)
    num = cv2.GaussianBlur(values * m, (0, 0), sigma, borderType=cv2.BORDER_CONSTANT)
    den = cv2.GaussianBlur(m, (0, 0), sigma, borderType=cv2.BORDER_CONSTANT)
    return num / np.maximum(den, np.float32(1e-6))


def log_ratio(before: np.ndarray, after: np.ndarray, ellipse: Ellipse) -> np.ndarray:
    """(h, w) float32 ``ln(Y_after + EPS) - ln(Y_before + EPS)`` on the ellipse's crop."""
    y0, y1, x0, x1 = ellipse.box
    b = luminance(before)[y0:y1, x0:x1]
    a = luminance(after)[y0:y1, x0:x1]
    return (np.log(np.maximum(a, 0.0) + np.float32(EPS)) - np.log(np.maximum(b, 0.0) + np.float32(EPS))
            ).astype(np.float32)


def halves_ratio(before: np.ndarray, ellipse: Ellipse) -> float:
    """How unevenly the input is lit: the larger over the smaller mean linear luminance of the ellipse's two
    halves, split at the eyes' midpoint across their line (1 for an evenly lit face)."""
    y0, y1, x0, x1 = ellipse.box
    y = luminance(before)[y0:y1, x0:x1]
    left = y[ellipse.mask & (ellipse.side > 0)]
    right = y[ellipse.mask & (ellipse.side <= 0)]
    if not left.size or not right.size:
        return float("inf")
    lo, hi = sorted((float(left.mean()), float(right.mean())))
    return hi / max(lo, 1e-9)


def harm(before: np.ndarray, after: np.ndarray, eyes: np.ndarray) -> Harm:
    """``Harm`` of ``after`` (the relit photo) against ``before`` (the input), both linear, on the face whose
    eyes are ``eyes`` (2, 2) photo pixels."""
    ellipse = face_ellipse(eyes, np.shape(before)[:2])
    m = ellipse.mask
    if not m.any():
        raise ValueError(f"eyes {np.asarray(eyes).tolist()}: the face's ellipse is outside the photo")
    r = log_ratio(before, after, ellipse)
    high = (r - _masked_blur(r, m, HIGH_PASS * ellipse.iod))[m]
    h = 100.0 * float(np.sqrt(np.mean(high.astype(np.float64) ** 2)))
    p = 100.0 * float(np.mean(np.abs(high) > BLOTCH))
    return Harm(h, p, halves_ratio(before, ellipse))


def light_move(before: np.ndarray, after: np.ndarray, eyes: np.ndarray) -> float:
    """How far a new light moved the light across the face: the blurred log ratio (``HIGH_PASS`` eye distances,
    over the ellipse) averaged over the image-left half of the ellipse, less its average over the right half.
    Positive when the image's left brightened against its right (a light from the image's left)."""
    ellipse = face_ellipse(eyes, np.shape(before)[:2])
    m = ellipse.mask
    smooth = _masked_blur(log_ratio(before, after, ellipse), m, HIGH_PASS * ellipse.iod)
    left, right = smooth[m & (ellipse.side > 0)], smooth[m & (ellipse.side <= 0)]
    if not left.size or not right.size:
        return float("nan")
    return float(left.mean() - right.mean())
