"""Robust fit of the needle-map model to one image (Smith & Hancock, sections 3-4).

Alternate (a) a robust fit of the model to the current on-cone needle-map in AEP coordinates
and (b) rotating the fitted normals back onto their reflectance cones, until the needle-map
stops changing. Two solvers:

* ``irls`` (default): exact iteratively reweighted least squares, per iteration
  ``b = (P^T W P + lambda Lambda^-1)^-1 P^T W (v - vbar)``, with Huber weights from the
  previous iteration's residuals. This is the M-estimate the paper's equation (1) asks for.
* ``paper``: the paper's one-step formula (3), ``b = C P^T W (v - vbar)`` with ``C = N / sum(w)``.
  The paper prints ``C = N Tr(W^-1)``, which is at least ``N^2`` and scales ``b`` away at
  once; ``N / sum(w)`` is the compensation for the overall scaling of ``W`` the text intends.
  Even so the formula ignores the correlation that ``W`` puts between modes and drifts.

Residuals are 2-D (per pixel, in the tangent plane), so their norms are Rayleigh rather than
normal: ``scale="rayleigh"`` (default) estimates the per-axis spread as
``median(eta) / sqrt(2 ln 2)`` and thresholds Huber at ``huber_k`` times it;
``scale="mad"`` is the paper's ``1.4826 MAD(eta)`` with threshold ``sigma`` itself, which
down-weights most clean pixels (README, "Where we depart from the paper").
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable, Literal

import numpy as np
from scipy import linalg
from scipy.linalg import blas

from nodes.geometry import angle_deg
from nodes.integrate import masked_least_squares
from nodes.reflectance import irradiance_constraint
from nodes.shape_model import ShapeModel
from nodes.sfs_init import gradient_init, mean_init
from nodes.shadow import cast_shadow

RAYLEIGH_MEDIAN = float(np.sqrt(2.0 * np.log(2.0)))  # median of a unit Rayleigh variable


@dataclass(frozen=True)
class FitConfig:
    """Options of the robust fit; ``FitConfig.paper()`` is the paper's variant throughout."""

    solver: Literal["irls", "paper"] = "irls"
    scale: Literal["rayleigh", "mad"] = "rayleigh"
    huber_k: float = 1.5  # Huber threshold in units of sigma
    init: Literal["mean", "gradient"] = "mean"
    attached_shadow: bool = True  # I <= dark_threshold: n.s <= 0 instead of the 90-degree cone
    dark_threshold: float = 0.02
    release_cast: bool = True  # dark pixels the current shape casts a shadow on: no constraint
    cast_every: int = 5  # re-trace cast shadows every this many iterations
    prior: float = 0.0  # weight of the Gaussian prior b_k^2 / eigenvalue_k (0: none)
    # weight of the same prior in units of the current residual variance sigma^2 (MAP with
    # correlated residuals): strong when the image fits badly (real skin), nil on clean input
    adaptive_prior: float = 100.0
    # over-relaxation of the coefficients, b <- b_prev + omega (b - b_prev): the loop creeps toward
    # its fixed point; omega = 1.8 takes 30-45 % fewer iterations to the same or lower error (3 diverges;
    # a residual scale that jumps switches it off for the rest of the fit)
    relaxation: float = 1.8
    max_iterations: int = 100
    tolerance_deg: float = 0.01  # stop when the mean normal change falls below this
    n_modes: int | None = None  # use the model's first K modes (None: all)
    saturation: float = 0.998  # input brightness at or above this is clipped (255 of 8 bits): no constraint (> 1: off)

    @staticmethod
    def paper(**overrides) -> "FitConfig":
        """The paper's choices: one-step formula, MAD scale, gradient start, 90-degree cone,
        saturated pixels kept, no prior."""
        base = FitConfig(solver="paper", scale="mad", huber_k=1.0, init="gradient", attached_shadow=False,
                         release_cast=False, saturation=2.0, adaptive_prior=0.0, relaxation=1.0)
        return replace(base, **overrides)


