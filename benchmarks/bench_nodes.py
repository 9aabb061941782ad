"""Per-node timings of the method on the model grid (medians over repeated frames).

Usage: python benchmarks/bench_nodes.py [--repeats 5] [--angle 45] [--json out.json]
Reports seconds per node and per iteration; not part of the tests (no pass/fail thresholds).
"""
from __future__ import annotations

import argparse
import json
import platform
import statistics

from shadowflow.flow import Chain
from shadowflow.nodes.evaluation.scenes import render_scene
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.method.nodes import on_model_grid
from shadowflow.nodes.method.options import MethodOptions
from shadowflow.nodes.relight.nodes import face_nodes
from shadowflow.nodes.model.default_model import default_model
from shadowflow.nodes.model.sources import procedural


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--angle", type=float, default=45.0)
    ap.add_argument("--json")
    args = ap.parse_args()
    model = default_model()
    chain = Chain(face_nodes(MethodOptions()))
    s = light_from_angles(args.angle)
    depths, albedos = procedural(args.repeats, seed=99)
    rows = []
    for d, a in zip(depths, albedos):
        sc = render_scene(d, a, s, model.mask)
        f = chain.process(on_model_grid(0, "bench", sc.image, s, model))
        t = dict(f.meta["timings"])
        t["per_iteration"] = t["robust_fit"] / f.meta["iterations"]
        t["iterations"] = f.meta["iterations"]
        rows.append(t)
    med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
    total = sum(v for k, v in med.items() if k not in ("per_iteration", "iterations"))
    print(f"machine: {platform.machine()} {platform.processor() or ''}, python {platform.python_version()}, "
          f"grid {model.grid}, K={model.n_modes}, light {args.angle:g} deg, {args.repeats} frames (medians)")
    print("| node | ms |\n|---|---|")
    for k, v in med.items():
        if k != "iterations":
            print(f"| {k} | {1000 * v:.1f} |")
    print(f"| whole chain | {1000 * total:.1f} |\n\niterations (median): {med['iterations']:.0f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"medians_s": med, "chain_s": total, "grid": list(model.grid)}, fh, indent=2)


if __name__ == "__main__":
    main()
