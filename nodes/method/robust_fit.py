"""Robust fit of the needle-map model to one image (Smith & Hancock, sections 3-4).

The paper alternates (a) a robust fit of the model to the current on-cone needle-map in AEP
coordinates and (b) rotating the fitted normals back onto their reflectance cones, until the
needle-map stops changing. Its fixed point is where the weighted gradient
``Pᵀ W r - ridge b`` vanishes, ``r`` being each model normal's AEP offset to its cone. Three
solvers:

* ``gauss-newton`` (default): Gauss-Newton steps on that same objective. A cone constrains one
  direction per pixel, its normal ``nu``; the step uses ``Qᵀ W Q`` with ``Q = nuᵀ P`` where the
  alternation uses ``Pᵀ W P``, which also holds back motion *along* the cones that the image
  does not constrain. Same fixed point, 3-7x fewer iterations, and half the Gram matrix work
  (N rows instead of 2N). If a step makes the residual scale jump, the fit falls back to the
  alternation, which cannot diverge.
* ``irls``: the paper's alternation with the exact weighted least squares per pass,
  ``b = (P^T W P + ridge)^-1 P^T W (v - vbar)``, Huber weights from the previous residuals, and
  over-relaxation. This is the M-estimate the paper's equation (1) asks for.
* ``paper``: the paper's one-step formula (3), ``b = C P^T W (v - vbar)`` with ``C = N / sum(w)``.
  The paper prints ``C = N Tr(W^-1)``, which is at least ``N^2`` and scales ``b`` away at
  once; ``N / sum(w)`` is the compensation for the overall scaling of ``W`` the text intends.
  Even so the formula ignores the correlation that ``W`` puts between modes and drifts.

The residual scale comes from the pixels that constrain the fit: released pixels (saturated,
outside the photo, in the shape's own cast shadow) and dark pixels already facing away from the
light have zero residual by construction and would drag the median to zero.

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
from scipy import sparse
from scipy.linalg import blas, lapack

from ..geometry.integrate import masked_least_squares
from ..geometry.normals import angle_deg
from ..geometry.reflectance import irradiance_constraint
from ..model.shape_model import ShapeModel
from .albedo import smooth_albedo
from .sfs_init import gradient_init, mean_init
from .shadow import cast_shadow

RAYLEIGH_MEDIAN = float(np.sqrt(2.0 * np.log(2.0)))  # median of a unit Rayleigh variable


@dataclass(frozen=True)
class FitConfig:
    """Options of the robust fit; ``FitConfig.paper()`` is the paper's variant throughout."""

    solver: Literal["gauss-newton", "irls", "paper"] = "gauss-newton"  # see the module docstring
    scale: Literal["rayleigh", "mad"] = "rayleigh"
    # Huber threshold in units of sigma: 1.0 on real photos (Yale B, ICT model) beat 1.5 by up to 0.4 deg at
    # +-70 with the stronger prior below; clean renders lose 0.1-0.3 deg (README, "Real photographs")
    huber_k: float = 1.0
    init: Literal["mean", "gradient"] = "mean"
    attached_shadow: bool = True  # I <= dark_threshold: n.s <= 0 instead of the 90-degree cone
    dark_threshold: float = 0.02
    release_cast: bool = True  # dark pixels the current shape casts a shadow on: no constraint
    cast_every: int = 5  # re-trace cast shadows every this many iterations
    prior: float = 0.0  # weight of the Gaussian prior b_k^2 / eigenvalue_k (0: none)
    # weight of the same prior in units of the current residual variance sigma^2 (MAP with
    # correlated residuals): strong when the image fits badly (real skin), nil on clean input
    # 200 with the ICT model (100 was the procedural model's choice): on Yale B photos with Huber 1.5, 100 and 300
    # gave 16.5 and 15.8 deg at +-25; with Huber 1.0, 200 was as good as 300 or better at every light (within
    # 0.02 deg at +-25) and 0.2 deg better on clean SFM renders
    adaptive_prior: float = 200.0
    # irls: over-relaxation of the coefficients, b <- b_prev + omega (b - b_prev): the loop creeps toward
    # its fixed point; omega = 1.8 takes 30-45 % fewer iterations to the same or lower error (3 diverges;
    # a residual scale that jumps switches it off for the rest of the fit)
    relaxation: float = 1.8
    damping: float = 1e-3  # gauss-newton: Levenberg term added to the K x K system (modes are orthonormal)
    max_iterations: int = 100
    # stop when the mean normal change falls below this (degrees). None: 0.05 for gauss-newton, whose
    # changes shrink by half or more per step so the rest of the way is below it too (same errors to
    # 0.005 deg as 0.01, a third fewer iterations); 0.01 for the alternation, which creeps
    tolerance_deg: float | None = None
    n_modes: int | None = None  # use the model's first K modes (None: all)
    saturation: float = 0.998  # input brightness at or above this is clipped (255 of 8 bits): no constraint (> 1: off)
    # real skin: when the fit has converged, divide the image by the smooth albedo its shape implies
    # (nodes.albedo.smooth_albedo) and fit on, this many times (0: one albedo everywhere, the paper)
    # (on by default: with the ICT model and today's other defaults it takes Yale B normals 0.1-0.4 deg lower at
    # +-25 / +-50 / +-35+15 and leaves +-70 as it was; 0.7-1.8 deg lower before the mouth line and cone trust)
    albedo_rounds: int = 1
    albedo_sigma: float = 0.08  # that albedo's smoothing, in interocular distances (2.9 px at 128^2)
    # output blend normalize(c w n'' + (1 - c w) n') (``combine``): how far the on-cone normals are trusted
    # where the weights trust their pixel; 1 is the paper's blend. On photos the cones carry the skin's albedo
    # errors: on Yale B 0.5 is 0.1-0.2 deg better than 1 at +-50 and +-70. The albedo and the relighting keep
    # the paper's blend, which relit 0.5 dB better (README, "Real photographs")
    cone_trust: float = 0.5

    @staticmethod
    def paper(**overrides) -> "FitConfig":
        """The paper's choices: one-step formula, MAD scale, gradient start, 90-degree cone,
        saturated pixels kept, no prior."""
        base = FitConfig(solver="paper", scale="mad", huber_k=1.0, init="gradient", attached_shadow=False,
                         release_cast=False, saturation=2.0, adaptive_prior=0.0, relaxation=1.0, albedo_rounds=0,
                         cone_trust=1.0)
        return replace(base, **overrides)


