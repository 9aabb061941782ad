"""Soak: one long run with both recordings; do memory and speed stay flat? Then replay and diff it.

    python benchmarks/bench_soak.py [--frames 2000] [--record rerun,mcap] [--json soak.json] [--no-replay]
                                    [--renew-frames N]

Runs ``shadowflow run`` over N synthetic 128x128 faces (copies of 10, ``bench_stream.make_inputs``)
in a child process and samples, every second, its resident memory with its recording process's
(``/proc/PID/status`` VmRSS, summed over the process tree) and
how many frames it has finished (lines of its journal), and the CPU seconds the tree has used
(``/proc/PID/stat``: its own, its live descendants', and those of children it has reaped, such as
a renewed recording process). Reports memory, frames/s and CPU seconds a frame over a tenth
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
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.stats import theilslopes

from bench_stream import make_inputs

CLI = [sys.executable, "-m", "shadowflow.nodes.app.cli"]
# the run with its Rerun sink's process renewed every N frames (``sinks.RERUN_RENEW_FRAMES``), N from argv[1]
_RENEWED = ("import runpy, sys\nimport shadowflow.nodes.app.sinks as sinks\n"
            "sinks.RERUN_RENEW_FRAMES = int(sys.argv[1])\nsys.argv = ['shadowflow'] + sys.argv[2:]\n"
            "runpy.run_module('shadowflow.nodes.app.cli', run_name='__main__')\n")
_HWM = ("import runpy, sys\nsys.argv = ['shadowflow'] + sys.argv[1:]\n"
        "try:\n    runpy.run_module('shadowflow.nodes.app.cli', run_name='__main__')\n"
        "except SystemExit as e:\n    code = e.code\n"
        "print([int(x.split()[1]) for x in open('/proc/self/status') if x.startswith('VmHWM')][0], file=sys.stderr)\n"
        "sys.exit(code)\n")


def _rss_kib(pid: int, tree: bool = True) -> int | None:
    """Resident KiB of ``pid`` and (``tree``) its descendants (the run and its recording processes)."""
    try:
        own = next(int(line.split()[1]) for line in open(f"/proc/{pid}/status") if line.startswith("VmRSS"))
    except (OSError, StopIteration):
        return None
    return own + (sum(_rss_kib(c) or 0 for c in _children(pid)) if tree else 0)


def _cpu_seconds(pid: int, tree: bool = True) -> float | None:
    """CPU seconds (user + system) of ``pid``, with (``tree``) its live descendants and the children
    it has reaped; without, of its own threads alone."""
    try:
        fields = open(f"/proc/{pid}/stat").read().rpartition(")")[2].split()
    except OSError:
        return None
    ticks = fields[11:15] if tree else fields[11:13]  # utime stime [cutime cstime]
    own = sum(int(x) for x in ticks) / os.sysconf("SC_CLK_TCK")
    return own + (sum(_cpu_seconds(c) or 0.0 for c in _children(pid)) if tree else 0.0)


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


def soak(n: int, record: str, tmp: Path, renew_frames: int | None = None) -> tuple[dict, Path]:
    src, out = tmp / "in", tmp / "out"
    src.mkdir()
    make_inputs(src, n)
    cli = CLI if renew_frames is None else [sys.executable, "-c", _RENEWED, str(renew_frames)]
    proc = subprocess.Popen(cli + ["run", str(src), "--out", str(out), "--quiet", "--record", record])
    samples = []  # (seconds, frames done, RSS KiB, CPU seconds, the run's own CPU seconds, the run's own RSS KiB)
    t0 = time.perf_counter()
    done = 0
    while proc.poll() is None:
        rss, cpu, done = _rss_kib(proc.pid), _cpu_seconds(proc.pid), max(done, _done(out))  # journal emptied at the end
        own, own_rss = _cpu_seconds(proc.pid, tree=False), _rss_kib(proc.pid, tree=False)
        if None not in (rss, cpu, own, own_rss):
            samples.append((time.perf_counter() - t0, done, rss, cpu, own, own_rss))
        time.sleep(1.0)
    seconds = time.perf_counter() - t0

    def window(lo: int, hi: int) -> tuple[float, float, float]:
        """frames/s, mean RSS (MiB) and CPU ms a frame over the samples with lo <= frames done < hi."""
        s = [x for x in samples if lo <= x[1] < hi]
        if len(s) < 2:
            return float("nan"), float("nan"), float("nan")
        frames = max(s[-1][1] - s[0][1], 1)
        fps = (s[-1][1] - s[0][1]) / max(s[-1][0] - s[0][0], 1e-9)
        return fps, sum(x[2] for x in s) / len(s) / 1024, 1000 * (s[-1][3] - s[0][3]) / frames

    tenth = n // 10
    rss_trend, fps_trend = trend(samples, n, tenth // 2, n - tenth // 2)
    fps_a, rss_a, cpu_a = window(tenth // 2, tenth // 2 + tenth)  # past the start-up
    fps_b, rss_b, cpu_b = window(n - tenth - tenth // 2, n - tenth // 2)  # short of the drain
    fps_end, rss_end, _ = window(n - tenth, n)
    row = {"frames": n, "record": record, "renew_frames": renew_frames, "exit": proc.returncode, "seconds": round(seconds, 1),
           "fps_early": round(fps_a, 2), "fps_late": round(fps_b, 2), "fps_ratio": round(fps_b / fps_a, 3),
           "rss_early_mib": round(rss_a, 1), "rss_late_mib": round(rss_b, 1), "rss_ratio": round(rss_b / rss_a, 3),
           "cpu_ms_per_frame_early": round(cpu_a, 1), "cpu_ms_per_frame_late": round(cpu_b, 1),
           "cpu_ratio": round(cpu_b / cpu_a, 3), "rss_trend": round(rss_trend, 3), "fps_trend": round(fps_trend, 3),
           "fps_last_tenth": round(fps_end, 2), "rss_last_tenth_mib": round(rss_end, 1),
           "rss_peak_mib": round(max(x[2] for x in samples) / 1024, 1),
           "recording_mib": round(sum(f.stat().st_size for f in out.glob("run.*")) / 2**20, 1),
           "rss_mib_by_quarter": [round(window(q * n // 4 - tenth, q * n // 4)[1], 1) for q in (1, 2, 3, 4)],
           "samples": [{"s": round(t, 1), "frames": d, "rss_mib": round(r / 1024, 1), "cpu_s": round(c, 2),
                        "cpu_run_s": round(o, 2), "rss_run_mib": round(q / 1024, 1)} for t, d, r, c, o, q in samples]}
    return row, out


def trend(samples: list[tuple], n: int, lo: int, hi: int) -> tuple[float, float]:
    """(RSS, frames/s): where a Theil-Sen line ends against where it starts over frames lo..hi of
    n, through every RSS sample and through the frames/s of each 5 % of the frames. ``samples``:
    (seconds, frames done, RSS, ...). A window's mean can land on either end of a saw (a recording
    process growing, then renewed); the line weighs the whole run."""
    s = [x for x in samples if lo <= x[1] < hi]
    f, m = np.array([x[1] for x in s], float), np.array([x[2] for x in s], float)
    slope, icept, *_ = theilslopes(m, f)
    step, mids, rates = max(n // 20, 1), [], []
    for a in range(lo, hi - step + 1, step):
        w = [x for x in s if a <= x[1] < a + step]
        if len(w) > 1 and w[-1][0] > w[0][0]:
            mids.append(a + step / 2)
            rates.append((w[-1][1] - w[0][1]) / (w[-1][0] - w[0][0]))
    if len(rates) < 3:
        return float("nan"), float("nan")
    fslope, ficept, *_ = theilslopes(rates, mids)
    return (float((icept + slope * hi) / (icept + slope * lo)),
            float((ficept + fslope * mids[-1]) / (ficept + fslope * mids[0])))


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
    ap.add_argument("--renew-frames", type=int, help="renew the Rerun sink's process every N frames "
                    "(default: sinks.RERUN_RENEW_FRAMES; a number above --frames: never)")
    ap.add_argument("--no-replay", action="store_true", help="skip replay and diff of the run")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        row, out = soak(args.frames, args.record, Path(tmp), args.renew_frames)
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
    print(f"CPU ms a frame (the run and its recording processes), same windows: {r['cpu_ms_per_frame_early']} / "
          f"{r['cpu_ms_per_frame_late']} ({r['cpu_ratio']}x)")
    print(f"Theil-Sen lines over the same span, end against start: RSS {r['rss_trend']}x, frames/s {r['fps_trend']}x")
    print(f"the very last tenth (the drain included): {r['fps_last_tenth']} frames/s, {r['rss_last_tenth_mib']} MiB")
    if args.json:
        Path(args.json).write_text(json.dumps(row, indent=2) + "\n")


if __name__ == "__main__":
    main()
