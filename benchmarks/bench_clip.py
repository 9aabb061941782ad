"""A clip's run against the floor any video tool pays: OpenCV decoding the same clip and encoding it twice (relit.mp4
and one --relight clip), measured in the same sitting, rounds taking turns.

    python benchmarks/bench_clip.py [--frames 48] [--size 256] [--repeats 3] [--clip PATH] [--workers N]
        [--json out.json]

Without ``--clip`` the clip is made here: one rendered ICT face, its light swinging, H.264. Each round times
``shadowflow run CLIP --relight=-60,10 --record none`` in a fresh process (its start-up, about 2 s of imports and
the model, is reported apart: the same run over a one-frame clip), and OpenCV's ``VideoCapture`` read of every frame
plus two ``VideoWriter`` (mp4v) encodes. Reports frames/s of each, medians over rounds, and their ratio. Not part of
the tests; no thresholds.
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def make_clip(path: Path, frames: int, size: int) -> Path:
    """``frames`` frames of a rendered face (``size`` pixels square), its light swinging from 40 left to 40 right."""
    import av

    from shadowflow.nodes.evaluation.scenes import draw_face, render_scene
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    depth, mask, albedo = draw_face(np.random.default_rng(7), (size, size), "ict")
    with av.open(str(path), "w") as out:
        video = out.add_stream("libx264", rate=25)
        video.width = video.height = size
        video.pix_fmt = "yuv420p"
        for i in range(frames):
            light = light_from_angles(40 - 80 * i / max(frames - 1, 1), 0)
            grey = (np.clip(render_scene(depth, albedo, light, mask).image, 0, 1) * 255 + 0.5).astype(np.uint8)
            frame = av.VideoFrame.from_ndarray(np.repeat(grey[..., None], 3, axis=2), format="rgb24")
            frame.pts = i
            out.mux(video.encode(frame))
        out.mux(video.encode(None))
    return path


def opencv_floor(clip: Path, tmp: Path) -> tuple[float, int]:
    """Seconds for OpenCV to decode ``clip`` and encode it twice (mp4v, the codec its wheels write), and the frames."""
    import cv2

    t0 = time.perf_counter()
    cap = cv2.VideoCapture(str(clip))
    fps = cap.get(cv2.CAP_PROP_FPS) or 25.0
    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    writers = [cv2.VideoWriter(str(tmp / f"cv{k}.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h)) for k in (1, 2)]
    n = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        for writer in writers:
            writer.write(frame)
        n += 1
    for writer in writers:
        writer.release()
    cap.release()
    return time.perf_counter() - t0, n


def shadowflow_run(clip: Path, out: Path, workers: int = 1) -> float:
    cmd = [sys.executable, "-m", "shadowflow.nodes.app.cli", "run", str(clip), "--out", str(out), "--relight=-60,10",
           "--record", "none", "--quiet", "--workers", str(workers)]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=False, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--clip", type=Path, help="a clip of your own instead of the rendered one")
    ap.add_argument("--workers", type=int, default=1,
                    help="the run's --workers (the fit's and the relighting's threads)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        clip = args.clip or make_clip(tmp / "clip.mp4", args.frames, args.size)
        one = make_clip(tmp / "one.mp4", 1, args.size)
        rows = []
        for r in range(args.repeats):
            start = shadowflow_run(one, tmp / f"one{r}", args.workers)
            ours = shadowflow_run(clip, tmp / f"run{r}", args.workers)
            floor, n = opencv_floor(clip, tmp)
            rows.append({"round": r, "frames": n, "shadowflow_s": round(ours, 3), "startup_s": round(start, 3),
                         "opencv_s": round(floor, 4)})
            print(rows[-1], flush=True)
        n = rows[0]["frames"]
        ours = statistics.median(x["shadowflow_s"] for x in rows)
        start = statistics.median(x["startup_s"] for x in rows)
        floor = statistics.median(x["opencv_s"] for x in rows)
        result = {"frames": n, "size": args.size, "clip": str(args.clip or "rendered"), "workers": args.workers,
                  "rounds": rows,
                  "shadowflow_fps": round(n / ours, 2), "shadowflow_fps_after_startup": round(n / max(ours - start,
                                                                                                     1e-9), 2),
                  "opencv_fps": round(n / floor, 1), "opencv_over_shadowflow": round(ours / floor, 1)}
        print(json.dumps({k: v for k, v in result.items() if k != "rounds"}, indent=1))
        if args.json:
            args.json.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
