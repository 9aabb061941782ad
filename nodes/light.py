"""Light-direction estimate for inputs whose light nobody wrote down."""
from __future__ import annotations

import numpy as np


def estimate_light(intensity: np.ndarray, normals: np.ndarray, min_intensity: float = 0.05) -> np.ndarray:
    """Least-squares light from ``I = rho n . s`` over pixels bright enough to be lit.

    intensity: (N,) brightness; normals: (N, 3) unit, camera frame (e.g. the model's mean
    face). Solves for ``l = rho s`` and returns ``s = l / |l|`` (3,), forced toward the
    camera (z >= 0.05). A first-order estimate: shadowed pixels are left out, so it is
    biased toward the view axis when much of the face is dark.
    """
    I = np.asarray(intensity, np.float64)
    n = np.asarray(normals, np.float64)
    use = I > min_intensity
    if use.sum() < 10:
        raise ValueError("too few lit pixels to estimate the light")
    l, *_ = np.linalg.lstsq(n[use], I[use], rcond=None)
    s = l / max(np.linalg.norm(l), 1e-12)
    s[2] = max(s[2], 0.05)
    return s / np.linalg.norm(s)
