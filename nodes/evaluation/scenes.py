"""Rendered test scenes: a face's heights under a light, Lambertian with its cast and attached
shadows (``render_scene``), and written as a user would give it, a PNG with a sidecar light
(``write_shadowed_face``; the ``--demo`` inputs)."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ...flow.files import atomic_write_bytes
from ..geometry.integrate import fill_holes
from ..geometry.normals import normals_from_depth
from ..geometry.reflectance import lambertian
from ..method.shadow import ShadowMaps, shadow_maps
from ..model.canonical import canonical_eyes
from ..model.faces.facegen import render_face, sample_face
from ..model.faces.ict import render_identity, shipped_basis


@dataclass
class Scene:
    """A rendered test face on the model grid: image (H, W), true normals (H, W, 3),
    true depth (H, W), true shadows, light (3,), valid (H, W) pixels with ground truth."""

    image: np.ndarray
    normals: np.ndarray
    depth: np.ndarray
    shadows: ShadowMaps
    light: np.ndarray
    valid: np.ndarray


def render_scene(depth: np.ndarray, albedo: np.ndarray | float, light: np.ndarray, region: np.ndarray) -> Scene:
    """Render a face (heights in pixels, NaN off it) under ``light`` with its shadows.

    Interior holes inside ``region`` are filled first; pixels of ``region`` the face does
    not cover are black and excluded from the metrics.
    """
    d = fill_holes(depth, region)
    n = normals_from_depth(d)
    sh = shadow_maps(d, n, light)
    img = lambertian(np.nan_to_num(n), light, np.nan_to_num(albedo)) * sh.lit
    valid = region & np.isfinite(d)
    return Scene(np.where(valid, img, 0.0).astype(np.float32), n, d.astype(np.float32), sh, light, valid)



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

    basis = shipped_basis()
    depth = render_identity(basis, rng.standard_normal(basis.n_identity), grid)
    mask = np.isfinite(depth)
    albedo = np.where(mask, np.clip(rng.normal(0.8, 0.05), 0.6, 0.95), np.nan).astype(np.float32)
    return depth, mask, albedo


def write_shadowed_face(path: str | Path, rng: np.random.Generator, light: np.ndarray,
                        grid: tuple[int, int] = (128, 128), source: str = "procedural") -> Path:
    """Draw a face from ``rng`` (``draw_face``), render it under ``light`` (3,) with its cast and
    attached shadows and its albedo, and write ``path`` (8-bit PNG) with ``<stem>.json``
    holding ``{"light": [x, y, z], "eyes": [[x1, y1], [x2, y2]]}``, each atomically (a link at either name is
    replaced, never written through: ``--demo`` writes these into ``--out``)."""
    depth, mask, albedo = draw_face(rng, grid, source)
    image = render_scene(depth, albedo, light, mask).image
    path = Path(path)
    ok, encoded = cv2.imencode(path.suffix or ".png", (np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8))
    if not ok:
        raise ValueError(f"{path}: cannot encode an image of this kind")
    atomic_write_bytes(path, encoded.tobytes())
    eyes = canonical_eyes(grid).tolist()  # the generator knows where it put them
    atomic_write_bytes(path.with_suffix(".json"), json.dumps({"light": [float(x) for x in light], "eyes": eyes}).encode())
    return path
