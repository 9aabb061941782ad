"""Robust statistics of the fit: Huber weights and the scale of 2-D residual norms."""
from __future__ import annotations

import numpy as np

RAYLEIGH_MEDIAN = float(np.sqrt(2.0 * np.log(2.0)))  # median of a unit Rayleigh variable
MAD_TO_SIGMA = 1.4826  # a normal variable's sigma over its median absolute deviation


def huber_weights(residuals: np.ndarray, threshold: float) -> np.ndarray:
    """Huber weights: 1 below ``threshold``, ``threshold / |r|`` above. (N,) -> (N,)."""
    r = np.abs(residuals)
    return np.where(r <= threshold, 1.0, threshold / np.maximum(r, 1e-300))


def residual_scale(residuals: np.ndarray, method: str) -> float:
    """Robust scale of residual norms (radians): ``rayleigh`` or the paper's ``mad``."""
    r = np.asarray(residuals, np.float64)
    if r.size == 0:
        return 0.0
    if method == "mad":
        return float(MAD_TO_SIGMA * median(np.abs(r - median(r))))
    return float(median(r) / RAYLEIGH_MEDIAN)


def median(x: np.ndarray) -> float:
    """Median of a 1-D array by partial sort (np.median's checks cost more than the sort here)."""
    n = x.size
    if n == 0:
        return float("nan")
    if n % 2:
        return float(np.partition(x, n // 2)[n // 2])
    part = np.partition(x, (n // 2 - 1, n // 2))
    return 0.5 * float(part[n // 2 - 1] + part[n // 2])
