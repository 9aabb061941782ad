"""Placing a face mesh on the canonical grid: its eye centres on the grid's canonical eye pixels,
then rendered as a height field. Shared by the mesh sources (eos models, mesh folders, ICT-FaceKit).

A turned head (``turn_to_view``): the frontally placed face turned by a yaw and a pitch about its eye
midpoint, which stays on the canonical one; its scale stays. (Turned about the neck and moved back, the
image is the same: the axis only moves the heights by a constant.) What the camera sees of it is then
rendered as the frontal face is (nearest surface wins: the far cheek behind the nose is hidden).
"""
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


def view_rotation(yaw_deg: float, pitch_deg: float) -> np.ndarray:
    """(3, 3) the rotation of a head turned ``yaw_deg`` (> 0 toward the image's right) and tilted
    ``pitch_deg`` (> 0 up), camera frame (x right, y up, z toward the viewer): ``Ry(yaw) Rx(-pitch)``,
    tilted first, then turned (``photo.faces.Pose``)."""
    a, b = np.radians(yaw_deg), np.radians(-pitch_deg)
    ry = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(b), -np.sin(b)], [0.0, np.sin(b), np.cos(b)]])
    return ry @ rx


def turn_to_view(points_px: np.ndarray, eyes_px: np.ndarray, view: tuple[float, float]) -> np.ndarray:
    """(P, 3) points of a frontally placed face (column, row, height: pixels, ``align_to_eyes``) as the
    camera sees the head turned by ``view`` = (yaw, pitch) degrees (``view_rotation``) about its eye
    midpoint. eyes_px: (2, 3) the face's eye centres placed the same way."""
    p = np.asarray(points_px, np.float64)
    if tuple(view) == (0.0, 0.0):
        return p
    mid = np.asarray(eyes_px, np.float64).mean(axis=0)
    flip = np.array([1.0, -1.0, 1.0])  # rows down -> y up, and back
    return ((p - mid) * flip) @ view_rotation(*view).T * flip + mid


def render_mesh(vertices_px: np.ndarray, triangles: np.ndarray, grid: tuple[int, int]) -> np.ndarray:
    """Height field (H, W) of a mesh already in pixel coordinates; interior holes filled."""
    depth, _ = rasterize(vertices_px, triangles, grid)
    covered = np.isfinite(depth)
    region = ndimage.binary_fill_holes(covered)
    return fill_holes(depth, region).astype(np.float32)
