"""A turned face against a frontal one: ``shadowflow.fit`` on the same ICT identity rendered frontal and turned
(``nodes/evaluation/turned.py``), medians over repeats, after the models are built and cached.

Usage: taskset -c 0 python benchmarks/bench_turned.py [--repeats 7] [--yaw 25]
Reports seconds per photo and the turned/frontal ratio; not part of the tests (no pass/fail thresholds).
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import shadowflow
from shadowflow.nodes.evaluation.turned import render_turned
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.model.default_model import default_model
from shadowflow.nodes.model.faces.ict import shipped_basis


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--yaw", type=float, default=25.0)
    args = ap.parse_args()
    basis, model, light = shipped_basis(), default_model(), light_from_angles(45.0, 0.0)
    w = np.random.default_rng(1000).standard_normal(basis.n_identity)
    medians = {}
    for name, view in (("frontal", (0.0, 0.0)), ("turned", (args.yaw, 0.0))):
        photo = render_turned(basis, w, view, light, model).photo
        result = shadowflow.fit(photo, light=light)  # warm: nets loaded, the turned models built
        times = []
        for _ in range(args.repeats):
            t = time.perf_counter()
            shadowflow.fit(photo, light=light)
            times.append(time.perf_counter() - t)
        medians[name] = statistics.median(times)
        print(f"{name:8s} {photo.shape[1]}x{photo.shape[0]}: {medians[name]:.3f} s "
              f"(views tried: {result.frame.meta.get('view_choice', 'frontal only')})")
    print(f"turned / frontal: {medians['turned'] / medians['frontal']:.2f}")


if __name__ == "__main__":
    main()
