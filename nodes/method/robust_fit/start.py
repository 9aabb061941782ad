"""Where the fit starts (``initial_normals``) and how its two needle-maps are blended for output
(``combine``, the paper's section 4.1)."""
from __future__ import annotations

import numpy as np

from ...model.shape_model import ShapeModel
from ..sfs_init import gradient_init, mean_init
from .config import FitConfig


def initial_normals(model: ShapeModel, image: np.ndarray, light: np.ndarray, config: FitConfig) -> np.ndarray:
    """Starting needle-map (N, 3) for ``config.init``: the mean face or the image gradient.

    image: (H, W) remapped brightness on the model grid.
    """
    I = np.clip(np.asarray(image, np.float64)[model.mask], 0.0, 1.0)
    if config.init == "gradient":
        thr = config.dark_threshold if config.attached_shadow else 0.0
        return gradient_init(image, model.mask, light, thr).astype(np.float64)[model.mask]
    dark = (I <= config.dark_threshold) if config.attached_shadow else None
    return mean_init(model.mean_normals, I, light, dark)


def combine(cone_normals: np.ndarray, model_normals: np.ndarray, weights: np.ndarray,
            min_z: float = 1e-3) -> np.ndarray:
    """The paper's section 4.1 blend ``normalize(w n'' + (1 - w) n')``, kept visible.

    cone_normals, model_normals (N, 3); weights (N,). The closest on-cone direction to a
    normal near the silhouette can point away from the camera; a visible surface has
    ``z > 0``, so such a blend is moved onto ``z = min_z`` keeping its azimuth. Returns (N, 3).
    """
    w = np.asarray(weights, np.float64)[:, None]
    n = w * cone_normals + (1.0 - w) * model_normals
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    hidden = n[:, 2] < min_z
    if np.any(hidden):
        xy = n[hidden, :2]
        xy = xy / np.maximum(np.linalg.norm(xy, axis=1, keepdims=True), 1e-12) * np.sqrt(1.0 - min_z**2)
        n[hidden] = np.column_stack([xy, np.full(len(xy), min_z)])
    return n
