"""Soak: one long run with both recordings; do memory and speed stay flat? Then replay and diff it.

    python benchmarks/bench_soak.py [--frames 2000] [--record rerun,mcap] [--json soak.json] [--no-replay]

Runs ``shadowflow run`` over N synthetic 128x128 faces (copies of 10, ``bench_stream.make_inputs``)
in a child process and samples, every second, its resident memory with its recording process's
(``/proc/PID/status`` VmRSS, summed over the process tree) and
how many frames it has finished (lines of its journal). Reports memory and frames/s over a tenth
of the frames near the start and one near the end, and their ratios (flat: within 10 %). Both
windows stand half a tenth off the ends: the first skips the start-up (the model loaded, the pipeline
filling), the last the drain (the pipeline emptying, its stages no longer overlapping: in three runs of
an earlier release the last 100 frames ran about 20 % slower than the 100 before). The very last
tenth is reported beside it. Then ``shadowflow replay``
and ``shadowflow diff`` (the run against itself) of the run's folder, with their peak RSS
(VmHWM) and seconds. Linux only (``/proc``). Not part of the tests.
"""
from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_stream import make_inputs

CLI = [sys.executable, "-m", "shadowflow.nodes.app.cli"]
_HWM = ("import runpy, sys\nsys.argv = ['shadowflow'] + sys.argv[1:]\n"
        "try:\n    runpy.run_module('shadowflow.nodes.app.cli', run_name='__main__')\n"
        "except SystemExit as e:\n    code = e.code\n"
        "print([int(x.split()[1]) for x in open('/proc/self/status') if x.startswith('VmHWM')][0], file=sys.stderr)\n"
        "sys.exit(code)\n")


def _rss_kib(pid: int) -> int | None:
    """Resident KiB of ``pid`` and its descendants (the run and its recording process)."""
    try:
        own = next(int(line.split()[1]) for line in open(f"/proc/{pid}/status") if line.startswith("VmRSS"))
    except (OSError, StopIteration):
        return None
    return own + sum(_rss_kib(c) or 0 for c in _children(pid))


def _children(pid: int) -> list[int]:
    try:
        return [int(c) for c in open(f"/proc/{pid}/task/{pid}/children").read().split()]
    except OSError:
        return []


def _done(out: Path) -> int:
    try:
        return (out / ".journal.jsonl").read_bytes().count(b"\n")
    except OSError:
        return 0


def soak(n: int, record: str, tmp: Path) -> tuple[dict, Path]:
    src, out = tmp / "in", tmp / "out"
    src.mkdir()
    make_inputs(src, n)
    proc = subprocess.Popen(CLI + ["run", str(src), "--out", str(out), "--quiet", "--record", record])
    samples = []  # (seconds, frames done, RSS KiB)
    t0 = time.perf_counter()
    done = 0
    while proc.poll() is None:
        rss, done = _rss_kib(proc.pid), max(done, _done(out))  # the journal is emptied at the end
        if rss is not None:
            samples.append((time.perf_counter() - t0, done, rss))
        time.sleep(1.0)
    seconds = time.perf_counter() - t0

    def window(lo: int, hi: int) -> tuple[float, float]:
        """frames/s and mean RSS (MiB) over the samples with lo <= frames done < hi."""
        s = [x for x in samples if lo <= x[1] < hi]
        if len(s) < 2:
            return float("nan"), float("nan")
        fps = (s[-1][1] - s[0][1]) / max(s[-1][0] - s[0][0], 1e-9)
        return fps, sum(x[2] for x in s) / len(s) / 1024

    tenth = n // 10
    fps_a, rss_a = window(tenth // 2, tenth // 2 + tenth)  # past the start-up
    fps_b, rss_b = window(n - tenth - tenth // 2, n - tenth // 2)  # short of the drain
    fps_end, rss_end = window(n - tenth, n)
    row = {"frames": n, "record": record, "exit": proc.returncode, "seconds": round(seconds, 1),
           "fps_early": round(fps_a, 2), "fps_late": round(fps_b, 2), "fps_ratio": round(fps_b / fps_a, 3),
           "rss_early_mib": round(rss_a, 1), "rss_late_mib": round(rss_b, 1), "rss_ratio": round(rss_b / rss_a, 3),
           "fps_last_tenth": round(fps_end, 2), "rss_last_tenth_mib": round(rss_end, 1),
           "rss_peak_mib": round(max(x[2] for x in samples) / 1024, 1),
           "recording_mib": round(sum(f.stat().st_size for f in out.glob("run.*")) / 2**20, 1),
           "rss_mib_by_quarter": [round(window(q * n // 4 - tenth, q * n // 4)[1], 1) for q in (1, 2, 3, 4)],
           "samples": [{"s": round(t, 1), "frames": d, "rss_mib": round(r / 1024, 1)} for t, d, r in samples]}
    return row, out


def peak_of(cmd: list[str]) -> tuple[int, float, float]:
    """(exit code, seconds, peak RSS MiB) of ``shadowflow CMD`` in a fresh process."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _HWM, *cmd], capture_output=True, text=True)
    return proc.returncode, time.perf_counter() - t0, int(proc.stderr.split()[-1]) / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=2000)
    ap.add_argument("--record", default="rerun,mcap")
    ap.add_argument("--json")
    ap.add_argument("--no-replay", action="store_true", help="skip replay and diff of the run")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        row, out = soak(args.frames, args.record, Path(tmp))
        for name, cmd in (("replay", ["replay", str(out)]), ("diff", ["diff", str(out), str(out)])):
            if args.no_replay:
                row[f"{name}_exit"] = row[f"{name}_seconds"] = row[f"{name}_peak_mib"] = "-"
                continue
            code, secs, peak = peak_of(cmd)
            row[f"{name}_exit"], row[f"{name}_seconds"], row[f"{name}_peak_mib"] = code, round(secs, 1), round(peak, 1)
    print(f"machine: {platform.machine()}, Python {platform.python_version()}")
    print("| frames | record | s | frames/s early / late tenth | RSS MiB early / late tenth | peak RSS | recordings "
          "MiB | replay s / peak MiB | diff s / peak MiB |")
    print("|---|---|---|---|---|---|---|---|---|")
    r = row
    print(f"| {r['frames']} | {r['record']} | {r['seconds']} | {r['fps_early']} / {r['fps_late']} ({r['fps_ratio']}x) | "
          f"{r['rss_early_mib']} / {r['rss_late_mib']} ({r['rss_ratio']}x) | {r['rss_peak_mib']} | {r['recording_mib']} | "
          f"{r['replay_seconds']} / {r['replay_peak_mib']} | {r['diff_seconds']} / {r['diff_peak_mib']} |")
    print(f"RSS MiB over the tenth before 1/4, 1/2, 3/4 and all of the frames: {r['rss_mib_by_quarter']}")
    print(f"the very last tenth (the drain included): {r['fps_last_tenth']} frames/s, {r['rss_last_tenth_mib']} MiB")
    if args.json:
        Path(args.json).write_text(json.dumps(row, indent=2) + "\n")


if __name__ == "__main__":
    main()
