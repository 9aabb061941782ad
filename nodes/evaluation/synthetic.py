"""Accuracy harness: render held-out faces with cast shadows, run the method, measure.

Faces are rendered on the model's own grid (so alignment is the identity), Lambertian with
cast and attached shadows, light in the x-z plane at the given angles from the view axis
(from the image's left), constant or procedural albedo. Everything the method computes comes
from the same nodes ``shadowflow run`` uses.
"""
from __future__ import annotations

import time
import uuid

import numpy as np

from ...flow.chain import Chain
from ...flow.distributed import local_map
from ...flow.frame import Frame
from ..geometry.integrate import fill_holes
from ..geometry.normals import angle_deg, normals_from_depth
from ..geometry.reflectance import light_from_angles
from ..method.nodes import method_nodes, on_model_grid
from ..method.options import MethodOptions
from ..model.shape_model import ShapeModel
from .scenes import Scene, render_scene


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else float("nan")


def score(scene: Scene, frame: Frame) -> dict[str, float]:
    """Metrics of one result against its scene (angles in degrees, depth in pixels)."""
    v = scene.valid
    err = angle_deg(np.nan_to_num(frame.data["normals"]), np.nan_to_num(scene.normals))
    sh_true, sh_est = scene.shadows, frame.data["shadow"]
    dz = (frame.data["depth"] - scene.depth)[v]
    dz = dz - np.mean(dz)
    out = {
        "err_all": float(np.mean(err[v])),
        "err_lit": float(np.mean(err[v & sh_true.lit])) if np.any(v & sh_true.lit) else float("nan"),
        "err_cast": float(np.mean(err[v & sh_true.cast])) if np.any(v & sh_true.cast) else float("nan"),
        "err_attached": float(np.mean(err[v & sh_true.attached])) if np.any(v & sh_true.attached) else float("nan"),
        "cast_iou": _iou(sh_true.cast & v, sh_est.cast & v),
        "shadow_iou": _iou(~sh_true.lit & v, ~sh_est.lit & v),
        "depth_rmse": float(np.sqrt(np.mean(dz**2))),
        "iterations": float(frame.meta["iterations"]),
        "converged": float(frame.meta["converged"]),
    }
    return out


_CHAINS: dict[str, Chain] = {}  # per process: evaluation token -> the method's chain


def score_one(shared: tuple[str, ShapeModel, MethodOptions], item: tuple[int, float, np.ndarray, object]) -> dict:
    """One test face at one light: render, run the method's nodes, score (``score``) and time it.
    shared: (a token naming this evaluation, model, options); item: (face index, angle in degrees,
    depth (H, W), albedo (H, W) or 1.0). A task of ``evaluate``, locally or on a Dask worker (the
    chain is built once per token there)."""
    token, model, options = shared
    chain = _CHAINS.get(token)
    if chain is None:
        _CHAINS.clear()
        chain = _CHAINS[token] = Chain(method_nodes(options, with_views=False))
    i, angle, depth, albedo = item
    s = light_from_angles(angle, 0.0)
    t0 = time.perf_counter()
    scene = render_scene(depth, albedo, s, model.mask)
    frame = chain.process(on_model_grid(i, f"test-{i}@{angle:g}deg", scene.image, s, model))
    if not frame.ok:
        raise RuntimeError(frame.status)
    return {**score(scene, frame), "seconds": time.perf_counter() - t0}


def evaluate(
    model: ShapeModel,
    depths: np.ndarray,
    albedos: np.ndarray | None,
    angles_deg: list[float],
    options: MethodOptions = MethodOptions(),
    mapper=local_map,
) -> dict:
    """Run the method on every test face at every light angle; mean metrics per angle.

    depths: (M, H, W) test heights on the model grid; albedos: (M, H, W) or None (constant 1).
    mapper: how the (face, angle) items are run: ``local_map`` here, or ``ordered_map`` bound to
    a Dask client (``eval --dask``); the results are the same. Returns ``{"per_angle": {angle:
    {metric: mean}}, "faces": M}``; NaN metrics (e.g. no cast shadow at 0 degrees) are left out
    of the means; ``seconds_per_face`` is the mean time of one face's task.
    """
    items = [(i, float(angle), d, 1.0 if albedos is None else albedos[i])
             for angle in angles_deg for i, d in enumerate(depths)]
    results = list(mapper(score_one, items, (uuid.uuid4().hex, model, options)))
    per_angle = {}
    for angle in angles_deg:
        rows = [r for (_, a, _, _), r in zip(items, results) if a == float(angle)]
        seconds = float(np.mean([r.pop("seconds") for r in rows])) if rows else 0.0
        means = {k: float(np.nanmean([r[k] for r in rows])) if np.any(np.isfinite([r[k] for r in rows]))
                 else float("nan") for k in rows[0]}
        means["seconds_per_face"] = seconds
        per_angle[f"{angle:g}"] = means
    return {"per_angle": per_angle, "faces": int(len(depths))}


def model_floor(model: ShapeModel, depths: np.ndarray) -> float:
    """Mean angle (degrees) between true normals and their least-squares projection on the
    model: the best any fit with this model can do."""
    errs = []
    for d in depths:
        n = normals_from_depth(fill_holes(d, model.mask))[model.mask].astype(np.float64)
        ok = np.all(np.isfinite(n), axis=1)
        fit_n = model.closest_normals(np.where(ok[:, None], n, model.mean_normals), ok)
        errs.append(np.mean(angle_deg(fit_n[ok], n[ok])))
    return float(np.mean(errs))


# the table's columns, per fit and light angle (``evaluate``'s ``per_angle`` rows)
TABLE_COLUMNS = ("err_all", "err_lit", "err_cast", "err_attached", "cast_iou", "shadow_iou", "depth_rmse",
                 "iterations", "seconds_per_face")


def table_header() -> str:
    return f"{'fit':12} {'angle':>5} " + " ".join(f"{c:>12}" for c in TABLE_COLUMNS)


def table_row(fit: str, angle, row: dict) -> str:
    """One line of the table: a fit at one light angle (degrees)."""
    return f"{fit:12} {angle:>5} " + " ".join(f"{row[c]:12.3f}" for c in TABLE_COLUMNS)
