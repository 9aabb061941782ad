"""The fit loop: one ``FitState`` carried through iterations, one step function per solver.

Each iteration (``fit``) does three things:
1. a solver step moves the model coefficients ``b`` toward the current on-cone normals
   (``STEPS[config.solver]``: ``gauss_newton_step``, ``irls_step`` or ``paper_step``) and
   sets the Huber weights from the residuals it saw;
2. the model normals are rotated back onto their reflectance cones (``irradiance_constraint``);
   pixels the shape's own cast shadow darkens, or the photo does not constrain, take the model's;
3. the iteration is reported (``on_iteration``) and the stopping rule is applied, with the
   smooth-albedo rounds (``config.albedo_rounds``) run at the first convergence.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ...geometry.integrate import masked_least_squares
from ...geometry.normals import angle_deg
from ...geometry.reflectance import irradiance_constraint
from ...model.shape_model import ShapeModel
from ..albedo import MIN_SHADING, smooth_albedo
from ..sfs_init import mean_init
from ..shadow import cast_shadow
from .config import (
    ALBEDO_MIN_WEIGHT,
    ALTERNATION_TOLERANCE_DEG,
    MIN_CONE_DISTANCE,
    MIN_EIGENVALUE,
    MIN_SIGMA,
    NEWTON_WARMUP,
    OVERSHOOT_FACTOR,
    RELAXATION_WARMUP,
    FitConfig,
)
from .linalg import newton_step, synthesize, unit_weight_solve, weighted_solve
from .robust import huber_weights, median, residual_scale


@dataclass
class FitIteration:
    """One pass of the loop. Arrays are over the N model pixels.

    normals: (N, 3) on-cone normals n''; model_normals: (N, 3) model fit n';
    weights: (N,) Huber weights of this pass; residuals: (N,) radians, the offsets they came from
    (gauss-newton: the previous model's distance to its cones, before this pass's step; irls:
    this pass's fit to the previous on-cone normals);
    sigma: scale (radians); b: (K,) coefficients; change_deg: mean angle n -> n''; albedo_round: the
    smooth-albedo round measured the albedo again just before this pass, so its cones moved (its change and
    residuals jump: the convergence plots mark it).
    """

    iteration: int
    normals: np.ndarray
    model_normals: np.ndarray
    weights: np.ndarray
    residuals: np.ndarray
    sigma: float
    b: np.ndarray
    change_deg: float
    albedo_round: bool = False

    def scalars(self) -> dict[str, float]:
        r = self.residuals
        return {
            "sigma": float(self.sigma),
            "residual_mean": float(np.mean(r)),
            "residual_median": median(r),
            "downweighted_fraction": float(np.mean(self.weights < 1.0)),
            "change_deg": float(self.change_deg),
            "albedo_round": float(self.albedo_round),
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


@dataclass(frozen=True)
class FitProblem:
    """What does not change during one fit. Arrays over the N model pixels.

    modes32: (2N, K) float32 modes (Gram matrices and products in single precision, same fit);
    scaled: (2N, K) float32 buffer reused for ``sqrt(w) P``; vbar: (N, 2) mean AEP coordinates;
    prior, adaptive: (K,) ridge per mode, fixed and per unit of residual variance;
    light: (3,) unit; intensity: (N,) remapped brightness in [0, 1]; dark: (N,) bool or None
    (no attached-shadow constraint); known_bad: (N,) bool, pixels that never constrain.
    """

    model: ShapeModel
    config: FitConfig
    modes32: np.ndarray
    scaled: np.ndarray
    vbar: np.ndarray
    prior: np.ndarray
    adaptive: np.ndarray
    light: np.ndarray
    intensity: np.ndarray
    dark: np.ndarray | None
    known_bad: np.ndarray

    @staticmethod
    def build(model: ShapeModel, intensity: np.ndarray, light: np.ndarray, config: FitConfig,
              unreliable: np.ndarray | None) -> "FitProblem":
        s = np.asarray(light, np.float64)
        eig = np.maximum(model.eigenvalues.astype(np.float64), MIN_EIGENVALUE)
        I0 = np.clip(np.asarray(intensity, np.float64), 0.0, 1.0)
        modes32 = model.modes_as(np.float32)
        return FitProblem(
            model=model, config=config, modes32=modes32, scaled=np.empty_like(modes32),
            vbar=model.mean_proj.astype(np.float64), prior=config.prior / eig, adaptive=config.adaptive_prior / eig,
            light=s / np.linalg.norm(s), intensity=I0,
            dark=(I0 <= config.dark_threshold) if config.attached_shadow else None,
            known_bad=np.zeros(model.n_pixels, bool) if unreliable is None else np.asarray(unreliable, bool))

    def ridge(self, sigma: float) -> np.ndarray:
        """(K,) the prior's weight per mode at residual scale ``sigma``."""
        return self.prior + self.adaptive * sigma**2


@dataclass
class FitState:
    """What one iteration hands the next. Arrays over the N model pixels.

    normals: (N, 3) current on-cone normals; model_normals: (N, 3) the model's; v_fit: (N, 2) the
    model's AEP coordinates; b: (K,) coefficients (None before the first step); weights (N,);
    residuals (N,) and sigma: this pass's; sigma_prev: the scale the last step was taken at;
    released: (N,) bool, pixels that do not constrain now (``known_bad`` and the shape's own cast
    shadow); intensity: (N,) the brightness fitted (the albedo rounds divide it);
    newton: Gauss-Newton steps still in use; omega: IRLS over-relaxation still in use;
    tolerance: the stopping rule (degrees); albedo_rounds: smooth-albedo rounds left.
    """

    normals: np.ndarray
    model_normals: np.ndarray
    v_fit: np.ndarray
    weights: np.ndarray
    released: np.ndarray
    intensity: np.ndarray
    newton: bool
    omega: float
    tolerance: float
    albedo_rounds: int
    b: np.ndarray | None = None
    residuals: np.ndarray | None = None
    sigma: float = 0.0
    sigma_prev: float = 0.0  # no residuals before the first pass
    albedo_measured: bool = False  # a smooth-albedo round ran since the last pass


def _constrained(released: np.ndarray, dark: np.ndarray | None, model_normals: np.ndarray,
                 light: np.ndarray) -> np.ndarray:
    """(N,) bool: pixels whose brightness constrains the current fit: not released, and not dark
    pixels already facing away from the light (an attached-shadow constraint that is obeyed is
    inactive). Their residuals alone set the scale: the others' are zero by construction."""
    free = released if dark is None else released | (dark & (model_normals @ light <= 0.0))
    return ~free


def _cone_normal(model: ShapeModel, normals: np.ndarray, light: np.ndarray, where: np.ndarray) -> np.ndarray:
    """(M, 2) unit AEP direction (first order, mean-normal tangent basis) in which the angle of
    ``normals`` (M, 3) from ``light`` grows: the normal of their cones."""
    u = (normals @ light)[:, None] * normals - light
    d = np.stack([np.sum(u * model.e1[where], axis=1), np.sum(u * model.e2[where], axis=1)], axis=1)
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)


