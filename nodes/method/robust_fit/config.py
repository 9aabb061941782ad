"""``FitConfig``: every option of the robust fit, checked where it is built, and the fit's
named constants."""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

from ..remap import SATURATION

SOLVERS = ("gauss-newton", "irls", "paper")

# Stopping rules (mean normal change per iteration, degrees), when ``FitConfig.tolerance_deg`` is None:
# Gauss-Newton's last steps shrink by 0.8-0.9 each (the Huber weights and cast shadows move under them), but
# stopping at 0.1 rather than 0.05 moves every measured error by 0.02 degrees at most and takes a fifth fewer
# iterations (docs/tuning.md, "The fit"); the alternation creeps and needs 0.01.
NEWTON_TOLERANCE_DEG = 0.1
ALTERNATION_TOLERANCE_DEG = 0.01

# A step is judged to have overshot when the residual scale grows by more than this factor in one
# iteration: Gauss-Newton then falls back to the alternation, and over-relaxed IRLS to plain steps.
OVERSHOOT_FACTOR = 1.5
# ... but not in the first iterations, while the weights settle from their unit start: Gauss-Newton's
# residual scale may grow up to iteration 3 (its first steps move the shape most), the relaxed
# alternation's up to iteration 2.
NEWTON_WARMUP = 3
RELAXATION_WARMUP = 2

# The smooth-albedo round (``albedo_rounds``): the albedo is measured where the fit trusts the pixel
# (Huber weight at least this) and the model's shading is strong enough to divide by (``albedo.MIN_SHADING``).
ALBEDO_MIN_WEIGHT = 0.5

# Floors that keep a division or a direction defined.
MIN_SIGMA = 1e-9  # residual scale (radians) under the Huber threshold
MIN_CONE_DISTANCE = 1e-6  # AEP round-off: a model normal this close to its cone has no residual direction
MIN_EIGENVALUE = 1e-12  # under the prior's 1 / eigenvalue


# the command line's flags of the options it sets, named with them in what a bad value raises
FLAGS = {"solver": "--fit", "max_iterations": "--max-iterations", "albedo_rounds": "--albedo-rounds",
         "n_modes": "--modes", "cone_trust": "--cone-trust"}


def _named(name: str) -> str:
    """``FitConfig.<name>``, with its command-line flag when it has one."""
    return f"FitConfig.{name} ({FLAGS[name]})" if name in FLAGS else f"FitConfig.{name}"


def _one_of(name: str, value, allowed) -> None:
    if value not in allowed:
        raise ValueError(f"{_named(name)} must be one of {', '.join(allowed)}, not {value!r}")


def _at_least(name: str, value, low: int) -> None:
    if not isinstance(value, int) or isinstance(value, bool) or value < low:
        raise ValueError(f"{_named(name)} must be an integer of at least {low}, not {value!r}")


