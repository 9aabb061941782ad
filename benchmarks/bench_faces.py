"""Finding and placing the faces of a photo (``photo.placement.place_faces``: detector views, face mesh,
landmark placement, pose) on one core, against the photo's size and number of faces.

Usage: python benchmarks/bench_faces.py [--repeat 7]
Photos (made here, nothing read from ../shared): scikit-image's ``astronaut`` (public domain) as it
is (512^2), scaled to 1 MP and 4 MP, pasted small (eyes 30 px apart) into a 1 MP frame of colour
shapes, three times into one 1 MP frame (a group), and the 1 MP frame alone (no face). Prints the
median milliseconds of ``--repeat`` runs with the nets in each runtime (LiteRT where installed, OpenCV's
dnn), their ratio, the detector's views, the mesh calls and the faces found; writes
benchmarks/results/faces.json.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import cv2
import numpy as np
from threadpoolctl import threadpool_limits

import shadowflow.nodes.photo.mediapipe as mp
from shadowflow.nodes.evaluation.composites import background
from shadowflow.nodes.model.default_model import default_model
from shadowflow.nodes.photo.placement import place_faces

ASTRONAUT_IOD = 43.6  # pixels between her eyes in the 512^2 original


def photos() -> dict[str, np.ndarray]:
    from skimage import data

    ast = np.ascontiguousarray(data.astronaut())
    rng = np.random.default_rng(0)
    frame = (background((866, 1155), rng) * 255).astype(np.uint8)
    out = {"astronaut 512^2": ast,
           "astronaut 1 MP": cv2.resize(ast, (1000, 1000), interpolation=cv2.INTER_CUBIC),
           "astronaut 4 MP": cv2.resize(ast, (2048, 2048), interpolation=cv2.INTER_CUBIC),
           "no face, 1 MP": frame.copy()}
    small = cv2.resize(ast, None, fx=30 / ASTRONAUT_IOD, fy=30 / ASTRONAUT_IOD, interpolation=cv2.INTER_AREA)
    one = frame.copy()
    one[500:500 + small.shape[0], 700:700 + small.shape[1]] = small
    out["eyes 30 px apart in 1 MP"] = one
    group = frame.copy()
    head = cv2.resize(ast, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    for x in (40, 420, 800):
        group[300:300 + head.shape[0], x:x + head.shape[1]] = head
    out["three people, 1 MP"] = group
    return out


def count_calls(fn):
    """Wrap ``fn`` to count its calls (the detector's views, the mesh's crops)."""
    def wrapped(*a, **k):
        wrapped.calls += 1
        return fn(*a, **k)
    wrapped.calls = 0
    return wrapped


def runtimes() -> list[str]:
    """The nets' runtimes to time: LiteRT (where installed) and OpenCV's dnn (``mediapipe.runtime``)."""
    return [n for n in mp.RUNTIMES if n != "litert" or mp._litert() is not None]


def timed(model, rgb, runtime: str, repeat: int) -> tuple[float, int]:
    """Median milliseconds of ``place_faces`` on ``rgb`` with the nets in ``runtime``, and the faces found."""
    os.environ["SHADOWFLOW_NETS"] = runtime
    for pool in (mp.DETECTOR, mp.MESH):
        pool._free.clear()  # nets of this runtime from here on
    place_faces(model, rgb)  # warm: the nets load once
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        faces = place_faces(model, rgb)
        times.append(time.perf_counter() - t0)
    return 1000 * statistics.median(times), len(faces)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    model = default_model()
    rows = []
    names = runtimes()
    with threadpool_limits(1):
        for name, rgb in photos().items():
            ms, found = {}, {}
            for runtime in names:
                ms[runtime], found[runtime] = timed(model, rgb, runtime, args.repeat)
            mesh = count_calls(mp.face_mesh)
            import shadowflow.nodes.photo.faces as faces_module

            faces_module.face_mesh, saved = mesh, faces_module.face_mesh
            place_faces(model, rgb)
            faces_module.face_mesh = saved
            views = len(mp._views(rgb.shape[:2], 30.0))
            rows.append({"photo": name, "megapixels": round(rgb.shape[0] * rgb.shape[1] / 1e6, 2),
                         "ms": {k: round(v, 1) for k, v in ms.items()}, "views": views, "mesh_calls": mesh.calls,
                         "faces": found})
            times = "  ".join(f"{k} {v:6.1f} ms" for k, v in ms.items())
            ratio = f"  opencv / litert {ms['opencv'] / ms['litert']:.2f}" if "litert" in ms else ""
            print(f"{name:28s} {rows[-1]['megapixels']:5.2f} MP  {times}{ratio}  {views:3d} detector views  "
                  f"{mesh.calls:2d} mesh calls  {found[names[0]]} faces", flush=True)
    out = Path(__file__).parent / "results" / "faces.json"
    out.write_text(json.dumps({"machine": f"{platform.machine()}, {platform.python_version()}, one core",
                               "repeat": args.repeat, "rows": rows}, indent=1) + "\n")
    print(f"written: {out}")


if __name__ == "__main__":
    main()
