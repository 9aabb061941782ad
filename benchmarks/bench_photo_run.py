"""Whole runs of ordinary photos on one core, beside the fit alone: where a photo's time goes.

    python benchmarks/bench_photo_run.py [--repeats 5] [--record mcap,rerun] [--baseline REV] [--memory]

Cases: scikit-image's astronaut (public domain) scaled 4x (2048 x 2048, 4.2 MP) and 2x (1 MP), and
30 synthetic 128 x 128 faces. Each case runs ``shadowflow run`` in a fresh process pinned to one
core: once to warm the model cache and imports, then ``--repeats`` times; it reports the median
wall time of the run (seconds per photo; per frame for the 30 faces), the median of the fit's own
nodes (remap to relight, on the model grid), the photo's steps (load, faces, relight_photo,
compose, write), the child's peak memory, the megabytes a photo's outputs take (its folder; the 30 faces'
per face) and the run's exit code (1: a frame failed). ``--baseline REV`` runs the same cases on git
revision REV (installed into a temporary folder) for a ratio. ``--memory``: also the peak memory of one
run over twenty 4.2 MP photos with two ``--relight`` lights (both cores, as a user runs it). Not part of
the tests.
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

FIT_NODES = ("remap", "sfs_init", "robust_fit", "combine", "integrate", "shadow", "albedo", "quality", "relight")
PHOTO_NODES = ("load", "faces", "relight_photo", "compose", "write", "record")

# run in the child: the CLI in-process, its per-frame node timings caught from the summary records
CHILD = r"""
import json, os, shutil, statistics, sys, time
os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
import shadowflow.nodes.app.runner as runner
inputs, out, record, repeats = json.loads(sys.argv[1])
timings = []
original = runner.summary_record
def caught(frame):
    timings.append(dict(frame.meta.get("timings", {})))
    return original(frame)
runner.summary_record = caught
from shadowflow.nodes.app.cli import main
walls = []
for k in range(repeats + 1):
    shutil.rmtree(out, ignore_errors=True)
    timings.clear()
    t = time.perf_counter()
    code = main(["run", *inputs, "--out", out, "--quiet", "--record", record])
    walls.append(time.perf_counter() - t)
    if k == 0:
        continue
    per_node = {}
    for t in timings:
        for name, s in t.items():
            per_node[name] = per_node.get(name, 0.0) + s
    print(json.dumps({"wall": walls[-1], "nodes": per_node, "frames": len(timings), "exit": code}), flush=True)