@dataclass
class FitIteration:
    """One pass of the loop. Arrays are over the N model pixels.

    normals: (N, 3) on-cone normals n''; model_normals: (N, 3) model fit n';
    weights: (N,) Huber weights from this pass's residuals; residuals: (N,) radians;
    sigma: scale (radians); b: (K,) coefficients; change_deg: mean angle n -> n''.
    """

    iteration: int
    normals: np.ndarray
    model_normals: np.ndarray
    weights: np.ndarray
    residuals: np.ndarray
    sigma: float
    b: np.ndarray
    change_deg: float

    def scalars(self) -> dict[str, float]:
        r = self.residuals
        return {
            "sigma": float(self.sigma),
            "residual_mean": float(np.mean(r)),
            "residual_median": float(np.median(r)),
            "downweighted_fraction": float(np.mean(self.weights < 1.0)),
            "change_deg": float(self.change_deg),
        }


@dataclass
class FitResult:
    """Outcome of ``fit``: the last iteration's arrays plus how the loop ended."""

    normals: np.ndarray  # (N, 3) on-cone n''
    model_normals: np.ndarray  # (N, 3) model fit n'
    weights: np.ndarray  # (N,)
    residuals: np.ndarray  # (N,)
    b: np.ndarray  # (K,)
    sigma: float
    iterations: int
    converged: bool
    history: list[dict[str, float]] = field(default_factory=list)


def huber_weights(residuals: np.ndarray, threshold: float) -> np.ndarray:
    """Huber weights: 1 below ``threshold``, ``threshold / |r|`` above. (N,) -> (N,)."""
    r = np.abs(residuals)
    return np.where(r <= threshold, 1.0, threshold / np.maximum(r, 1e-300))


def residual_scale(residuals: np.ndarray, method: str) -> float:
    """Robust scale of residual norms (radians): ``rayleigh`` or the paper's ``mad``."""
    r = np.asarray(residuals, np.float64)
    if method == "mad":
        return float(1.4826 * np.median(np.abs(r - np.median(r))))
    return float(np.median(r) / RAYLEIGH_MEDIAN)


