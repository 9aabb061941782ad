"""Speed of the method per frame across model grids and mode counts, against its floor and a
naive reference. Not part of the tests (no pass/fail thresholds).

Usage (from the repository root; one core, as the issue asks):
    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/bench_speed.py --out benchmarks/results

For each grid (64, 128, 256) and K (30, 60): a model trained on 60 faces of ``--source`` (``ict``,
the default model's source, or ``procedural``), ``--frames`` held-out faces lit from 45 degrees;
medians of each node's time, the iterations, the time per
iteration, and the FLOOR per iteration measured in the same run on the same shapes: the
weighted K x K Gram matrix, two matrix-vector products with the (2N, K) modes and a K x K
solve, float64 (the linear algebra one IRLS step cannot avoid). The naive reference
(``naive_fit.py``, pixel loops) runs on the first frame where ``--naive-max-grid`` allows.
Writes ``speed.json`` and ``speed.md``; the scaling exponent is the slope of log(time) on
log(pixels) across grids.
"""
from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from naive_fit import naive_fit  # noqa: E402
from shadowflow.flow import Chain  # noqa: E402
from shadowflow.nodes.evaluation.scenes import render_scene  # noqa: E402
from shadowflow.nodes.geometry.normals import angle_deg  # noqa: E402
from shadowflow.nodes.geometry.reflectance import light_from_angles  # noqa: E402
from shadowflow.nodes.method.nodes import on_model_grid
from shadowflow.nodes.method.options import MethodOptions
from shadowflow.nodes.relight.nodes import face_nodes  # noqa: E402
from shadowflow.nodes.method.robust_fit import FitConfig, fit  # noqa: E402
from shadowflow.nodes.model.shape_model import train_shape_model  # noqa: E402
from shadowflow.nodes.model.sources import load_source  # noqa: E402


def floor_per_iteration(modes: np.ndarray, repeats: int = 30) -> float:
    """Median seconds of the unavoidable IRLS linear algebra on (2N, K) modes."""
    rng = np.random.default_rng(0)
    w, r = rng.random(modes.shape[0]), rng.standard_normal(modes.shape[0])
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        gram = modes.T @ (modes * w[:, None])
        b = np.linalg.solve(gram, modes.T @ (w * r))
        _ = modes @ b
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def run(grid: int, ks: list[int], frames: int, repeats: int, naive_max_grid: int, source: str = "ict") -> list[dict]:
    depths, _ = load_source(source, 60, 0, (grid, grid))
    full = train_shape_model(depths, max(ks), source=source)
    tests, albedos = load_source(source, frames, 99, (grid, grid))
    s = light_from_angles(45.0)
    rows = []
    for k in ks:
        model = full.truncated(k)
        chain = Chain(face_nodes(MethodOptions()))
        timings, errors = [], []
        for d in tests:
            sc = render_scene(d, 1.0, s, model.mask)
            runs = []
            for _ in range(repeats):  # the same frame again: the median of its repeats
                f = chain.process(on_model_grid(0, "bench", sc.image, s, model))
                runs.append(dict(f.meta["timings"]))
            t = {key: statistics.median(r[key] for r in runs) for key in runs[0]}
            t["iterations"] = f.meta["iterations"]
            timings.append(t)
            ok = np.isfinite(f.data["normals"][..., 0]) & sc.valid
            errors.append(float(np.mean(angle_deg(f.data["normals"][ok], sc.normals[ok]))))
        med = {key: statistics.median(t[key] for t in timings) for key in timings[0]}
        nodes_s = {key: v for key, v in med.items() if key != "iterations"}
        fit_s = statistics.median(t["robust_fit"] / t["iterations"] for t in timings)
        floor_s = floor_per_iteration(model.modes_as(np.float64))
        row = {"grid": grid, "K": k, "pixels": model.n_pixels, "nodes_ms": {n: 1000 * v for n, v in nodes_s.items()},
               "chain_ms": 1000 * sum(nodes_s.values()), "iterations": med["iterations"],
               "per_iteration_ms": 1000 * fit_s, "floor_ms": 1000 * floor_s, "ratio_to_floor": fit_s / floor_s,
               "err_deg": statistics.median(errors)}
        if grid <= naive_max_grid:
            row.update(naive_comparison(model, tests[0], s, repeats))
        rows.append(row)
        print(json.dumps({k2: (round(v, 3) if isinstance(v, float) else v) for k2, v in row.items() if k2 != "nodes_ms"}),
              flush=True)
    return rows