def _huber(p: FitProblem, residuals: np.ndarray, sigma: float) -> np.ndarray:
    return huber_weights(residuals, p.config.huber_k * max(sigma, MIN_SIGMA))


def gauss_newton_step(p: FitProblem, st: FitState, v: np.ndarray, it: int) -> None:
    """One Gauss-Newton step from the model's distance to the cones of the on-cone normals ``v``
    (N, 2, AEP). The first step, and every step from the one where the residual scale jumps by
    ``OVERSHOOT_FACTOR`` (past ``NEWTON_WARMUP``), is the alternation instead (``irls_step``),
    which cannot diverge; from then on the alternation's stopping rule applies."""
    if st.b is None or not st.newton:
        irls_step(p, st, v, it)
        return
    r = v - st.v_fit  # the model's distance to its cones: r points along each cone's normal direction
    eta = np.hypot(r[:, 0], r[:, 1])
    active = _constrained(st.released, p.dark, st.model_normals, p.light)
    sigma = residual_scale(eta[active], p.config.scale)
    if it > NEWTON_WARMUP and sigma > OVERSHOOT_FACTOR * st.sigma_prev:
        st.newton = False  # the step overshot: alternating projections (always stable) from here on
        if p.config.tolerance_deg is None:
            st.tolerance = ALTERNATION_TOLERANCE_DEG  # and the alternation's stopping rule, as it creeps
        irls_step(p, st, v, it)
        return
    w = _huber(p, eta, sigma)
    w[~active] = 0.0
    on_cone = active & (eta < MIN_CONE_DISTANCE)  # at the round-off of the AEP round trip: r has no direction
    if on_cone.any():
        r[on_cone] = MIN_CONE_DISTANCE * _cone_normal(p.model, st.model_normals[on_cone], p.light, on_cone)
    step = newton_step(p.modes32, r, np.maximum(eta, MIN_CONE_DISTANCE), w, p.ridge(sigma), st.b, p.config.damping)
    st.b = st.b + step
    st.v_fit = synthesize(p.modes32, p.vbar, st.b)
    st.weights, st.residuals, st.sigma, st.sigma_prev = w, eta, sigma, sigma


