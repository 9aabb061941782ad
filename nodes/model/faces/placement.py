"""Placing a face mesh on the canonical grid: its eye centres on the grid's canonical eye pixels,
then rendered as a height field. Shared by the mesh sources (eos models, mesh folders, ICT-FaceKit)."""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from ...geometry.integrate import fill_holes
from ...geometry.raster import rasterize
from ...geometry.similarity import two_point_similarity
from ..canonical import canonical_eyes


def align_to_eyes(vertices: np.ndarray, eye_left: np.ndarray, eye_right: np.ndarray,
                  grid: tuple[int, int]) -> np.ndarray:
    """Similarity-map mesh vertices (any unit, x right, y up, z toward viewer) to pixel coordinates.

    The image-left and image-right eye centres (3,) land on the canonical eye pixels of
    ``grid``; heights scale with the same factor. Returns (V, 3): column, row, height (px).
    """
    target = canonical_eyes(grid)
    src = np.array([eye_left[:2], eye_right[:2]], float)
    dst = np.array([[target[0, 0], -target[0, 1]], [target[1, 0], -target[1, 1]]])  # y up
    sim = two_point_similarity(src, dst)
    xy = sim.apply(vertices[:, :2])
    return np.column_stack([xy[:, 0], -xy[:, 1], vertices[:, 2] * sim.scale])


def render_mesh(vertices_px: np.ndarray, triangles: np.ndarray, grid: tuple[int, int]) -> np.ndarray:
    """Height field (H, W) of a mesh already in pixel coordinates; interior holes filled."""
    depth, _ = rasterize(vertices_px, triangles, grid)
    covered = np.isfinite(depth)
    region = ndimage.binary_fill_holes(covered)
    return fill_holes(depth, region).astype(np.float32)
