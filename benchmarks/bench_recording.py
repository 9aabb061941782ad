"""Recording overhead per frame at 128x128: off / mcap / rerun / both, and the thinning options.

    python benchmarks/bench_recording.py [--frames 6] [--repeats 3]

Wall time per frame of ``run_stream`` (including the recorder thread draining to disk), the
median of ``--repeats`` runs, as a ratio to recording off, and the bytes written per frame.
Not part of the tests.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

from flow.recording import RecordOptions
from nodes.default_model import default_model
from nodes.pipeline import MethodOptions
from nodes.runner import RunOptions, run_stream

CASES = [
    ("off", (), RecordOptions()),
    ("mcap", ("mcap",), RecordOptions()),
    ("rerun", ("rerun",), RecordOptions()),
    ("both", ("rerun", "mcap"), RecordOptions()),
    ("both, float16", ("rerun", "mcap"), RecordOptions(float16=True)),
    ("both, every 5th", ("rerun", "mcap"), RecordOptions(every=5)),
]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_stream import make_inputs

    model = default_model()
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "in"
        src.mkdir()
        make_inputs(src, args.frames)
        paths = sorted(str(p) for p in src.glob("*.png"))
        base = None
        print(f"{args.frames} frames, 128x128, K={model.n_modes}, median of {args.repeats} runs")
        print("| recording | ms / frame | x off | MiB / frame |\n|---|---|---|---|")
        for name, record, ropt in CASES:
            times, size = [], 0
            for r in range(args.repeats):
                out = Path(tmp) / f"out-{name}-{r}".replace(" ", "").replace(",", "")
                t0 = time.perf_counter()
                run_stream(paths, out, model, MethodOptions(), RunOptions(record=record, record_options=ropt, quiet=True))
                times.append((time.perf_counter() - t0) / args.frames)
                size = sum(f.stat().st_size for f in out.glob("run.*")) / args.frames
            med = statistics.median(times)
            base = base or med
            print(f"| {name} | {1000 * med:.0f} | {med / base:.2f} | {size / 2**20:.2f} |", flush=True)


if __name__ == "__main__":
    main()
