"""The linear algebra of one fit step, in single precision where the fit's tolerance allows:
the Gauss-Newton step, the (weighted) least-squares coefficients, and synthesis from them."""
from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.linalg import blas, lapack


def newton_step(modes32: np.ndarray, r: np.ndarray, eta: np.ndarray, w: np.ndarray, ridge: np.ndarray,
                 b: np.ndarray, damping: float) -> np.ndarray:
    """Gauss-Newton step on ``sum w eta^2 + sum ridge b^2`` (eta: each pixel's distance to its cone).

    A cone constrains one direction per pixel, its normal ``nu = r / eta`` in the tangent plane;
    along the cone the brightness says nothing. The step is ``(Qᵀ W Q + diag(ridge) + damping I)⁻¹
    (Qᵀ W eta - ridge b)`` with ``Q = nuᵀ P`` (N, K); the alternating loop solves the same with
    ``Pᵀ W P``, which also resists motion along the cones, hence its many small steps. Both stop at
    the same place (the right-hand side, the gradient, is the same). ``sqrt(w) Q`` is one sparse
    product (two entries a row) with the (2N, K) float32 modes: one pass over them, 15 % faster
    than two broadcast products; its Gram matrix a float32 BLAS ``syrk``.
    modes32 (2N, K) float32; r (N, 2); eta (N,) > 0, |r| or its floor; w (N,); ridge, b (K,).
    """
    n = len(eta)
    sw = np.sqrt(w)
    unit = sw / eta
    rows = sparse.csr_matrix(((r * unit[:, None]).astype(np.float32).ravel(), np.arange(2 * n),
                              np.arange(0, 2 * n + 1, 2)), shape=(n, 2 * n))
    along = np.asarray(rows @ modes32)  # (N, K): sqrt(w) nuᵀ P
    gram = blas.ssyrk(1.0, along.T, trans=0).astype(np.float64)  # upper triangle of Qᵀ W Q
    gram[np.diag_indices_from(gram)] += ridge + damping
    rhs = (along.T @ (sw * eta).astype(np.float32)).astype(np.float64) - ridge * b
    return cholesky_solve(gram, rhs)


def synthesize(modes32: np.ndarray, vbar: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Model AEP coordinates (N, 2) float64 of coefficients ``b`` (K,): ``vbar + P b``, the product
    in single precision (1e-7 relative, far below the fit's tolerance; a third of the time)."""
    return vbar + (modes32 @ b.astype(np.float32)).reshape(-1, 2)


def cholesky_solve(upper: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve a symmetric positive (semi-)definite system given its upper triangle (K, K)."""
    factor, info = lapack.dpotrf(upper, lower=0, clean=0, overwrite_a=0)
    if info == 0:
        x, info = lapack.dpotrs(factor, rhs, lower=0)
        if info == 0:
            return x
    full = np.triu(upper) + np.triu(upper, 1).T  # every weight 0 on some mode: least squares
    return np.linalg.lstsq(full, rhs, rcond=None)[0]


def unit_weight_solve(modes32: np.ndarray, released: np.ndarray, r0: np.ndarray) -> np.ndarray:
    """``(Pᵀ W P)⁻¹ Pᵀ W r0`` for W = 1 except 0 on ``released`` (N,) pixels: the modes are
    orthonormal, so ``Pᵀ W P = I - P_Rᵀ P_R`` needs the released rows only (none: one product).
    modes32 (2N, K) float32; r0 (2N,)."""
    rows = np.repeat(released, 2)
    rhs = (modes32.T @ np.where(rows, 0.0, r0).astype(np.float32)).astype(np.float64)
    if not rows.any():
        return rhs
    cut = modes32[rows]
    return cholesky_solve(np.eye(len(rhs)) - (cut.T @ cut).astype(np.float64), rhs)


def weighted_solve(modes32: np.ndarray, scaled: np.ndarray, w2: np.ndarray, r0: np.ndarray,
                    ridge: np.ndarray) -> np.ndarray:
    """``b = (Pᵀ W P + diag(ridge))⁻¹ Pᵀ W r0``: the Gram matrix by a symmetric rank-k update
    (BLAS syrk) of ``sqrt(w) P`` in float32 into ``scaled`` (2N, K), solved in float64 by
    Cholesky. modes32 (2N, K) float32; w2, r0 (2N,); ridge (K,)."""
    sw = np.sqrt(w2).astype(np.float32)
    np.multiply(modes32, sw[:, None], out=scaled)
    gram = blas.ssyrk(1.0, scaled.T, trans=0).astype(np.float64)  # upper triangle of Pᵀ W P
    gram[np.diag_indices_from(gram)] += ridge
    rhs = (scaled.T @ (sw * r0).astype(np.float32)).astype(np.float64)
    return cholesky_solve(gram, rhs)
