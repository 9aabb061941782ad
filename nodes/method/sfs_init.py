"""Initial needle-map for the fit (Worthington & Hancock's shape-from-shading start).

``gradient_init`` is the paper's: every normal on its reflectance cone, pointing opposite
the local image gradient. ``mean_init`` starts from the model's mean face instead, put on
the cones; on faces it starts far closer to the answer (README, "Where we depart from the paper").
"""
from __future__ import annotations

import cv2
import numpy as np

from ..geometry.normals import normalize
from ..geometry.reflectance import irradiance_constraint


def gradient_init(image: np.ndarray, mask: np.ndarray, light: np.ndarray, dark_threshold: float = 0.0) -> np.ndarray:
    """Normals on the cones of axis ``light`` and angle ``arccos I``, opposite the gradient.

    image (H, W) remapped to [0, 1]; mask (H, W) bool; light (3,) unit camera frame.
    The image gradient (Sobel, 3x3, in camera axes: x right, y up) gives the azimuth: the
    direction ``-grad I`` is made perpendicular to ``s`` and the normal is rotated from ``s``
    toward it by ``arccos I``. Returns (H, W, 3) float32, NaN outside ``mask``.
    """
    img = np.asarray(image, np.float32)
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3)
    gy = -cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3)  # rows grow downward, y grows upward
    m = np.asarray(mask, bool)
    away = np.stack([-gx[m], -gy[m], np.zeros(int(m.sum()), np.float32)], axis=1).astype(np.float64)
    s = np.asarray(light, np.float64)
    # Seed direction: away from the gradient, tilted off s so the cone rotation has an azimuth.
    seed = normalize(s[None, :] + away)
    dark = img[m] <= dark_threshold if dark_threshold > 0 else None
    n = irradiance_constraint(seed, s, img[m], dark)
    out = np.full(m.shape + (3,), np.nan, np.float32)
    out[m] = n
    return out


def mean_init(mean_normals: np.ndarray, intensity: np.ndarray, light: np.ndarray,
              dark: np.ndarray | None = None) -> np.ndarray:
    """The model's mean normals (N, 3) put on their cones (dark pixels: ``n . s <= 0``)."""
    return irradiance_constraint(np.asarray(mean_normals, np.float64), light, intensity, dark)
