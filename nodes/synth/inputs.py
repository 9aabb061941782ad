"""Synthetic shadowed face images as a user would give them: a PNG and a sidecar light."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from nodes.synth.facegen import canonical_eyes, render_face, sample_face


def write_shadowed_face(path: str | Path, rng: np.random.Generator, light: np.ndarray,
                        grid: tuple[int, int] = (128, 128)) -> Path:
    """Draw a procedural face from ``rng``, render it under ``light`` (3,) with its cast and
    attached shadows and its albedo, and write ``path`` (8-bit PNG) with ``<stem>.json``
    holding ``{"light": [x, y, z], "eyes": [[x1, y1], [x2, y2]]}``."""
    from nodes.evaluate import render_scene

    depth, mask, albedo = render_face(sample_face(rng), grid)
    image = render_scene(depth, albedo, light, mask).image
    path = Path(path)
    cv2.imwrite(str(path), (np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8))
    eyes = canonical_eyes(grid).tolist()  # the generator knows where it put them
    path.with_suffix(".json").write_text(json.dumps({"light": [float(x) for x in light], "eyes": eyes}))
    return path