def naive_comparison(model, depth: np.ndarray, light: np.ndarray, repeats: int) -> dict:
    """The naive transcription against ``fit`` with the same settings (no misfit-scaled prior, no
    in-loop cast release) on one frame: whole-fit times, iterations and errors (degrees, fitted
    model normals on the face). ``irls`` is the same alternation as the naive code, so the same
    answer; ``gauss-newton`` is the default solver, whose fixed point is the same."""
    sc = render_scene(depth, 1.0, light, model.mask)
    I, truth = sc.image[model.mask], sc.normals[model.mask]
    ok = np.all(np.isfinite(truth), axis=1)
    t0 = time.perf_counter()
    n_naive, its = naive_fit(model.mean_normals, model.mean_proj, model.modes_as(np.float64), I, light)
    naive_s = time.perf_counter() - t0
    out = {"naive_ms": 1000 * naive_s, "naive_iterations": its, "naive_per_iteration_ms": 1000 * naive_s / its,
           "naive_err_deg": float(np.mean(angle_deg(n_naive[ok], truth[ok])))}
    for solver in ("irls", "gauss-newton"):
        cfg = FitConfig(solver=solver, adaptive_prior=0.0, release_cast=False, relaxation=1.0)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            r = fit(model, I, light, cfg)
            times.append(time.perf_counter() - t0)
        fit_s = statistics.median(times)
        out[solver] = {"ms": 1000 * fit_s, "iterations": r.iterations,
                       "err_deg": float(np.mean(angle_deg(r.normals[ok], truth[ok]))),
                       "speedup": naive_s / fit_s, "speedup_per_iteration": (naive_s / its) / (fit_s / r.iterations)}
    return out


def markdown(rows: list[dict], exponent: dict[int, float]) -> str:
    out = ["| grid | K | pixels | chain ms | fit ms | iterations | ms / iteration | floor ms | × floor | error ° |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['grid']} | {r['K']} | {r['pixels']} | {r['chain_ms']:.0f} | {r['nodes_ms']['robust_fit']:.0f} | "
                   f"{r['iterations']:.0f} | {r['per_iteration_ms']:.2f} | {r['floor_ms']:.2f} | {r['ratio_to_floor']:.2f} | "
                   f"{r['err_deg']:.2f} |")
    out.append("")
    out.append("Scaling of the time per iteration with pixels (64 -> 256): " +
               ", ".join(f"K={k}: exponent {e:.2f}" for k, e in exponent.items()))
    naive = [r for r in rows if "naive_ms" in r]
    if naive:
        out += ["", "Against the naive transcription (`naive_fit.py`), one frame, the same settings (no misfit-scaled "
                "prior, no in-loop cast release): whole fit", "",
                "| grid | K | fit | ms | iterations | error ° | speed-up |", "|---|---|---|---|---|---|---|"]
        for r in naive:
            out.append(f"| {r['grid']} | {r['K']} | naive | {r['naive_ms']:.0f} | {r['naive_iterations']} | "
                       f"{r['naive_err_deg']:.3f} | 1 |")
            for solver in ("irls", "gauss-newton"):
                x = r[solver]
                out.append(f"| {r['grid']} | {r['K']} | {solver} | {x['ms']:.1f} | {x['iterations']} | {x['err_deg']:.3f} | "
                           f"{x['speedup']:.0f}× |")
    return "\n".join(out) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--grids", default="64,128,256")
    ap.add_argument("--modes", default="30,60")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--naive-max-grid", type=int, default=64)
    ap.add_argument("--out", default="benchmarks/results")
    ap.add_argument("--source", default="ict", help="training and test faces: ict (the default model's) or procedural")
    args = ap.parse_args()
    ks = [int(k) for k in args.modes.split(",")]
    rows = []
    for g in (int(x) for x in args.grids.split(",")):
        rows.extend(run(g, ks, args.frames, args.repeats, args.naive_max_grid, args.source))
    exponent = {}
    for k in ks:
        rs = [r for r in rows if r["K"] == k]
        if len(rs) >= 2:
            exponent[k] = float(np.polyfit(np.log([r["pixels"] for r in rs]), np.log([r["per_iteration_ms"] for r in rs]), 1)[0])
    machine = f"{platform.machine()}, {platform.python_version()}, numpy {np.__version__}"
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "speed.json").write_text(json.dumps({"machine": machine, "rows": rows, "exponent": exponent}, indent=2) + "\n")
    md = (f"Machine: {machine}; {args.source} faces; medians over {args.frames} frames lit from 45° of {args.repeats} "
          "runs each.\n\n") + markdown(rows, exponent)
    (out / "speed.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
