"""How evenly a face is lit, side to side: the linear luminance of the two halves of an ellipse placed by its eyes.

A face's albedo is nearly the same on both sides of its midline, so the halves' brightness tells a light from the
side from one from the front (an elevation it cannot tell: brows, lips and a beard run downward). The ellipse is the
face from the forehead to the chin: ``ELLIPSE_AXES`` eye distances across and along, centred ``ELLIPSE_DROP`` below
the eyes' midpoint, turned with the eyes' line. Arrays are (H, W) linear luminance or (H, W, C) linear values on the
photo's grid; eyes are (2, 2) photo pixels ``[[x, y], [x, y]]`` (either order).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .encoding import linear_luminance

# the ellipse: semi-axes across and along the face, and its centre below the eyes' midpoint, in eye distances
ELLIPSE_AXES = (1.0, 1.35)
ELLIPSE_DROP = 0.45
EVEN = 0.15  # a face is evenly lit when its two halves' mean luminance are within this share of each other


@dataclass(frozen=True)
class Ellipse:
    """The face's ellipse in a crop: ``mask`` (h, w) bool; ``side`` (h, w) float32, each pixel's signed distance
    from the face's vertical axis (positive toward the image's left); ``box`` ``(y0, y1, x0, x1)`` of the crop
    in the photo; ``iod`` the eyes' distance in pixels."""

    mask: np.ndarray
    side: np.ndarray
    box: tuple[int, int, int, int]
    iod: float


def eye_axes(eyes: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """``(mid, iod, u, down)`` of a face's eyes (2, 2) photo pixels, either order: their midpoint, their distance, the
    unit vector along them toward the image's right and the one across them toward the chin (image rows grow
    downward); ``ValueError`` when they are less than a pixel apart."""
    e = np.asarray(eyes, np.float64).reshape(2, 2)
    left, right = (e[0], e[1]) if e[0, 0] <= e[1, 0] else (e[1], e[0])
    across = right - left
    iod = float(np.linalg.norm(across))
    if iod < 1.0:
        raise ValueError(f"eyes {e.tolist()} are less than a pixel apart")
    u = across / iod
    return (left + right) / 2.0, iod, u, np.array([-u[1], u[0]])


def face_ellipse(eyes: np.ndarray, shape: tuple[int, int], margin: float = 0.45) -> Ellipse:
    """The face's ellipse from its eyes (2, 2), in a crop of an (H, W) photo around it grown by ``margin`` eye
    distances (the blur's reach). The ellipse follows the eyes' line (a rolled face's is rolled)."""
    mid, iod, u, down = eye_axes(eyes)
    centre = mid + ELLIPSE_DROP * iod * down
    reach = (max(ELLIPSE_AXES) + margin) * iod
    x0, x1 = max(0, int(centre[0] - reach)), min(shape[1], int(np.ceil(centre[0] + reach)) + 1)
    y0, y1 = max(0, int(centre[1] - reach)), min(shape[0], int(np.ceil(centre[1] + reach)) + 1)
    yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
    dx, dy = xx - centre[0], yy - centre[1]
    a = (dx * u[0] + dy * u[1]) / (ELLIPSE_AXES[0] * iod)
    b = (dx * down[0] + dy * down[1]) / (ELLIPSE_AXES[1] * iod)
    side = -((xx - mid[0]) * u[0] + (yy - mid[1]) * u[1])  # > 0 on the image's left of the axis
    return Ellipse(a * a + b * b <= 1.0, side.astype(np.float32), (y0, y1, x0, x1), iod)


def luminance(image: np.ndarray) -> np.ndarray:
    """(H, W) float32 linear luminance of (H, W) grey or (H, W, 1 | 3) linear values."""
    img = np.asarray(image, np.float32)
    if img.ndim == 3 and img.shape[-1] == 3:
        return linear_luminance(img)
    return img.reshape(img.shape[:2])


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




def evenly_lit(photo: np.ndarray, eyes: np.ndarray | None) -> bool:
    """Whether the face whose eyes are ``eyes`` (2, 2) in ``photo`` (H, W[, C]) linear is lit evenly from side to side
    (``halves_ratio`` within ``EVEN``); False without eyes or an ellipse in the photo."""
    if eyes is None:
        return False
    try:
        return halves_ratio(photo, face_ellipse(eyes, np.shape(photo)[:2])) <= 1.0 + EVEN
    except ValueError:
        return False