@dataclass
class FitIteration:
    """One pass of the loop. Arrays are over the N model pixels.

    normals: (N, 3) on-cone normals n''; model_normals: (N, 3) model fit n';
    weights: (N,) Huber weights of this pass; residuals: (N,) radians, the offsets they came from
    (gauss-newton: the previous model's distance to its cones, before this pass's step; irls:
    this pass's fit to the previous on-cone normals);
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
            "residual_median": _median(r),
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
    if r.size == 0:
        return 0.0
    if method == "mad":
        return float(1.4826 * _median(np.abs(r - _median(r))))
    return float(_median(r) / RAYLEIGH_MEDIAN)


def _median(x: np.ndarray) -> float:
    """Median of a 1-D array by partial sort (np.median's checks cost more than the sort here)."""
    n = x.size
    if n == 0:
        return float("nan")
    if n % 2:
        return float(np.partition(x, n // 2)[n // 2])
    part = np.partition(x, (n // 2 - 1, n // 2))
    return 0.5 * float(part[n // 2 - 1] + part[n // 2])


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
    I0 = np.clip(np.asarray(intensity, np.float64), 0.0, 1.0)
    I = I0
    n_pix = model.n_pixels
    dark = (I <= config.dark_threshold) if config.attached_shadow else None
    albedo_rounds = config.albedo_rounds

    P32 = model.modes_as(np.float32)  # (2N, K): Gram matrices and products in single precision, same fit
    scaled = np.empty_like(P32)  # reused: sqrt(w) P
    vbar = model.mean_proj.astype(np.float64)
    prior = config.prior / np.maximum(model.eigenvalues.astype(np.float64), 1e-12)
    adaptive = config.adaptive_prior / np.maximum(model.eigenvalues.astype(np.float64), 1e-12)
    sigma_prev = 0.0  # no residuals before the first pass
    newton = config.solver == "gauss-newton"
    tolerance = config.tolerance_deg if config.tolerance_deg is not None else (0.05 if newton else 0.01)
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
    b: np.ndarray | None = None
    v_fit = vbar
    n_model = n
    it = 0
    for it in range(1, config.max_iterations + 1):
        v = model.project(n)
        if newton and b is not None:
            # the model's distance to its cones: r points along each cone's normal direction
            r = v - v_fit
            eta = np.hypot(r[:, 0], r[:, 1])
            active = _constrained(released, dark, n_model, s)
            sigma = residual_scale(eta[active], config.scale)
            if it > 3 and sigma > 1.5 * sigma_prev:
                newton = False  # the step overshot: alternating projections (always stable) from here on
                if config.tolerance_deg is None:
                    tolerance = 0.01  # and the alternation's stopping rule, as it creeps
            else:
                w = huber_weights(eta, config.huber_k * max(sigma, 1e-9))
                w[~active] = 0.0
                on_cone = active & (eta < 1e-6)  # at the round-off of the AEP round trip: r has no direction
                if on_cone.any():
                    r[on_cone] = 1e-6 * _cone_normal(model, n_model[on_cone], s, on_cone)
                step = _newton_step(P32, r, np.maximum(eta, 1e-6), w, prior + adaptive * sigma**2, b, config.damping)
                b = b + step
                sigma_prev = sigma
                v_fit = _synthesize(P32, vbar, b)
        if not newton or b is None:
            r0 = (v - vbar).reshape(-1)
            w2 = np.repeat(np.where(released, 0.0, w), 2)
            if config.solver == "paper":
                c = n_pix / max(float(w.sum()), 1e-12)
                b_new = c * (model.modes_as(np.float64).T @ (w2 * r0))
            elif b is None and not prior.any() and released.mean() < 0.5:  # first pass: unit weights
                b_new = _unit_weight_solve(P32, released, r0)
            elif config.solver in ("irls", "gauss-newton"):
                b_new = _weighted_solve(P32, scaled, w2, r0, prior + adaptive * sigma_prev**2)
            else:
                raise ValueError(f"unknown solver {config.solver!r}")
            if omega != 1.0 and b is not None:
                b_new = b + omega * (b_new - b)
            b = b_new
            v_fit = _synthesize(P32, vbar, b)
            eta = np.linalg.norm(v - v_fit, axis=1)
            sigma = residual_scale(eta[_constrained(released, dark, n_model, s)], config.scale)
            if omega != 1.0 and it > 2 and sigma > 1.5 * sigma_prev:
                omega = 1.0  # the relaxed steps overshoot: plain iterations from here on
            sigma_prev = sigma
            w = huber_weights(eta, config.huber_k * max(sigma, 1e-9))
        n_model = model.unproject(v_fit)
        n_new = irradiance_constraint(n_model, s, I, dark, fallback=model.mean_normals)
        if config.release_cast and dark is not None and it % config.cast_every == 0:
            released = known_bad | _cast_by_shape(model, n_model, s, dark)
        if released.any():
            n_new[released] = n_model[released]
            w = np.where(released, 0.0, w)
        change = float(np.mean(angle_deg(n, n_new)))
        record = FitIteration(it, n_new, n_model, w, eta, sigma, b, change)
        history.append({"iteration": it, **record.scalars()})
        if on_iteration is not None:
            on_iteration(record)
        n = n_new
        if change < tolerance and albedo_rounds > 0:
            albedo_rounds -= 1
            I = _without_smooth_albedo(model, I0, n_model, s, w, released, dark, config)
            n = irradiance_constraint(n_model, s, I, dark, fallback=model.mean_normals)
            continue
        if change < tolerance:
            converged = True
            break
    return FitResult(n, n_model, w, eta, b, sigma, it, converged, history)


def _without_smooth_albedo(model: ShapeModel, I0: np.ndarray, n_model: np.ndarray, s: np.ndarray, w: np.ndarray,
                           released: np.ndarray, dark: np.ndarray | None, config: FitConfig) -> np.ndarray:
    """The image (N,) divided by the smooth albedo the fitted shape implies, measured where the
    fit trusts the pixel and the shading is strong enough to divide by."""
    shading = n_model @ s
    trusted = (w >= 0.5) & ~released & (shading >= 0.4)
    if dark is not None:
        trusted &= ~dark
    iod = float(np.linalg.norm(np.subtract(*model.eyes)))
    albedo = smooth_albedo(model.mask, I0, shading, trusted, config.albedo_sigma * iod)
    return np.clip(I0 / albedo, 0.0, 1.0)


def _newton_step(modes32: np.ndarray, r: np.ndarray, eta: np.ndarray, w: np.ndarray, ridge: np.ndarray,
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
    return _cholesky_solve(gram, rhs)


def _constrained(released: np.ndarray, dark: np.ndarray | None, model_normals: np.ndarray,
                 light: np.ndarray) -> np.ndarray:
    """(N,) bool: pixels whose brightness constrains the current fit: not released, and not dark
    pixels already facing away from the light (an attached-shadow constraint that is obeyed is
    inactive). Their residuals alone set the scale: the others' are zero by construction."""
    free = released if dark is None else released | (dark & (model_normals @ light <= 0.0))
    return ~free


def _synthesize(modes32: np.ndarray, vbar: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Model AEP coordinates (N, 2) float64 of coefficients ``b`` (K,): ``vbar + P b``, the product
    in single precision (1e-7 relative, far below the fit's tolerance; a third of the time)."""
    return vbar + (modes32 @ b.astype(np.float32)).reshape(-1, 2)


def _cone_normal(model: ShapeModel, normals: np.ndarray, light: np.ndarray, where: np.ndarray) -> np.ndarray:
    """(M, 2) unit AEP direction (first order, mean-normal tangent basis) in which the angle of
    ``normals`` (M, 3) from ``light`` grows: the normal of their cones."""
    u = (normals @ light)[:, None] * normals - light
    d = np.stack([np.sum(u * model.e1[where], axis=1), np.sum(u * model.e2[where], axis=1)], axis=1)
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)


def _cholesky_solve(upper: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve a symmetric positive (semi-)definite system given its upper triangle (K, K)."""
    factor, info = lapack.dpotrf(upper, lower=0, clean=0, overwrite_a=0)
    if info == 0:
        x, info = lapack.dpotrs(factor, rhs, lower=0)
        if info == 0:
            return x
    full = np.triu(upper) + np.triu(upper, 1).T  # every weight 0 on some mode: least squares
    return np.linalg.lstsq(full, rhs, rcond=None)[0]


def _unit_weight_solve(modes32: np.ndarray, released: np.ndarray, r0: np.ndarray) -> np.ndarray:
    """``(Pᵀ W P)⁻¹ Pᵀ W r0`` for W = 1 except 0 on ``released`` (N,) pixels: the modes are
    orthonormal, so ``Pᵀ W P = I - P_Rᵀ P_R`` needs the released rows only (none: one product).
    modes32 (2N, K) float32; r0 (2N,)."""
    rows = np.repeat(released, 2)
    rhs = (modes32.T @ np.where(rows, 0.0, r0).astype(np.float32)).astype(np.float64)
    if not rows.any():
        return rhs
    cut = modes32[rows]
    return _cholesky_solve(np.eye(len(rhs)) - (cut.T @ cut).astype(np.float64), rhs)


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
    return _cholesky_solve(gram, rhs)


def _cast_by_shape(model: ShapeModel, normals: np.ndarray, light: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """(N,) bool: which of the ``sources`` (N,) bool model pixels lie in the cast shadow of the
    surface integrated from ``normals`` (N, 3); rays are traced from those pixels only."""
    if not sources.any():
        return sources.copy()
    depth = masked_least_squares(model.to_image(normals.astype(np.float32)), model.mask)
    return cast_shadow(depth, light, sources=model.to_image(sources, fill=False).astype(bool))[model.mask]


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