def irls_step(p: FitProblem, st: FitState, v: np.ndarray, it: int) -> None:
    """One pass of the paper's alternation: the weighted least-squares coefficients of the
    on-cone normals ``v`` (N, 2, AEP) with the previous pass's weights, over-relaxed by
    ``omega`` until a pass makes the residual scale jump (past ``RELAXATION_WARMUP``)."""
    r0 = (v - p.vbar).reshape(-1)
    if st.b is None and not p.prior.any() and st.released.mean() < 0.5:  # first pass: unit weights
        b_new = unit_weight_solve(p.modes32, st.released, r0)
    else:
        w2 = np.repeat(np.where(st.released, 0.0, st.weights), 2)
        b_new = weighted_solve(p.modes32, p.scaled, w2, r0, p.ridge(st.sigma_prev))
    _take_alternation(p, st, v, it, b_new)


def paper_step(p: FitProblem, st: FitState, v: np.ndarray, it: int) -> None:
    """One pass with the paper's one-step formula (3), ``b = C Pᵀ W (v - vbar)``, ``C = N / sum(w)``
    (module docstring of ``robust_fit``)."""
    r0 = (v - p.vbar).reshape(-1)
    w2 = np.repeat(np.where(st.released, 0.0, st.weights), 2)
    c = p.model.n_pixels / max(float(st.weights.sum()), 1e-12)
    _take_alternation(p, st, v, it, c * (p.model.modes_as(np.float64).T @ (w2 * r0)))


def _take_alternation(p: FitProblem, st: FitState, v: np.ndarray, it: int, b_new: np.ndarray) -> None:
    """Accept an alternation pass's coefficients (over-relaxed while ``omega`` != 1) and set the
    residuals, scale and Huber weights of the fit to ``v``."""
    if st.omega != 1.0 and st.b is not None:
        b_new = st.b + st.omega * (b_new - st.b)
    st.b = b_new
    st.v_fit = synthesize(p.modes32, p.vbar, st.b)
    eta = np.linalg.norm(v - st.v_fit, axis=1)
    sigma = residual_scale(eta[_constrained(st.released, p.dark, st.model_normals, p.light)], p.config.scale)
    if st.omega != 1.0 and it > RELAXATION_WARMUP and sigma > OVERSHOOT_FACTOR * st.sigma_prev:
        st.omega = 1.0  # the relaxed steps overshoot: plain iterations from here on
    st.weights, st.residuals, st.sigma, st.sigma_prev = _huber(p, eta, sigma), eta, sigma, sigma


