"""Lambertian remapping (the paper's [8]): scale brightness so the brightest face point is 1."""
from __future__ import annotations

import numpy as np
from scipy import ndimage


def lambertian_remap(image: np.ndarray, mask: np.ndarray, window: int = 3) -> tuple[np.ndarray, float]:
    """Divide ``image`` by the brightness of its brightest face point, then clip to [0, 1].

    Under unit albedo the brightest point of a face whose normals include the light
    direction has ``n . s = 1``. The brightest point is taken after a ``window`` x ``window``
    median filter, so a few isolated hot pixels (specks, sensor defects) do not set the scale.
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
    return np.clip(img / scale, 0.0, 1.0).astype(np.float32), scale


class RemapNode:
    """Node wrapper: ``frame['image']`` on the model grid -> ``frame['remapped']``."""

    name = "remap"

    def __call__(self, frame: dict) -> dict:
        frame["remapped"], frame["remap_scale"] = lambertian_remap(frame["grid_image"], frame["model"].mask)
        return frame
