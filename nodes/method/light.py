"""Light-direction estimate for inputs whose light nobody wrote down."""
from __future__ import annotations

import numpy as np


def estimate_light(intensity: np.ndarray, normals: np.ndarray, min_intensity: float = 0.05,
                   iterations: int = 10) -> np.ndarray:
    """Least-squares light from the clamped Lambertian model ``I = rho max(n . s, 0)``.

    intensity: (N,) brightness; normals: (N, 3) camera frame, the normals' best guess (e.g. a
    model's ``expected_normals``; need not be unit). Starts from ``l = rho s`` fitted over pixels
    brighter than ``min_intensity`` of the peak, then refits over the pixels the current ``l``
    lights (``n . l > 0``), dark ones included, so the shadowed side pulls the light away from the
    view axis as it should; ``iterations`` refits. Returns ``s = l / |l|`` (3,), forced toward the
    camera (z >= 0.05). On Yale B photos with the ICT model's expected normals: 6.7 / 6.2 / 7.1 /
    5.2 deg at (25, 0) / (50, 0) / (70, 0) / (35, 15) (docs/accuracy.md).
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


def expected_normals(mean_normals: np.ndarray, normal_variance: np.ndarray) -> np.ndarray:
    """(N, 3) the expected normal of each pixel over a model's faces, ``exp(-var / 2) x mean``
    (to first order in the variance, for AEP coordinates drawn from a zero-mean Gaussian around
    the mean normal): mean_normals (N, 3) unit; normal_variance (N,) radians squared, both AEP
    axes (``ShapeModel.normal_variance``).

    A photo's brightness is ``rho n . s`` with ``n`` the photo's normal, which the mean face only
    guesses: its expected value is ``rho E[n] . s``, not ``rho mean . s``. Where faces differ
    much (around the nose, the eyes, the jaw) ``E[n]`` is shorter, and a light fitted on the mean
    normals leans toward wherever those pixels face (on ICT renders: 2-3.5 deg too high)."""
    var = np.asarray(normal_variance, np.float64)
    return np.asarray(mean_normals, np.float64) * np.exp(-0.5 * var)[:, None]


def light_on_face(grid_image: np.ndarray, use: np.ndarray, model) -> np.ndarray:
    """(3,) the light of a face on the model grid, model camera frame, estimated from the model's expected
    normals (``expected_normals``) at the pixels ``use`` (Hm, Wm) bool, e.g. the skin the photo shows.
    grid_image: (Hm, Wm) brightness; model: the ``ShapeModel``."""
    u = use[model.mask]
    normals = expected_normals(model.mean_normals[u], model.normal_variance[u])
    return estimate_light(grid_image[model.mask][u], normals)