STEPS: dict[str, Callable[[FitProblem, FitState, np.ndarray, int], None]] = {
    "gauss-newton": gauss_newton_step,
    "irls": irls_step,
    "paper": paper_step,
}


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
    p = FitProblem.build(model, intensity, light, config, unreliable)
    n = mean_init(model.mean_normals, p.intensity, p.light, p.dark) if initial is None \
        else np.asarray(initial, np.float64)
    st = FitState(normals=n, model_normals=n, v_fit=p.vbar, weights=np.ones(model.n_pixels),
                  released=p.known_bad.copy(), intensity=p.intensity, newton=config.solver == "gauss-newton",
                  omega=config.relaxation if config.solver == "irls" else 1.0,
                  tolerance=config.stop_tolerance_deg, albedo_rounds=config.albedo_rounds)
    step = STEPS[config.solver]
    history: list[dict[str, float]] = []
    converged = False
    it = 0
    for it in range(1, config.max_iterations + 1):
        step(p, st, model.project(st.normals), it)
        record = _onto_cones(p, st, it)
        record.albedo_round, st.albedo_measured = st.albedo_measured, False
        history.append({"iteration": it, **record.scalars()})
        if on_iteration is not None:
            on_iteration(record)
        st.normals = record.normals
        if record.change_deg < st.tolerance and st.albedo_rounds > 0:
            st.albedo_rounds -= 1
            st.albedo_measured = True
            st.intensity = _without_smooth_albedo(p, st)
            st.normals = irradiance_constraint(st.model_normals, p.light, st.intensity, p.dark,
                                               fallback=model.mean_normals)
            continue
        if record.change_deg < st.tolerance:
            converged = True
            break
    return FitResult(st.normals, st.model_normals, st.weights, st.residuals, st.b, st.sigma, it, converged, history)


def _onto_cones(p: FitProblem, st: FitState, it: int) -> FitIteration:
    """The model normals of the step just taken, rotated onto their cones (released pixels keep
    the model's, weight 0); cast shadows re-traced every ``cast_every`` iterations."""
    cfg, model = p.config, p.model
    st.model_normals = model.unproject(st.v_fit)
    n_new = irradiance_constraint(st.model_normals, p.light, st.intensity, p.dark, fallback=model.mean_normals)
    if cfg.release_cast and p.dark is not None and it % cfg.cast_every == 0:
        st.released = p.known_bad | _cast_by_shape(model, st.model_normals, p.light, p.dark)
    if st.released.any():
        n_new[st.released] = st.model_normals[st.released]
        st.weights = np.where(st.released, 0.0, st.weights)
    change = float(np.mean(angle_deg(st.normals, n_new)))
    return FitIteration(it, n_new, st.model_normals, st.weights, st.residuals, st.sigma, st.b, change)


def _without_smooth_albedo(p: FitProblem, st: FitState) -> np.ndarray:
    """The image (N,) divided by the smooth albedo the fitted shape implies, measured where the
    fit trusts the pixel and the shading is strong enough to divide by."""
    shading = st.model_normals @ p.light
    trusted = (st.weights >= ALBEDO_MIN_WEIGHT) & ~st.released & (shading >= MIN_SHADING)
    if p.dark is not None:
        trusted &= ~p.dark
    iod = p.model.iod
    albedo = smooth_albedo(p.model.mask, p.intensity, shading, trusted, p.config.albedo_sigma * iod)
    return np.clip(p.intensity / albedo, 0.0, 1.0)


def _cast_by_shape(model: ShapeModel, normals: np.ndarray, light: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """(N,) bool: which of the ``sources`` (N,) bool model pixels lie in the cast shadow of the
    surface integrated from ``normals`` (N, 3); rays are traced from those pixels only."""
    if not sources.any():
        return sources.copy()
    depth = masked_least_squares(model.to_image(normals.astype(np.float32)), model.mask)
    return cast_shadow(depth, light, sources=model.to_image(sources, fill=False).astype(bool))[model.mask]
