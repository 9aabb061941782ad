"""A relit clip measured against its input (``evaluation.steadiness``): the run's ``relit.mp4`` and
``frames.jsonl`` read beside the clip it came from, one frame of each at a time."""
from __future__ import annotations

import json
import os
import tempfile
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from ..evaluation.steadiness import Steadiness
from .clip_io import ClipEncoder, ClipReader


def measured_eyes(line: dict) -> np.ndarray | None:
    """(2, 2) the eyes of a ``frames.jsonl`` line's largest face that has eyes (photo pixels), else None."""
    faces = [f for f in line.get("faces", []) if f.get("eyes") and f.get("box")]
    if not faces:
        return None
    largest = max(faces, key=lambda f: (f["box"][2] - f["box"][0]) * (f["box"][3] - f["box"][1]))
    return np.asarray(largest["eyes"], np.float64).reshape(2, 2)


def codec_floor(source: str | os.PathLike, folder: str | os.PathLike) -> Path:
    """``source`` through the relit clips' encoder alone (``ClipEncoder``, no relighting), written in ``folder``:
    what the codec changes by itself."""
    path = Path(folder) / "floor.mp4"
    reader = ClipReader(source)
    try:
        encoder = ClipEncoder(path, reader.info, str(source))
        for frame in reader:
            if frame.rgb is not None:
                encoder.write(frame.rgb, frame.pts, frame.time)
        encoder.finish()
    finally:
        reader.close()
    return path


def clip_steadiness(source: str | os.PathLike, folder: str | os.PathLike, relit: str = "relit.mp4",
                    harm_every: int = 1, floor: bool = True) -> dict:
    """``Steadiness.figures`` of ``folder``'s ``relit`` clip (a run's output folder of the clip ``source``) against
    ``source``, its face where ``folder/frames.jsonl`` placed it; with ``floor``, the codec's own share of H
    measured on ``source`` re-encoded alone (in a temporary folder). ``ValueError`` naming the file when a file is
    missing or the two clips' frames do not pair up."""
    folder = Path(folder)
    lines_path = folder / "frames.jsonl"
    if not lines_path.is_file() or not (folder / relit).is_file():
        raise ValueError(f"{folder}: no {relit} and frames.jsonl (is it a run's folder of a clip?)")
    eyes = {}
    with open(lines_path, encoding="utf-8") as f:
        for row in f:
            line = json.loads(row)
            eyes[int(line["index"])] = measured_eyes(line)
    steady = Steadiness(harm_every=harm_every)
    with ExitStack() as stack:
        inputs, outputs = ClipReader(source), ClipReader(folder / relit)
        stack.callback(inputs.close)
        stack.callback(outputs.close)
        floors = iter(())
        if floor:
            scratch = stack.enter_context(tempfile.TemporaryDirectory(prefix="shadowflow-floor-"))
            floors = ClipReader(codec_floor(source, scratch))
            stack.callback(floors.close)
            floors = iter(floors)
        for a, b in zip(inputs, outputs):
            c = next(floors, None) if a.rgb is not None else None
            if a.rgb is None or b.rgb is None:
                steady.add(np.zeros((1, 1, 3), np.uint8), np.zeros((1, 1, 3), np.uint8), None)
                continue
            if a.rgb.shape != b.rgb.shape:
                raise ValueError(f"{folder / relit}: frame {a.index} is {b.rgb.shape[1]}x{b.rgb.shape[0]}, "
                                 f"{source}'s {a.rgb.shape[1]}x{a.rgb.shape[0]}")
            steady.add(a.rgb, b.rgb, eyes.get(a.index), None if c is None else c.rgb)
    return steady.figures()
