"""The Dask engine against the local one: frames/s and the client's peak memory.

    python benchmarks/bench_dask.py [--frames 200 2000] [--engines local dask:local:1 dask:local:2]
                                    [--record none mcap,rerun] [--json dask.json]

Each row runs ``shadowflow run`` over N synthetic 128x128 faces (copies of 10,
``bench_stream.make_inputs``) in a fresh process and reports the wall time, frames/s and that
(client) process's peak RSS (VmHWM; the Dask workers are other processes). ``dask:local:N``
starts a LocalCluster of N worker processes inside the run (its start-up is in the time). Linux
only. Not part of the tests.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

from bench_soak import peak_of
from bench_stream import make_inputs


def run(n: int, engine: str, record: str, tmp: Path) -> dict:
    src = tmp / f"in-{n}"
    if not src.exists():
        src.mkdir()
        make_inputs(src, n)
    out = tmp / f"out-{n}-{engine.replace(':', '_')}-{record.replace(',', '_')}"
    cmd = ["run", str(src), "--out", str(out), "--quiet", "--record", record]
    if engine.startswith("dask:"):
        cmd += ["--dask", engine[len("dask:"):]]
    t0 = time.perf_counter()
    code, _, peak = peak_of(cmd)
    seconds = time.perf_counter() - t0
    shutil.rmtree(out, ignore_errors=True)  # 2,000 recorded frames are about 15 GB
    return {"frames": n, "engine": engine, "record": record, "exit": code, "seconds": round(seconds, 1),
            "frames_per_s": round(n / seconds, 2), "client_peak_mib": round(peak, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, nargs="+", default=[200, 2000])
    ap.add_argument("--engines", nargs="+", default=["local", "dask:local:1", "dask:local:2"])
    ap.add_argument("--record", nargs="+", default=["none", "mcap,rerun"])
    ap.add_argument("--json")
    args = ap.parse_args()
    rows = []
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    print("| frames | engine | record | s | frames/s | client peak RSS (MiB) |\n|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.frames:
            for record in args.record:
                for engine in args.engines:
                    r = run(n, engine, record, Path(tmp))
                    rows.append(r)
                    print(f"| {n} | {engine} | {record} | {r['seconds']} | {r['frames_per_s']} | "
                          f"{r['client_peak_mib']} |", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    sys.exit(0)


if __name__ == "__main__":
    main()
