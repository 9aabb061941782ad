"""Streaming throughput and peak memory for N frames (default 100 and 1000).

    python benchmarks/bench_stream.py --frames 100 1000 [--record mcap] [--workers 1 2]

Each count runs ``shadowflow run`` in a fresh process over a folder of N synthetic 128x128
shadowed faces (copies of 10 distinct ones), full fits, and reports frames/s and the child's
peak RSS (does memory grow with the stream?), for each fit worker count. Not part of the tests.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def make_inputs(folder: Path, n: int, grid: tuple[int, int] = (128, 128)) -> None:
    """``n`` inputs of ``grid`` pixels: copies of 10 distinct shadowed faces (lights 30..66 degrees)."""
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    rng = np.random.default_rng(5)
    base = [write_shadowed_face(folder / f"base-{i}.png", rng, light_from_angles(30 + 4 * i), grid) for i in range(10)]
    for k in range(n):
        src = base[k % 10]
        shutil.copy(src, folder / f"f{k:05d}.png")
        shutil.copy(src.with_suffix(".json"), folder / f"f{k:05d}.json")
    for src in base:
        src.unlink()
        src.with_suffix(".json").unlink()


_PEAK_OF_CHILD = ("import resource, subprocess, sys; rc = subprocess.run(sys.argv[1:]).returncode; "
                  "print(rc, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")


def run(n: int, record: str, workers: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "in"
        src.mkdir()
        make_inputs(src, n)
        cmd = [sys.executable, "-m", "shadowflow.nodes.app.cli", "run", str(src), "--out", str(Path(tmp) / "out"),
               "--quiet", "--record", record, "--workers", str(workers)]
        t0 = time.perf_counter()
        # through a fresh parent: RUSAGE_CHILDREN keeps the largest child ever waited for, so a
        # second run measured from this process would report the first one's peak
        proc = subprocess.run([sys.executable, "-c", _PEAK_OF_CHILD, *cmd], capture_output=True, text=True)
        secs = time.perf_counter() - t0
        peak = int(proc.stdout.split()[-1])
        rec_bytes = sum(f.stat().st_size for f in (Path(tmp) / "out").glob("run.*"))
        shutil.rmtree(src)
    return {"frames": n, "record": record, "workers": workers, "exit": int(proc.stdout.split()[-2]), "seconds": round(secs, 1),
            "frames_per_s": round(n / secs, 2), "peak_rss_mib": round(peak / 1024, 1),
            "recording_mib": round(rec_bytes / 2**20, 1)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, nargs="+", default=[100, 1000])
    ap.add_argument("--record", default="mcap")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--json")
    args = ap.parse_args()
    rows = []
    print("| frames | record | fit workers | s | frames/s | peak RSS (MiB) | recordings (MiB) |\n|---|---|---|---|---|---|---|")
    for w in args.workers:
        for n in args.frames:
            r = run(n, args.record, w)
            rows.append(r)
            print(f"| {r['frames']} | {r['record']} | {w} | {r['seconds']} | {r['frames_per_s']} | "
                  f"{r['peak_rss_mib']} | {r['recording_mib']} |", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
