"""Time and memory of one large colour portrait through ``shadowflow.fit``: the photo-grid
relighting is the only step that grows with the photo.

Usage: python benchmarks/bench_photo.py [--scale 12] [--jpeg] [--max-megapixels MP]
(scale 12: a 3204 x 2400 frame, the face 1536 px wide, 7.7 megapixels; scale 25: 33 megapixels).
Photos over --max-megapixels (default: the run's, 4) are read reduced; 0 keeps the full size.
Prints the per-node seconds and the process's peak memory.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np
from shadowflow.nodes.evaluation.scenes import write_shadowed_face
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.photo.loader import MAX_WORK_PIXELS


def portrait(folder: Path, scale: int) -> Path:
    """A rendered ICT face lit from 50 deg left, skin-coloured, ``scale`` x its 128 px render, in a
    grey-blue frame 200 x ``scale`` by 267 x ``scale``; eyes and light in a sidecar."""
    face_png = write_shadowed_face(folder / "face.png", np.random.default_rng(8), light_from_angles(50), source="ict")
    grey = cv2.resize(cv2.imread(str(face_png), cv2.IMREAD_GRAYSCALE) / 255.0, None, fx=scale, fy=scale,
                      interpolation=cv2.INTER_CUBIC)
    h, w, top, left = 200 * scale, 267 * scale, 25 * scale, 67 * scale
    frame = np.dstack([np.full((h, w), 0.3), np.full((h, w), 0.4), np.full((h, w), 0.5)])
    region = frame[top:top + grey.shape[0], left:left + grey.shape[1]]
    on = grey > 0.01
    region[on] = grey[on][:, None] * np.array([1.0, 0.78, 0.62])
    photo = folder / "portrait.png"
    cv2.imwrite(str(photo), (np.clip(frame, 0, 1)[..., ::-1] * 255).astype(np.uint8))
    side = json.loads(face_png.with_suffix(".json").read_text())
    eyes = (np.array(side["eyes"]) * scale + [left, top]).tolist()
    photo.with_suffix(".json").write_text(json.dumps({"light": side["light"], "eyes": eyes}))
    return photo


def fit_in_child(photo: Path, max_pixels: int | None) -> tuple[dict, float]:
    """``shadowflow.fit`` of ``photo`` in a fresh process (Linux): (its report, its peak RSS in MiB),
    so the peak is the fit's alone, not the portrait's rendering."""
    code = ("import json, sys, time, shadowflow\n"
            "from shadowflow.nodes.method.options import MethodOptions\n"
            "t0 = time.perf_counter()\n"
            f"r = shadowflow.fit({str(photo)!r}, options=MethodOptions(max_pixels={max_pixels!r}))\n"
            "print(json.dumps({'seconds': time.perf_counter() - t0, 'timings': r.frame.meta['timings'],"
            " 'reduced': r.frame.meta.get('reduced'),"
            " 'peak': [int(ln.split()[1]) for ln in open('/proc/self/status') if ln.startswith('VmHWM')][0]}))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    report = json.loads(out.stdout.splitlines()[-1])
    return report, report["peak"] / 1024  # VmHWM (kB) starts afresh at exec; ru_maxrss would count the fork


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scale", type=int, default=12)
    ap.add_argument("--jpeg", action="store_true", help="the portrait as a JPEG (quality 92), as a camera gives it")
    ap.add_argument("--max-megapixels", type=float, default=MAX_WORK_PIXELS / 1e6)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        photo = portrait(Path(tmp), args.scale)
        h, w = cv2.imread(str(photo)).shape[:2]
        if args.jpeg:
            jpeg = photo.with_suffix(".jpg")
            cv2.imwrite(str(jpeg), cv2.imread(str(photo)), [cv2.IMWRITE_JPEG_QUALITY, 92])
            jpeg.with_suffix(".json").write_text(photo.with_suffix(".json").read_text())
            photo = jpeg
        report, peak = fit_in_child(photo, int(args.max_megapixels * 1e6) or None)
    worked = (report["reduced"] or {}).get("to", [w, h])
    print(f"{w} x {h} ({w * h / 1e6:.1f} MP{', JPEG' if args.jpeg else ''}), worked at {worked[0]} x {worked[1]}: "
          f"fit {report['seconds']:.1f} s, peak memory {peak:.0f} MiB")
    print(json.dumps({k: round(v, 3) for k, v in report["timings"].items()}))


if __name__ == "__main__":
    main()