@dataclass(frozen=True)
class FitConfig:
    """Options of the robust fit; ``FitConfig.paper()`` is the paper's variant throughout."""

    solver: Literal["gauss-newton", "irls", "paper"] = "gauss-newton"  # see the module docstring
    scale: Literal["rayleigh", "mad"] = "rayleigh"
    # Huber threshold in units of sigma: 1.0 is chosen for real photos, at a small cost on clean renders
    # (docs/tuning.md, "The fit")
    huber_k: float = 1.0
    init: Literal["mean", "gradient"] = "mean"
    attached_shadow: bool = True  # I <= dark_threshold: n.s <= 0 instead of the 90-degree cone
    dark_threshold: float = 0.02
    release_cast: bool = True  # dark pixels the current shape casts a shadow on: no constraint
    cast_every: int = 5  # re-trace cast shadows every this many iterations
    prior: float = 0.0  # weight of the Gaussian prior b_k^2 / eigenvalue_k (0: none)
    # weight of the same prior in units of the current residual variance sigma^2 (MAP with
    # correlated residuals): strong when the image fits badly (real skin), nil on clean input
    # 200 with the ICT model (100 was the procedural model's choice; docs/tuning.md, "The fit")
    adaptive_prior: float = 200.0
    # irls: over-relaxation of the coefficients, b <- b_prev + omega (b - b_prev): the loop creeps toward
    # its fixed point; over-relaxing reaches it in fewer iterations (docs/tuning.md, "The fit"; too much
    # diverges, so a residual scale that jumps switches it off for the rest of the fit)
    relaxation: float = 1.8
    damping: float = 1e-3  # gauss-newton: Levenberg term added to the K x K system (modes are orthonormal)
    max_iterations: int = 100
    # stop when the mean normal change falls below this (degrees). None: 0.1 for gauss-newton (0.05 gives
    # the same errors to 0.02 degrees in a quarter more iterations); 0.01 for the alternation, which creeps
    # (docs/tuning.md, "The fit")
    tolerance_deg: float | None = None
    n_modes: int | None = None  # use the model's first K modes (None: all)
    saturation: float = SATURATION  # input brightness at or above this is clipped (255 of 8 bits): no constraint (> 1: off)
    # real skin: when the fit has converged, divide the image by the smooth albedo its shape implies
    # (method.albedo.smooth_albedo) and fit on, this many times (0: one albedo everywhere, the paper)
    # (on by default: it takes real photos' normals closer to the truth, docs/tuning.md, "The fit")
    albedo_rounds: int = 1
    albedo_sigma: float = 0.08  # that albedo's smoothing, in interocular distances (2.9 px at 128^2)
    # output blend normalize(c w n'' + (1 - c w) n') (``combine``): how far the on-cone normals are trusted
    # where the weights trust their pixel; 1 is the paper's blend. On photos the cones carry the skin's albedo
    # errors, so the shape trusts them less; the albedo and the relighting keep the paper's blend, which
    # explains the photo's shading (docs/tuning.md, "The fit")
    cone_trust: float = 0.5

    def __post_init__(self) -> None:
        """Every option checked here, where the configuration is built (``ValueError`` naming it)."""
        _one_of("solver", self.solver, SOLVERS)
        _one_of("scale", self.scale, ("rayleigh", "mad"))
        _one_of("init", self.init, ("mean", "gradient"))
        _at_least("max_iterations", self.max_iterations, 1)
        _at_least("cast_every", self.cast_every, 1)
        _at_least("albedo_rounds", self.albedo_rounds, 0)
        if self.n_modes is not None:
            _at_least("n_modes", self.n_modes, 1)
        for name in ("huber_k", "albedo_sigma"):
            if not getattr(self, name) > 0:
                raise ValueError(f"FitConfig.{name} must be positive, not {getattr(self, name)}")
        for name in ("prior", "adaptive_prior", "damping", "dark_threshold"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"FitConfig.{name} must be 0 or more, not {getattr(self, name)}")
        if not 0.0 < self.relaxation < 2.0:
            raise ValueError(f"FitConfig.relaxation must be in (0, 2) (over-relaxation diverges at 2), "
                             f"not {self.relaxation}")
        if not 0.0 <= self.cone_trust <= 1.0:
            raise ValueError(f"{_named('cone_trust')} is a fraction in [0, 1], not {self.cone_trust}")
        if self.tolerance_deg is not None and not self.tolerance_deg >= 0:  # 0: always max_iterations
            raise ValueError(f"FitConfig.tolerance_deg must be 0 or more, not {self.tolerance_deg}")

    @property
    def stop_tolerance_deg(self) -> float:
        """The stopping rule in use: ``tolerance_deg`` if given, else the solver's own."""
        if self.tolerance_deg is not None:
            return self.tolerance_deg
        return NEWTON_TOLERANCE_DEG if self.solver == "gauss-newton" else ALTERNATION_TOLERANCE_DEG

    @staticmethod
    def paper(**overrides) -> "FitConfig":
        """The paper's choices: one-step formula, MAD scale, gradient start, 90-degree cone,
        saturated pixels kept, no prior."""
        base = FitConfig(solver="paper", scale="mad", huber_k=1.0, init="gradient", attached_shadow=False,
                         release_cast=False, saturation=2.0, adaptive_prior=0.0, relaxation=1.0, albedo_rounds=0,
                         cone_trust=1.0)
        return replace(base, **overrides)