peak = [int(ln.split()[1]) for ln in open("/proc/self/status") if ln.startswith("VmHWM")][0]
folders = [p for p in os.scandir(out) if p.is_dir()]
size = sum(os.path.getsize(os.path.join(root, f)) for p in folders for root, _, files in os.walk(p.path) for f in files)
print(json.dumps({"peak_mib": peak / 1024, "mb_per_photo": size / 1e6 / max(1, len(folders))}))
"""

# one run of many large photos in a fresh process, on every core: its peak memory
MEMORY_CHILD = r"""
import json, sys
from shadowflow.nodes.app.cli import main
folder, out = sys.argv[1], sys.argv[2]
code = main(["run", folder, "--out", out, "--quiet", "--record", "none", "--relight=30,0", "--relight=-30,0"])
peak = [int(ln.split()[1]) for ln in open("/proc/self/status") if ln.startswith("VmHWM")][0]
print(json.dumps({"peak_mib": peak / 1024, "exit": code}))
"""


def astronaut(folder: Path, scale: int) -> Path:
    from skimage import data

    rgb = data.astronaut()
    big = cv2.resize(rgb, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC)
    path = folder / f"astronaut-x{scale}.png"
    cv2.imwrite(str(path), big[..., ::-1])
    return path


def small_faces(folder: Path, n: int = 30) -> list[Path]:
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    rng = np.random.default_rng(5)
    folder.mkdir()
    return [write_shadowed_face(folder / f"face-{i:02d}.png", rng, light_from_angles(30 + 2 * i)) for i in range(n)]


def install(rev: str, folder: Path) -> Path:
    """Git revision ``rev`` of this repository installed (no dependencies) into ``folder``; its path
    for ``PYTHONPATH``."""
    src, site = folder / "src", folder / "site"
    root = Path(__file__).resolve().parents[1]
    subprocess.run(["git", "-C", str(root), "worktree", "add", "--detach", str(src), rev], check=True,
                   capture_output=True)
    try:
        subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps",
                        "--target", str(site), str(src)], check=True)
    finally:
        subprocess.run(["git", "-C", str(root), "worktree", "remove", "--force", str(src)], check=True)
    return site


def run_case(inputs: list[Path], out: Path, record: str, repeats: int, pythonpath: Path | None) -> dict:
    env = None
    if pythonpath is not None:
        import os

        env = {**os.environ, "PYTHONPATH": str(pythonpath)}
    proc = subprocess.run([sys.executable, "-c", CHILD, json.dumps([[str(p) for p in inputs], str(out), record,
                                                                    repeats])],
                          capture_output=True, text=True, env=env)
    if proc.returncode:
        raise RuntimeError(proc.stderr[-2000:])
    lines = [json.loads(ln) for ln in proc.stdout.splitlines() if ln.startswith("{")]
    runs, peak, size = lines[:-1], lines[-1]["peak_mib"], lines[-1]["mb_per_photo"]
    frames = runs[0]["frames"]

    def median(f) -> float:
        return statistics.median(f(r) for r in runs) / frames

    row = {"wall": median(lambda r: r["wall"]), "fit": median(lambda r: sum(r["nodes"].get(n, 0) for n in FIT_NODES)),
           "peak_mib": round(peak), "mb": round(size, 2), "frames": frames, "exit": runs[0]["exit"]}
    for name in PHOTO_NODES:
        row[name] = median(lambda r: r["nodes"].get(name, 0.0))
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--record", default="mcap,rerun")
    ap.add_argument("--baseline", help="a git revision to run the same cases on")
    ap.add_argument("--json")
    ap.add_argument("--memory", action="store_true", help="also twenty 4.2 MP photos with two lights: peak memory")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cases = {"astronaut x4 (4.2 MP)": [astronaut(tmp, 4)], "astronaut x2 (1 MP)": [astronaut(tmp, 2)],
                 "30 faces at 128x128": small_faces(tmp / "faces")}
        builds = {"now": None}
        if args.baseline:
            builds[args.baseline] = install(args.baseline, tmp / "baseline")
        rows = []
        for case, inputs in cases.items():
            for build, path in builds.items():
                row = {"case": case, "build": build, **run_case(inputs, tmp / "out", args.record, args.repeats, path)}
                rows.append(row)
        memory = []
        if args.memory:
            twenty = tmp / "twenty"
            twenty.mkdir()
            big = astronaut(tmp, 4)
            for k in range(20):
                (twenty / f"a{k:02d}.png").write_bytes(big.read_bytes())
            for build, path in builds.items():
                env = None if path is None else {**__import__("os").environ, "PYTHONPATH": str(path)}
                proc = subprocess.run([sys.executable, "-c", MEMORY_CHILD, str(twenty), str(tmp / "mem")],
                                      capture_output=True, text=True, env=env)
                memory.append({"build": build, **json.loads(proc.stdout.splitlines()[-1])})
    cols = ("wall", "fit", *PHOTO_NODES)
    print(f"one core, record {args.record}, medians of {args.repeats} warm runs; seconds per photo (per frame for "
          "the 30 faces)\n")
    print("| case | build | " + " | ".join(cols) + " | peak MiB | MB written | exit | × fit | × baseline |")
    print("|---|---|" + "---|" * len(cols) + "---|---|---|---|---|")
    for row in rows:
        base = next((r for r in rows if r["case"] == row["case"] and r["build"] == args.baseline), None)
        ratio = f"{row['wall'] / base['wall']:.2f}" if base and base is not row else "-"
        print(f"| {row['case']} | {row['build']} | " + " | ".join(f"{row[c]:.3f}" for c in cols)
              + f" | {row['peak_mib']} | {row['mb']} | {row['exit']} | {row['wall'] / row['fit']:.1f} | {ratio} |")
    for m in memory:
        print(f"\ntwenty 4.2 MP photos, two --relight lights, both cores, {m['build']}: peak {m['peak_mib']:.0f} MiB "
              f"(exit {m['exit']})")
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "memory": memory}, indent=2))


if __name__ == "__main__":
    main()
