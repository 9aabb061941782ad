"""Robust fit of the needle-map model to one image (Smith & Hancock, sections 3-4).

The paper alternates (a) a robust fit of the model to the current on-cone needle-map in AEP
coordinates and (b) rotating the fitted normals back onto their reflectance cones, until the
needle-map stops changing. Its fixed point is where the weighted gradient
``Pᵀ W r - ridge b`` vanishes, ``r`` being each model normal's AEP offset to its cone. Three
solvers (``FitConfig.solver``), one step function each in ``loop``:

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

Modules: ``config`` (options, validated, and the named constants), ``loop`` (state, steps, the
loop), ``linalg`` (the steps' linear algebra), ``robust`` (Huber weights, residual scale),
``start`` (initial normals and the output blend).
"""
from .config import FitConfig
from .loop import FitIteration, FitResult, fit
from .robust import huber_weights, residual_scale
from .start import combine, initial_normals

__all__ = ["FitConfig", "FitIteration", "FitResult", "combine", "fit", "huber_weights", "initial_normals",
           "residual_scale"]
