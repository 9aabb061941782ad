"""The command line's shared arguments: help texts and the checks and conversions several commands use."""
from __future__ import annotations

import argparse
import dataclasses

from ...method.options import FACE_LENGTH, MethodOptions
from ...method.robust_fit import FitConfig
from ...method.robust_fit.config import SOLVERS
from ...model.default_model import resolve_model
from ...model.shape_model import check_grid

FITS = list(SOLVERS)  # the fit's solvers, as FitConfig checks them


MODEL_HELP = ("ict (default: built in, trained from ICT-FaceKit's real-scan identities) | procedural (built in, "
              "the project's anthropometric generator) | a model .npz written by 'shadowflow train'")


ALBEDO_ROUNDS_HELP = ("real skin: after the fit converges, divide out the smooth albedo its shape implies and fit on, "
                      "N times (default 1; 0 is the paper's one albedo everywhere, see README)")


FACE_LENGTH_HELP = ("auto (default): a found face's length (eyes to mouth) from its landmarks; off: the model's; "
                    "a number: stretch the model's face by it")


CONE_TRUST_HELP = ("output normals: blend on-cone and model normals by C x the robust weights (default 0.5; 1: the paper's "
                   "blend; 0: the model's normals; albedo and relighting always use the paper's blend)")


def fit_variant(args: argparse.Namespace, fit: str) -> dict:
    """``--remap`` and ``--albedo-fill`` as given, else as the fit's variant has them (``MethodOptions.paper``
    for ``--fit paper``, the defaults otherwise)."""
    base = MethodOptions.paper() if fit == "paper" else MethodOptions()
    return {"remap": args.remap or base.remap, "albedo_fill": args.albedo_fill or base.albedo_fill}


def fit_config(name: str, modes: int | None, max_iterations: int | None = None,
                albedo_rounds: int | None = None, cone_trust: float | None = None) -> FitConfig:
    """The fit's configuration from the command line's values (None: the variant's own); ``FitConfig`` checks
    each (``ValueError`` naming it and its flag)."""
    cfg = FitConfig.paper() if name == "paper" else FitConfig(solver=name)
    if cone_trust is not None:
        cfg = dataclasses.replace(cfg, cone_trust=cone_trust)
    if albedo_rounds is not None:
        cfg = dataclasses.replace(cfg, albedo_rounds=albedo_rounds)
    if modes is not None:
        cfg = dataclasses.replace(cfg, n_modes=modes)
    if max_iterations is not None:
        cfg = dataclasses.replace(cfg, max_iterations=max_iterations)
    return cfg


def face_length(text: str) -> str | float:
    """``--face-length`` as ``MethodOptions.face_length``: auto, off or a number (its range is the options' rule,
    ``options.FACE_LENGTH``)."""
    if text in ("auto", "off"):
        return text
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"{FACE_LENGTH.flag} {FACE_LENGTH.says}, not {text!r}") from None


def model_arg(spec: str | None):

    return resolve_model(spec)


def grid_size(text: str) -> tuple[int, int]:
    """``--size H,W``: a model grid (``shape_model.check_grid``)."""
    try:
        h, w = (int(t) for t in text.split(","))
    except ValueError:
        raise ValueError(f"--size is H,W, two whole numbers of pixels, not {text!r}") from None
    return check_grid((h, w), "--size")


def at_least(value: int, least: int, flag: str) -> int:
    if value < least:
        raise ValueError(f"{flag} must be {least} or more, not {value}")
    return value
