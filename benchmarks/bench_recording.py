"""Recording overhead per frame: off / mcap / rerun / both, the thinning options, and both on the
recorder's thread instead of a recording process, per model grid and mode count.

    python benchmarks/bench_recording.py [--grids 64 128 256] [--modes 30 60] [--frames 48]
                                         [--repeats 5] [--out benchmarks/results]

Per frame: the marginal wall time of ``run_stream`` (the whole chain and the recording drained to
disk), from runs of ``--frames`` and of a quarter as many, ``(t_long - t_short) / (frames -
frames // 4)``, the median of ``--repeats``, and its ratio to recording off. Per run: the fixed
cost (opening the files, starting the recording process, the report's plot), ``t_long - frames *
per_frame``, in seconds beyond the unrecorded run's. And the bytes written per frame. With no
``--grids``/``--modes`` it uses the shipped default model (128x128, K=60); otherwise a model
trained on 60 procedural faces per grid, truncated to each K, as in ``bench_speed.py``. Run it
pinned (``taskset -c 0``) for the one-core figures. Not part of the tests.
"""
from __future__ import annotations

import argparse
import json
import platform
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_stream import make_inputs  # noqa: E402
from shadowflow.flow.recording import RecordOptions  # noqa: E402
from shadowflow.nodes.app.runner import RunOptions, run_stream  # noqa: E402
from shadowflow.nodes.method.options import MethodOptions  # noqa: E402

CASES = [
    ("off", (), RecordOptions()),
    ("mcap", ("mcap",), RecordOptions()),
    ("rerun", ("rerun",), RecordOptions()),
    ("both", ("rerun", "mcap"), RecordOptions()),
    ("both, recorder thread", ("rerun", "mcap"), RecordOptions(own_process=False)),
    ("both, float16", ("rerun", "mcap"), RecordOptions(float16=True)),
    ("both, every 5th", ("rerun", "mcap"), RecordOptions(every=5)),
]


def models(grids: list[int] | None, ks: list[int] | None):
    """(grid, K, model) to measure: the default model, or procedural ones per grid and K."""
    if not grids and not ks:
        from shadowflow.nodes.model.default_model import default_model

        m = default_model()
        yield m.grid[0], m.n_modes, m
        return
    from shadowflow.nodes.model.shape_model import train_shape_model
    from shadowflow.nodes.model.sources import procedural

    for g in grids or [128]:
        depths, _ = procedural(60, seed=0, grid=(g, g))
        full = train_shape_model(depths, max(ks or [60]), source="procedural")
        for k in ks or [60]:
            yield g, k, full.truncated(k)


def measure(model, grid: int, frames: int, repeats: int, tmp: Path) -> list[dict]:
    src = tmp / f"in-{grid}"
    if not src.exists():
        src.mkdir()
        make_inputs(src, frames, (grid, grid))
    paths = sorted(str(p) for p in src.glob("*.png"))
    # untimed: per-mask caches (integration operator, meshes) and the Rerun import are one-off
    run_stream(paths[:2], tmp / f"warm-{grid}-{model.n_modes}", model, MethodOptions(),
               RunOptions(record=("rerun", "mcap"), quiet=True))
    # the cases take turns within each repeat: this shared machine's speed drifts by tens of percent
    # over minutes, and running every repeat of one case before the next put that drift in the ratios
    short = max(1, frames // 4)
    per_frame: dict[str, list[float]] = {name: [] for name, _, _ in CASES}
    fixed: dict[str, list[float]] = {name: [] for name, _, _ in CASES}
    size: dict[str, float] = {}
    for r in range(repeats):
        for name, record, ropt in CASES:
            t = {}
            for n in (short, frames):
                out = tmp / f"out-{grid}-{model.n_modes}-{name}-{r}-{n}".replace(" ", "").replace(",", "")
                t0 = time.perf_counter()
                run_stream(paths[:n], out, model, MethodOptions(),
                           RunOptions(record=record, record_options=ropt, quiet=True))
                t[n] = time.perf_counter() - t0
                if n == frames:
                    size[name] = sum(f.stat().st_size for f in out.glob("run.*")) / frames
                shutil.rmtree(out, ignore_errors=True)
            per_frame[name].append((t[frames] - t[short]) / (frames - short))
            fixed[name].append(t[frames] - frames * per_frame[name][-1])
    rows = []
    base, base_fixed = statistics.median(per_frame["off"]), statistics.median(fixed["off"])
    for name, _, _ in CASES:
        med, extra = statistics.median(per_frame[name]), statistics.median(fixed[name]) - base_fixed
        rows.append({"grid": grid, "K": model.n_modes, "recording": name, "ms_per_frame": round(1000 * med, 1),
                     "ratio_to_off": round(med / base, 3), "fixed_s": round(extra, 2),
                     "mib_per_frame": round(size[name] / 2**20, 3)})
        print(_row(rows[-1]), flush=True)
    return rows


def _row(r: dict) -> str:
    return (f"| {r['grid']} | {r['K']} | {r['recording']} | {r['ms_per_frame']:.0f} | {r['ratio_to_off']:.2f} | "
            f"{r['fixed_s']:+.2f} | {r['mib_per_frame']:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--grids", type=int, nargs="*")
    ap.add_argument("--modes", type=int, nargs="*")
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", help="folder for recording.json and recording.md")
    args = ap.parse_args()
    head = (f"Machine: {platform.machine()}, {platform.python_version()}; {args.frames} frames per run, "
            f"median of {args.repeats} runs; 'x off' is the ratio to the same chain with recording off; "
            f"'fixed s' is the run's fixed cost beyond the unrecorded run's.")
    print(head)
    table = ["| grid | K | recording | ms / frame | x off | fixed s | MiB / frame |", "|---|---|---|---|---|---|---|"]
    print("\n".join(table), flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for grid, k, model in models(args.grids, args.modes):
            rows.extend(measure(model, grid, args.frames, args.repeats, Path(tmp)))
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "recording.json").write_text(json.dumps({"machine": head, "rows": rows}, indent=1))
        lines = [_row(r) for r in rows]
        (out / "recording.md").write_text(head + "\n\n" + "\n".join(table + lines) + "\n")


if __name__ == "__main__":
    main()
