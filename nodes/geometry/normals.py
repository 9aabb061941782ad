"""Geometry of unit normals: tangent bases, azimuthal equidistant projection, angles.

All normals are unit vectors in the camera frame of ``conventions.md``
(x = image right, y = image up, z = toward the viewer), stored last-axis ``(..., 3)``.
"""
from __future__ import annotations

import numpy as np

_EPS = 1e-12


def normalize(v: np.ndarray, axis: int = -1) -> np.ndarray:
    """Unit vectors along ``axis``; zero vectors stay zero."""
    n = np.linalg.norm(v, axis=axis, keepdims=True)
    return v / np.maximum(n, _EPS)


def tangent_basis(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal tangent basis ``(e1, e2)`` at each unit reference direction ``m``.

    ``(e1, e2, m)`` are the columns of the minimal rotation taking +z to ``m``, so the basis
    is smooth everywhere except at ``m = -z`` (never a visible normal) and, for a frontal
    normal ``m = +z``, is exactly the image axes ``(x, y)``. The paper's elevation/azimuth
    parametrisation is singular there; this one is not.

    m: (..., 3) unit vectors. Returns two (..., 3) arrays.
    """
    mx, my, mz = m[..., 0], m[..., 1], m[..., 2]
    k = 1.0 / np.maximum(1.0 + mz, _EPS)
    e1 = np.stack([1.0 - mx * mx * k, -mx * my * k, -mx], axis=-1)
    e2 = np.stack([-mx * my * k, 1.0 - my * my * k, -my], axis=-1)
    return e1, e2


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product along the last axis (einsum: no (..., 3) temporary)."""
    return np.einsum("...i,...i->...", a, b)


def aep_forward(n: np.ndarray, m: np.ndarray, e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
    """Azimuthal equidistant projection of normals ``n`` about references ``m``.

    The point lies in the tangent plane at ``m`` along the great circle to ``n``, at a
    distance equal to the geodesic angle (radians). n, m, e1, e2: (..., 3), ``(e1, e2, m)``
    orthonormal. Returns (..., 2) float coordinates in the basis ``(e1, e2)``.
    """
    x, y = _dot(n, e1), _dot(n, e2)  # the tangent component of n (e1, e2 are orthogonal to m)
    s = np.hypot(x, y)  # sin(theta), exact for small angles unlike sqrt(1 - cos^2)
    theta = np.arctan2(s, _dot(n, m))
    scale = np.divide(theta, s, out=np.ones_like(s), where=s > 1e-12)  # theta / sin(theta) -> 1
    out = np.empty(x.shape + (2,), np.result_type(x, np.float64))
    out[..., 0] = x * scale
    out[..., 1] = y * scale
    return out


def aep_inverse(v: np.ndarray, m: np.ndarray, e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
    """Inverse azimuthal equidistant projection: (..., 2) tangent coordinates to unit normals."""
    v0, v1 = v[..., 0], v[..., 1]
    theta = np.hypot(v0, v1)
    k = np.divide(np.sin(theta), theta, out=np.ones_like(theta), where=theta > 1e-12)  # sin(theta) / theta
    return np.cos(theta)[..., None] * m + (k * v0)[..., None] * e1 + (k * v1)[..., None] * e2


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in degrees between unit vectors ``a`` and ``b`` along the last axis."""
    c = np.clip(_dot(a, b), -1.0, 1.0)
    return np.degrees(np.arccos(c))


def normals_from_depth(depth: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Unit normals of a height field.

    depth: (H, W) height toward the viewer in pixel units (NaN off the surface).
    Central differences inside, one-sided at the mask edge. Returns (H, W, 3) float32,
    camera frame, NaN where depth is NaN or outside ``mask``.
    """
    z = np.asarray(depth, dtype=np.float64)
    valid = np.isfinite(z) if mask is None else (np.asarray(mask, bool) & np.isfinite(z))
    dzdx = _masked_derivative(z, valid, axis=1)
    dzdrow = _masked_derivative(z, valid, axis=0)
    # y is up: dz/dy = -dz/drow
    n = np.stack([-dzdx, dzdrow, np.ones_like(z)], axis=-1)
    n = normalize(n)
    n[~valid] = np.nan
    return n.astype(np.float32)


def _masked_derivative(z: np.ndarray, valid: np.ndarray, axis: int) -> np.ndarray:
    """d z / d index along ``axis``: central where both neighbours are valid, else one-sided."""
    zf = np.where(valid, z, 0.0)
    zt, vt = np.moveaxis(zf, axis, -1), np.moveaxis(valid, axis, -1)
    step = np.zeros_like(zt)  # step[..., i] = z[i + 1] - z[i], where both are valid
    step[..., :-1] = zt[..., 1:] - zt[..., :-1]
    ok = np.zeros(vt.shape, bool)
    ok[..., :-1] = vt[..., 1:] & vt[..., :-1]
    fwd, fwd_ok = step, ok
    bwd = np.zeros_like(zt)
    bwd[..., 1:] = step[..., :-1]
    bwd_ok = np.zeros_like(ok)
    bwd_ok[..., 1:] = ok[..., :-1]
    d = np.where(fwd_ok & bwd_ok, 0.5 * (fwd + bwd), np.where(fwd_ok, fwd, np.where(bwd_ok, bwd, 0.0)))
    return np.moveaxis(d, -1, axis)
