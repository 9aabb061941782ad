"""Relighting, novel views and the textured mesh of a recovered face."""
from __future__ import annotations

import cv2
import numpy as np

from ..geometry.normals import normals_from_depth
from ..geometry.raster import grid_mesh, grid_row_edges, rasterize_row_edges
from ..geometry.reflectance import lambertian
from .shadow import cast_shadow

FRONTAL = np.array([0.0, 0.0, 1.0])


def relight(albedo: np.ndarray, normals: np.ndarray, light: np.ndarray = FRONTAL,
            depth: np.ndarray | None = None) -> np.ndarray:
    """The face under a new distant light: ``albedo * max(n . s, 0)``, with cast shadows.

    albedo (H, W); normals (H, W, 3) camera frame; light (3,) unit (default frontal);
    depth (H, W) pixel units, if given, casts shadows (none for a frontal light).
    Returns (H, W) float32, NaN off the face.
    """
    s = np.asarray(light, np.float64)
    s = s / np.linalg.norm(s)
    out = lambertian(normals, s, albedo)
    if depth is not None:
        out = np.where(cast_shadow(depth, s), np.float32(0.0), out)
    return out


EDGE_ON = 0.3  # a turned normal's z under this: a surface seen so edge-on it is a small part of its pixels


def novel_view(depth: np.ndarray, albedo: np.ndarray, yaw_deg: float = 45.0,
               light: np.ndarray = FRONTAL) -> np.ndarray:
    """Render the recovered surface turned ``yaw_deg`` about the vertical axis (z-buffered).

    The surface (pixel-unit heights, NaN off the face) is turned about the vertical line
    through its centroid; the light stays fixed in the camera frame, so the face is lit as
    a real head turned under the same lamp. albedo: (H, W) or (H, W, C) (colour) on the surface's
    grid. Returns (H, W) or (H, W, C) float32 in [0, 1], 0 background.
    """
    mask = np.isfinite(depth)
    h, w = depth.shape
    colours = np.asarray(albedo, np.float64).reshape(h * w, -1)
    pix, _ = grid_mesh(mask)
    rows, cols = np.divmod(pix, w)
    x, y, z = cols.astype(float), rows.astype(float), depth.flat[pix].astype(float)
    cx, cz = x.mean(), z.mean()
    a = np.radians(yaw_deg)
    c, s = np.cos(a), np.sin(a)
    xr = cx + c * (x - cx) + s * (z - cz)
    zr = cz - s * (x - cx) + c * (z - cz)
    # the surface's own normals, turned with it and interpolated like the albedo: normals taken from the
    # rendered heights would run across each occluding edge (the nose's profile over the far cheek) as a
    # wall, a dark crack down the face
    n = np.nan_to_num(normals_from_depth(depth).reshape(-1, 3)[pix].astype(np.float64))
    turned = np.column_stack([c * n[:, 0] + s * n[:, 2], n[:, 1], -s * n[:, 0] + c * n[:, 2]])
    attributes = np.column_stack([np.nan_to_num(colours[pix]), turned])
    _, attrs = rasterize_row_edges(np.column_stack([xr, y, zr]), grid_row_edges(mask), (h, w), attributes=attributes)
    k = colours.shape[1]
    normals = np.nan_to_num(attrs[..., k:])
    normals /= np.maximum(np.linalg.norm(normals, axis=-1, keepdims=True), 1e-12)
    s_light = np.asarray(light, np.float64) / np.linalg.norm(light)
    shade = np.clip(normals @ s_light, 0.0, None)
    img = np.nan_to_num(attrs[..., :k]) * shade[..., None]
    # a steep slope seen nearly edge-on (the nose's side beside the cheek it hides) covers a sliver of its
    # pixels, foreshortened by its normal's z: those pixels take their neighbours' shade, as an antialiased
    # edge would, not the slope's own (dark under a frontal light: a dotted crack down the nose)
    covered = np.isfinite(attrs[..., 0])
    edge_on = covered & (normals[..., 2] <= EDGE_ON)
    if edge_on.any():
        seen = (covered & ~edge_on).astype(np.float32)
        near = np.atleast_3d(cv2.GaussianBlur((img * seen[..., None]).astype(np.float32), (0, 0), 1.0)) / \
            np.maximum(cv2.GaussianBlur(seen, (0, 0), 1.0), 1e-6)[..., None]
        img = np.where(edge_on[..., None], near, img)
    out = np.clip(img, 0.0, 1.0).astype(np.float32)
    return out[..., 0] if np.ndim(albedo) == 2 else out


def resample_surface(depth: np.ndarray, albedo: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """The surface (heights in pixels, NaN off it) and its albedo ((H, W) or (H, W, C)) resampled to
    ``size`` x ``size`` (a square grid, as the model's): heights scale with the pixels."""
    h, w = depth.shape
    factor = size / max(h, w)
    out_hw = (max(1, int(round(w * factor))), max(1, int(round(h * factor))))
    valid = np.isfinite(depth).astype(np.float32)
    cover = cv2.resize(valid, out_hw, interpolation=cv2.INTER_LINEAR)
    d = cv2.resize(np.nan_to_num(depth).astype(np.float32), out_hw, interpolation=cv2.INTER_LINEAR)
    a = cv2.resize(np.nan_to_num(albedo).astype(np.float32), out_hw, interpolation=cv2.INTER_LINEAR)
    inside = cover >= 0.999
    return np.where(inside, d * factor, np.nan), np.where(inside if a.ndim == 2 else inside[..., None], a, np.nan)


def surface_mesh(depth: np.ndarray, albedo: np.ndarray) -> dict[str, np.ndarray]:
    """Mesh of a height field (NaN off the surface): vertices (V, 3) float32 (x = column,
    y = -row, z = height, pixels), triangles (T, 3) uint32 wound counter-clockwise seen from +z,
    grey colours (V, 3) uint8 from ``albedo`` clipped to [0, 1]."""
    pix, tris = grid_mesh(np.isfinite(depth))
    rows, cols = np.divmod(pix, depth.shape[1])
    grey = (np.clip(np.nan_to_num(albedo.ravel()[pix]), 0, 1) * 255).astype(np.uint8)
    return {"vertices": np.column_stack([cols, -rows, depth.ravel()[pix]]).astype(np.float32),
            "triangles": tris.astype(np.uint32), "colours": np.column_stack([grey, grey, grey])}
