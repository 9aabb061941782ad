"""A naive reference for the speed benchmark: a straightforward transcription of the paper's
robust fit, one pixel at a time. NOT used by the product.

Same mathematics as ``shadowflow.nodes.method.robust_fit.fit`` with ``FitConfig(adaptive_prior=0)`` minus the
in-loop cast-shadow release: per pixel, the tangent basis is rebuilt, the normal projected by
the azimuthal equidistant projection, the weighted normal equations accumulated, the fit
unprojected and rotated onto the reflectance cone, all in Python loops over pixels.
"""
from __future__ import annotations

import math

import numpy as np


def _basis(m):
    # minimal rotation taking +z to m, applied to x and y
    x, y, z = m
    k = 1.0 / (1.0 + z) if z > -0.999999 else 0.0
    e1 = np.array([1.0 - k * x * x, -k * x * y, -x])
    e2 = np.array([-k * x * y, 1.0 - k * y * y, -y])
    return e1, e2


def _aep(n, m, e1, e2):
    c = max(-1.0, min(1.0, float(n @ m)))
    theta = math.acos(c)
    t = n - c * m
    norm = math.sqrt(float(t @ t))
    if norm < 1e-12:
        return 0.0, 0.0
    return theta * float(t @ e1) / norm, theta * float(t @ e2) / norm


def _aep_inv(u, v, m, e1, e2):
    theta = math.hypot(u, v)
    if theta < 1e-12:
        return m.copy()
    d = (u * e1 + v * e2) / theta
    return math.cos(theta) * m + math.sin(theta) * d


def _on_cone(n, s, i):
    # rotate n about n x s so that n . s = i (i <= 0: keep n if it already faces away)
    i = min(1.0, i)
    if i <= 0.0 and n @ s <= 0.0:
        return n
    target = math.acos(max(0.0, i))
    axis = np.cross(n, s)
    an = math.sqrt(float(axis @ axis))
    if an < 1e-12:
        return n
    axis /= an
    current = math.acos(max(-1.0, min(1.0, float(n @ s))))
    a = current - target
    return n * math.cos(a) + np.cross(axis, n) * math.sin(a) + axis * float(axis @ n) * (1 - math.cos(a))


def naive_fit(mean_normals, mean_proj, modes, intensity, light, huber_k=1.5, dark=0.02,
              max_iterations=100, tolerance_deg=0.01):
    """(N, 3) fitted normals and the iteration count; arguments as ``shadowflow.nodes.method.robust_fit.fit``."""
    N, K = len(mean_normals), modes.shape[1]
    s = np.asarray(light, float)
    n = np.array(mean_normals, float)
    w = np.ones(N)
    it = 0
    for it in range(1, max_iterations + 1):
        gram = np.zeros((K, K))
        rhs = np.zeros(K)
        v = np.zeros((N, 2))
        for p in range(N):
            e1, e2 = _basis(mean_normals[p])
            v[p] = _aep(n[p], mean_normals[p], e1, e2)
            for a in range(2):
                row = modes[2 * p + a]
                gram += w[p] * np.outer(row, row)
                rhs += w[p] * row * (v[p, a] - mean_proj[p, a])
        b = np.linalg.solve(gram, rhs)
        fitted = mean_proj + (modes @ b).reshape(-1, 2)
        eta = np.linalg.norm(v - fitted, axis=1)
        sigma = np.median(eta) / math.sqrt(2 * math.log(2))
        w = np.minimum(1.0, huber_k * sigma / np.maximum(eta, 1e-12))
        new = np.empty_like(n)
        for p in range(N):
            e1, e2 = _basis(mean_normals[p])
            m = _aep_inv(fitted[p, 0], fitted[p, 1], mean_normals[p], e1, e2)
            new[p] = _on_cone(m, s, -1.0 if intensity[p] <= dark else float(intensity[p]))
        change = float(np.mean(np.degrees(np.arccos(np.clip(np.sum(new * n, axis=1), -1, 1)))))
        n = new
        if change < tolerance_deg:
            break
    return n, it
