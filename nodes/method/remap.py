"""Lambertian remapping (the paper's [8]): scale brightness so the brightest face point is 1."""
from __future__ import annotations

import numpy as np
from scipy import ndimage

# brightness at or above this is taken as clipped: only the top of the range (255 of 8 bits is 1.0, 254 is
# 0.996); such pixels carry no constraint on the shape. ``FitConfig.saturation`` and the remap default to it
SATURATION = 0.998


def lambertian_remap(image: np.ndarray, mask: np.ndarray, window: int = 3,
                     peak_shading: float = 1.0) -> tuple[np.ndarray, float]:
    """Scale ``image`` so its brightest face point has shading ``peak_shading``; clip to [0, 1].

    The paper's remap takes ``peak_shading = 1``: some face normal points at the light. At
    steep light none may (``expected_peak_shading`` gives the model's estimate instead).
    The brightest point is taken after a ``window`` x ``window`` median filter, so a few
    isolated hot pixels (specks, sensor defects) do not set the scale.
    image (H, W) float in [0, 1]; mask (H, W) bool. Returns ``(remapped (H, W) float32,
    scale)`` with ``remapped = clip(image / scale, 0, 1)``.
    """
    img = np.asarray(image, np.float64)
    m = np.asarray(mask, bool)
    if not m.any():
        raise ValueError("empty face mask")
    smooth = ndimage.median_filter(np.where(m, img, 0.0), size=window, mode="nearest")
    scale = float(np.max(smooth[m]))
    if not np.isfinite(scale) or scale <= 0:
        raise ValueError("the face region is black: nothing to remap")
    scale /= float(np.clip(peak_shading, 0.05, 1.0))
    return np.clip(img / scale, 0.0, 1.0).astype(np.float32), scale


def expected_peak_shading(mean_normals: np.ndarray, light: np.ndarray) -> float:
    """The largest ``n . s`` of the model's mean face under ``light``: where the brightest
    point of a typical face sits on the shading scale. mean_normals (N, 3); light (3,)."""
    return float(np.max(np.asarray(mean_normals, np.float64) @ np.asarray(light, np.float64)))


def ratio_scale(intensity: np.ndarray, mean_shading: np.ndarray, saturation: float = SATURATION,
                min_shading: float = 0.2, min_intensity: float = 0.02) -> float:
    """Brightness scale of a face whose brightest points are clipped (over-exposed).

    The peak is lost there, so the scale is the median of ``I / (n_mean . s)`` over pixels
    that are neither clipped nor dark and that the mean face lights well. intensity (N,)
    brightness, mean_shading (N,) the mean face's ``n . s``. Returns the scale (> 0).
    """
    I = np.asarray(intensity, np.float64)
    sh = np.asarray(mean_shading, np.float64)
    ok = (I < saturation) & (I > min_intensity) & (sh > min_shading)
    if ok.sum() < 20:
        raise ValueError("too few unclipped lit pixels to set the brightness scale")
    return float(np.median(I[ok] / sh[ok]))


def clipped_pixels(intensity: np.ndarray, saturation: float = SATURATION, min_fraction: float = 0.02) -> np.ndarray:
    """(N,) bool: pixels clipped by over-exposure. A few pixels at the top of the range are
    normal in a well-exposed photo (the brightest point of the face); only when more than
    ``min_fraction`` of them reach ``saturation`` is the photo over-exposed and they are clipped."""
    top = np.asarray(intensity) >= saturation
    return top if top.mean() > min_fraction else np.zeros_like(top)
