"""Synthetic shadowed face images as a user would give them: a PNG and a sidecar light."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from ..model.faces.facegen import canonical_eyes, render_face, sample_face


def draw_face(rng: np.random.Generator, grid: tuple[int, int] = (128, 128),
              source: str = "procedural") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One face drawn from ``rng`` on ``grid``: ``(depth (H, W) px, NaN off the face; mask (H, W)
    bool; albedo (H, W))``. ``procedural``: the anthropometric generator, with its albedo map
    (brows, lips, cheeks); ``ict``: a random ICT-FaceKit identity (real-scan model), one skin
    albedo drawn from N(0.8, 0.05)."""
    if source == "procedural":
        return render_face(sample_face(rng), grid)
    if source != "ict":
        raise ValueError(f"unknown face source {source!r}: procedural or ict")
    from ..model.faces.ict import render_identity, shipped_basis

    basis = shipped_basis()
    depth = render_identity(basis, rng.standard_normal(basis.n_identity), grid)
    mask = np.isfinite(depth)
    albedo = np.where(mask, np.clip(rng.normal(0.8, 0.05), 0.6, 0.95), np.nan).astype(np.float32)
    return depth, mask, albedo


def write_shadowed_face(path: str | Path, rng: np.random.Generator, light: np.ndarray,
                        grid: tuple[int, int] = (128, 128), source: str = "procedural") -> Path:
    """Draw a face from ``rng`` (``draw_face``), render it under ``light`` (3,) with its cast and
    attached shadows and its albedo, and write ``path`` (8-bit PNG) with ``<stem>.json``
    holding ``{"light": [x, y, z], "eyes": [[x1, y1], [x2, y2]]}``."""
    from .synthetic import render_scene

    depth, mask, albedo = draw_face(rng, grid, source)
    image = render_scene(depth, albedo, light, mask).image
    path = Path(path)
    cv2.imwrite(str(path), (np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8))
    eyes = canonical_eyes(grid).tolist()  # the generator knows where it put them
    path.with_suffix(".json").write_text(json.dumps({"light": [float(x) for x in light], "eyes": eyes}))
    return path
