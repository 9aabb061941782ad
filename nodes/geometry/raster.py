"""Orthographic z-buffer rasterisation of triangle meshes, vectorised over triangles; polygons as masks."""
from __future__ import annotations

import cv2
import numpy as np

from .mask_cache import per_mask


def rasterize(
    vertices: np.ndarray,
    triangles: np.ndarray,
    shape: tuple[int, int],
    attributes: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Render the height (z) of a mesh seen from +z, nearest surface wins.

    vertices: (V, 3) in PIXEL coordinates: x = column, y = row (downward), z = height toward
    the viewer. triangles: (T, 3) int vertex indices. shape: (H, W) of the output.
    attributes: optional (V, C) per-vertex values interpolated on the visible surface.
    Pixel centres are at integer coordinates. Returns ``(depth (H, W) float64, NaN where
    empty; attr (H, W, C) or None)``.
    """
    h, w = shape
    v = np.asarray(vertices, np.float64)
    tri = np.asarray(triangles, np.int64)
    p0, p1, p2 = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    xmin = np.maximum(np.ceil(np.minimum(np.minimum(p0[:, 0], p1[:, 0]), p2[:, 0])), 0).astype(np.int64)
    xmax = np.minimum(np.floor(np.maximum(np.maximum(p0[:, 0], p1[:, 0]), p2[:, 0])), w - 1).astype(np.int64)
    ymin = np.maximum(np.ceil(np.minimum(np.minimum(p0[:, 1], p1[:, 1]), p2[:, 1])), 0).astype(np.int64)
    ymax = np.minimum(np.floor(np.maximum(np.maximum(p0[:, 1], p1[:, 1]), p2[:, 1])), h - 1).astype(np.int64)
    bw, bh = xmax - xmin + 1, ymax - ymin + 1
    keep = (bw > 0) & (bh > 0)
    area = (p1[:, 0] - p0[:, 0]) * (p2[:, 1] - p0[:, 1]) - (p2[:, 0] - p0[:, 0]) * (p1[:, 1] - p0[:, 1])
    keep &= np.abs(area) > 1e-12

    pix_chunks, z_chunks, tri_chunks, bary_chunks = [], [], [], []
    idx_all = np.nonzero(keep)[0]
    # Group triangles by bounding-box size so each group is one dense vectorised test.
    sizes = np.maximum(bw[idx_all], bh[idx_all])
    buckets = 2 ** np.ceil(np.log2(sizes)).astype(np.int64)
    for size in np.unique(buckets):
        grp = idx_all[buckets == size]
        step = max(1, 2_000_000 // int(size * size))
        for start in range(0, len(grp), step):
            g = grp[start:start + step]
            oy, ox = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
            px = xmin[g, None] + ox.ravel()[None, :]
            py = ymin[g, None] + oy.ravel()[None, :]
            a, b, c = p0[g], p1[g], p2[g]
            ar = area[g][:, None]
            w0 = ((b[:, 0, None] - px) * (c[:, 1, None] - py) - (c[:, 0, None] - px) * (b[:, 1, None] - py)) / ar
            w1 = ((c[:, 0, None] - px) * (a[:, 1, None] - py) - (a[:, 0, None] - px) * (c[:, 1, None] - py)) / ar
            w2 = 1.0 - w0 - w1
            inside = (w0 >= -1e-9) & (w1 >= -1e-9) & (w2 >= -1e-9)
            inside &= (px <= xmax[g, None]) & (py <= ymax[g, None])
            ti, ki = np.nonzero(inside)
            if ti.size == 0:
                continue
            bary = np.stack([w0[ti, ki], w1[ti, ki], w2[ti, ki]], axis=1)
            z = bary[:, 0] * a[ti, 2] + bary[:, 1] * b[ti, 2] + bary[:, 2] * c[ti, 2]
            pix_chunks.append(py[ti, ki] * w + px[ti, ki])
            z_chunks.append(z)
            tri_chunks.append(g[ti])
            bary_chunks.append(bary)

    depth = np.full(h * w, np.nan)
    attr_img = None
    if attributes is not None:
        attributes = np.asarray(attributes, np.float64).reshape(len(v), -1)
        attr_img = np.full((h * w, attributes.shape[1]), np.nan)
    if not pix_chunks:
        return depth.reshape(h, w), None if attr_img is None else attr_img.reshape(h, w, -1)
    pix = np.concatenate(pix_chunks)
    z = np.concatenate(z_chunks)
    # z-buffer: for each pixel keep the fragment with the largest z (nearest the viewer)
    order = np.lexsort((-z, pix))
    first = np.ones(len(order), bool)
    first[1:] = pix[order][1:] != pix[order][:-1]
    win = order[first]
    depth[pix[win]] = z[win]
    if attr_img is not None:
        tri_id = np.concatenate(tri_chunks)[win]
        bary = np.concatenate(bary_chunks)[win]
        corners = attributes[tri[tri_id]]  # (F, 3, C)
        attr_img[pix[win]] = np.einsum("fk,fkc->fc", bary, corners)
    return depth.reshape(h, w), None if attr_img is None else attr_img.reshape(h, w, -1)


def grid_mesh(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of the pixel grid inside ``mask``.

    mask: (H, W) bool. Returns ``(pixel_index (V,) flat indices of the vertices,
    triangles (T, 3) into that vertex list)``: each 2x2 block with 3 or 4 mask pixels gives
    one or two triangles, wound counter-clockwise as seen from +z (y up). Kept per mask
    (read-only, ``geometry.mask_cache``).
    """
    return per_mask("grid mesh", mask, _grid_mesh)


def _grid_mesh(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    h, w = mask.shape
    m = np.asarray(mask, bool)
    vid = np.full((h, w), -1, np.int64)
    pix = np.flatnonzero(m)
    vid.flat[pix] = np.arange(len(pix))
    a, b = vid[:-1, :-1], vid[:-1, 1:]  # top-left, top-right
    c, d = vid[1:, :-1], vid[1:, 1:]  # bottom-left, bottom-right
    tris = []
    # In image rows (downward) a counter-clockwise triangle seen with y up is clockwise in (col,row).
    full = (a >= 0) & (b >= 0) & (c >= 0) & (d >= 0)
    tris.append(np.stack([a[full], c[full], b[full]], 1))
    tris.append(np.stack([b[full], c[full], d[full]], 1))
    for p, q, r, cond in (
        (a, c, b, (a >= 0) & (b >= 0) & (c >= 0) & (d < 0)),
        (b, c, d, (a < 0) & (b >= 0) & (c >= 0) & (d >= 0)),
        (a, c, d, (a >= 0) & (b < 0) & (c >= 0) & (d >= 0)),
        (a, d, b, (a >= 0) & (b >= 0) & (c < 0) & (d >= 0)),
    ):
        tris.append(np.stack([p[cond], q[cond], r[cond]], 1))
    tris = np.concatenate(tris).astype(np.int64)
    pix.flags.writeable = tris.flags.writeable = False
    return pix, tris


def grid_row_edges(mask: np.ndarray) -> np.ndarray:
    """(E, 2) vertex pairs (into ``grid_mesh(mask)``'s vertices, left then right) of the mesh's
    horizontal edges: row neighbours that share a triangle. Kept per mask like the mesh."""
    return per_mask("grid row edges", mask, _grid_row_edges)


def _grid_row_edges(mask: np.ndarray) -> np.ndarray:
    pix, tris = grid_mesh(mask)
    rows = pix // mask.shape[1]
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    e = np.sort(e[rows[e[:, 0]] == rows[e[:, 1]]], axis=1)  # same row: left vertex has the lower index
    k = np.unique(e[:, 0] * len(pix) + e[:, 1])  # each shared edge once
    edges = np.column_stack([k // len(pix), k % len(pix)])
    edges.flags.writeable = False
    return edges


def rasterize_row_edges(vertices: np.ndarray, edges: np.ndarray, shape: tuple[int, int],
                        attributes: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """``rasterize`` for meshes whose vertices all lie on pixel rows (integer y), such as
    ``grid_mesh`` turned about the vertical axis: pixel centres then meet the triangles only on
    their horizontal edges (``grid_row_edges``, (E, 2) vertex pairs), so rendering is 1-D
    interpolation along those edges, z-buffered. Otherwise the arguments and result of
    ``rasterize`` (which it matches to rounding), in O(fragments)."""
    h, w = shape
    v = np.asarray(vertices, np.float64)
    if not np.array_equal(v[:, 1], np.round(v[:, 1])):
        raise ValueError("rasterize_row_edges needs every vertex on a pixel row; use rasterize")
    a, b = np.asarray(edges, np.int64).T
    swap = v[a, 0] > v[b, 0]
    a, b = np.where(swap, b, a), np.where(swap, a, b)  # left to right on screen
    x0, x1 = v[a, 0], v[b, 0]
    row = v[a, 1].astype(np.int64)
    c0 = np.maximum(np.ceil(x0 - 1e-9), 0).astype(np.int64)
    c1 = np.minimum(np.floor(x1 + 1e-9), w - 1).astype(np.int64)
    ok = (row >= 0) & (row < h)
    count = np.where(ok, np.maximum(c1 - c0 + 1, 0), 0)
    depth = np.full(h * w, np.nan)
    attr_img = None
    if attributes is not None:
        attributes = np.asarray(attributes, np.float64).reshape(len(v), -1)
        attr_img = np.full((h * w, attributes.shape[1]), np.nan)
    if count.sum() == 0:
        return depth.reshape(h, w), None if attr_img is None else attr_img.reshape(h, w, -1)
    e = np.repeat(np.arange(len(a)), count)
    col = c0[e] + np.arange(len(e)) - np.repeat(np.cumsum(count) - count, count)
    span = x1[e] - x0[e]
    t = np.clip(np.divide(col - x0[e], span, out=np.zeros(len(e)), where=span > 1e-12), 0.0, 1.0)
    z = v[a[e], 2] + t * (v[b[e], 2] - v[a[e], 2])
    pix = row[e] * w + col
    order = np.lexsort((-z, pix))  # z-buffer: the largest z (nearest the viewer) per pixel
    first = np.ones(len(order), bool)
    first[1:] = pix[order][1:] != pix[order][:-1]
    win = order[first]
    depth[pix[win]] = z[win]
    if attr_img is not None:
        tw = t[win][:, None]
        attr_img[pix[win]] = (1 - tw) * attributes[a[e[win]]] + tw * attributes[b[e[win]]]
    return depth.reshape(h, w), None if attr_img is None else attr_img.reshape(h, w, -1)


def polygon_mask(points: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) bool: the pixels whose centres lie inside the polygon ``points`` (n, 2) ``(x, y)``
    (column, row), vertices placed to 1/16 pixel."""
    shift = 4
    pts = np.round(np.asarray(points, np.float64) * (1 << shift)).astype(np.int32)
    out = np.zeros(shape, np.uint8)
    cv2.fillPoly(out, [pts], 1, lineType=cv2.LINE_8, shift=shift)
    return out.astype(bool)