def fit(
    model: ShapeModel,
    intensity: np.ndarray,
    light: np.ndarray,
    config: FitConfig = FitConfig(),
    initial: np.ndarray | None = None,
    on_iteration: Callable[[FitIteration], None] | None = None,
    unreliable: np.ndarray | None = None,
) -> FitResult:
    """Fit ``model`` to remapped brightness under a known light.

    intensity: (N,) remapped brightness at the model pixels, [0, 1]. light: (3,) unit,
    camera frame. initial: (N, 3) starting normals (default: the mean face on its cones,
    see ``initial_normals``). on_iteration: called with every ``FitIteration``.
    unreliable: (N,) bool, pixels whose brightness says nothing (e.g. saturated): weight 0,
    their normals come from the model, like cast-shadowed dark pixels.
    """
    if config.n_modes is not None and config.n_modes < model.n_modes:
        model = model.truncated(config.n_modes)
    s = np.asarray(light, np.float64)
    s = s / np.linalg.norm(s)
    I = np.clip(np.asarray(intensity, np.float64), 0.0, 1.0)
    n_pix = model.n_pixels
    dark = (I <= config.dark_threshold) if config.attached_shadow else None

    P = model.modes_as(np.float64)  # (2N, K)
    P32 = model.modes_as(np.float32)  # the Gram matrix in single precision: half the time, same fit
    scaled = np.empty_like(P32)  # reused: sqrt(w) P
    vbar = model.mean_proj.astype(np.float64)
    prior = config.prior / np.maximum(model.eigenvalues.astype(np.float64), 1e-12)
    adaptive = config.adaptive_prior / np.maximum(model.eigenvalues.astype(np.float64), 1e-12)
    sigma_prev = 0.0  # no residuals before the first pass
    b_prev = None
    omega = config.relaxation if config.solver == "irls" else 1.0
    if initial is None:
        n = mean_init(model.mean_normals, I, s, dark)
    else:
        n = np.asarray(initial, np.float64)
    w = np.ones(n_pix)
    known_bad = np.zeros(n_pix, bool) if unreliable is None else np.asarray(unreliable, bool)
    released = known_bad.copy()  # plus dark pixels in the current shape's cast shadow
    history: list[dict[str, float]] = []
    converged = False
    it = 0
    for it in range(1, config.max_iterations + 1):
        v = model.project(n)
        r0 = (v - vbar).reshape(-1)
        w2 = np.repeat(np.where(released, 0.0, w), 2)
        if config.solver == "irls":
            b = _weighted_solve(P32, scaled, w2, r0, prior + adaptive * sigma_prev**2)
        elif config.solver == "paper":
            c = n_pix / max(float(w.sum()), 1e-12)
            b = c * (P.T @ (w2 * r0))
        else:
            raise ValueError(f"unknown solver {config.solver!r}")
        if omega != 1.0 and b_prev is not None:
            b = b_prev + omega * (b - b_prev)
        b_prev = b
        v_fit = vbar + (P @ b).reshape(-1, 2)
        eta = np.linalg.norm(v - v_fit, axis=1)
        sigma = residual_scale(eta, config.scale)
        if omega != 1.0 and it > 2 and sigma > 1.5 * sigma_prev:
            omega = 1.0  # the relaxed steps overshoot: plain iterations from here on
        sigma_prev = sigma
        w = huber_weights(eta, config.huber_k * max(sigma, 1e-9))
        n_model = model.unproject(v_fit)
        n_new = irradiance_constraint(n_model, s, I, dark, fallback=model.mean_normals)
        if config.release_cast and dark is not None and it % config.cast_every == 0:
            released = known_bad | (dark & _cast_by_shape(model, n_model, s))
        if released.any():
            n_new[released] = n_model[released]
            w = np.where(released, 0.0, w)
        change = float(np.mean(angle_deg(n, n_new)))
        record = FitIteration(it, n_new, n_model, w, eta, sigma, b, change)
        history.append({"iteration": it, **record.scalars()})
        if on_iteration is not None:
            on_iteration(record)
        n = n_new
        if change < config.tolerance_deg:
            converged = True
            break
    return FitResult(n, n_model, w, eta, b, sigma, it, converged, history)


def _weighted_solve(modes32: np.ndarray, scaled: np.ndarray, w2: np.ndarray, r0: np.ndarray,
                    ridge: np.ndarray) -> np.ndarray:
    """``b = (Pᵀ W P + diag(ridge))⁻¹ Pᵀ W r0``: the Gram matrix by a symmetric rank-k update
    (BLAS syrk) of ``sqrt(w) P`` in float32 into ``scaled`` (2N, K), solved in float64 by
    Cholesky. modes32 (2N, K) float32; w2, r0 (2N,); ridge (K,)."""
    sw = np.sqrt(w2).astype(np.float32)
    np.multiply(modes32, sw[:, None], out=scaled)
    gram = blas.ssyrk(1.0, scaled.T, trans=0).astype(np.float64)  # upper triangle of Pᵀ W P
    gram[np.diag_indices_from(gram)] += ridge
    rhs = (scaled.T @ (sw * r0).astype(np.float32)).astype(np.float64)
    try:
        return linalg.cho_solve(linalg.cho_factor(gram, lower=False, overwrite_a=True, check_finite=False), rhs,
                                check_finite=False)
    except linalg.LinAlgError:  # every weight 0 on some mode: fall back to least squares
        full = np.triu(gram) + np.triu(gram, 1).T
        return np.linalg.lstsq(full, rhs, rcond=None)[0]


def _cast_by_shape(model: ShapeModel, normals: np.ndarray, light: np.ndarray) -> np.ndarray:
    """(N,) bool: model pixels in the cast shadow of the surface integrated from ``normals``."""
    depth = masked_least_squares(model.to_image(normals.astype(np.float32)), model.mask)
    return cast_shadow(depth, light)[model.mask]


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
