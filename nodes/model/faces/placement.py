"""Placing a face mesh on the canonical grid: its eye centres on the grid's canonical eye pixels,
then rendered as a height field. Shared by the mesh sources (eos models, mesh folders, ICT-FaceKit).

A turned head (``turn_to_view``): the frontally placed face turned by a yaw and a pitch about its
neck (``NECK_BEHIND_EYES`` behind its eyes), then moved in the image plane so its eye midpoint is back
on the canonical one; its scale stays. What the camera sees of it is then rendered as the frontal face
is (nearest surface wins: the far cheek behind the nose is hidden).
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


# the axis a head turns about, behind the eyes: the neck (the ICT neutral head's eyes are 8.5 cm in front of its
# origin, the back of its face area 3.2 cm behind it)
NECK_BEHIND_EYES = 9.0  # cm


def view_rotation(yaw_deg: float, pitch_deg: float) -> np.ndarray:
    """(3, 3) the rotation of a head turned ``yaw_deg`` (> 0 toward the image's right) and tilted
    ``pitch_deg`` (> 0 up), camera frame (x right, y up, z toward the viewer): ``Ry(yaw) Rx(-pitch)``,
    tilted first, then turned (``photo.faces.Pose``)."""
    a, b = np.radians(yaw_deg), np.radians(-pitch_deg)
    ry = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(b), -np.sin(b)], [0.0, np.sin(b), np.cos(b)]])
    return ry @ rx


def turn_to_view(points_px: np.ndarray, eyes_px: np.ndarray, view: tuple[float, float], px_per_cm: float) -> np.ndarray:
    """(P, 3) points of a frontally placed face (column, row, height: pixels, ``align_to_eyes``) as the
    camera sees the head turned by ``view`` = (yaw, pitch) degrees (``view_rotation``) about its neck,
    ``NECK_BEHIND_EYES`` behind the eye midpoint, its eye midpoint then moved back onto where it was in the
    image. eyes_px: (2, 3) the face's eye centres placed the same way; px_per_cm: the placement's scale."""
    p = np.asarray(points_px, np.float64)
    if tuple(view) == (0.0, 0.0):
        return p
    mid = np.asarray(eyes_px, np.float64).mean(axis=0)
    pivot = mid - [0.0, 0.0, NECK_BEHIND_EYES * px_per_cm]
    flip = np.array([1.0, -1.0, 1.0])  # rows down -> y up, and back
    r = view_rotation(*view)
    turned = ((p - pivot) * flip) @ r.T * flip + pivot
    eyes_turned = ((mid - pivot) * flip) @ r.T * flip + pivot
    return turned - [eyes_turned[0] - mid[0], eyes_turned[1] - mid[1], 0.0]


def render_mesh(vertices_px: np.ndarray, triangles: np.ndarray, grid: tuple[int, int]) -> np.ndarray:
    """Height field (H, W) of a mesh already in pixel coordinates; interior holes filled."""
    depth, _ = rasterize(vertices_px, triangles, grid)
    covered = np.isfinite(depth)
    region = ndimage.binary_fill_holes(covered)
    return fill_holes(depth, region).astype(np.float32)
