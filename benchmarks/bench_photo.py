"""Time and memory of one large colour portrait through ``shadowflow.fit``: the photo-grid
relighting is the only step that grows with the photo.

Usage: python benchmarks/bench_photo.py [--scale 12]   (scale 12: a 2400 x 3200 frame, the face
1536 px wide, 7.7 megapixels). Prints the per-node seconds and the process's peak memory.
"""
from __future__ import annotations

import argparse
import json
import resource
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import shadowflow
from shadowflow.nodes.evaluation.scenes import write_shadowed_face
from shadowflow.nodes.geometry.reflectance import light_from_angles


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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scale", type=int, default=12)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        photo = portrait(Path(tmp), args.scale)
        h, w = cv2.imread(str(photo)).shape[:2]
        t0 = time.perf_counter()
        result = shadowflow.fit(photo)
        seconds = time.perf_counter() - t0
    timings = {k: round(v, 3) for k, v in result.frame.meta["timings"].items()}
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{w} x {h} ({w * h / 1e6:.1f} MP): fit {seconds:.1f} s, peak memory {peak:.0f} MiB")
    print(json.dumps(timings))


if __name__ == "__main__":
    main()
