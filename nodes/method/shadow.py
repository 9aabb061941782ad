"""Shadow caster: cast and attached shadows of a height field under a distant light."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class ShadowMaps:
    """``cast``: (H, W) bool, light blocked by another part of the surface (and facing it);
    ``attached``: (H, W) bool, surface facing away from the light (n . s <= 0)."""

    cast: np.ndarray
    attached: np.ndarray

    @property
    def lit(self) -> np.ndarray:
        return ~(self.cast | self.attached)


def cast_shadow(depth: np.ndarray, light: np.ndarray, bias: float = 0.05,
                sources: np.ndarray | None = None) -> np.ndarray:
    """Pixels whose ray toward the light is blocked by the height field.

    depth: (H, W) height toward the viewer, pixel units, NaN off the surface (never blocks).
    light: (3,) unit, camera frame. A ray from each pixel rises ``s_z / |s_xy|`` per pixel
    of travel in the image toward ``(s_x, -s_y)`` (columns, rows); the pixel is shadowed if
    the (bilinearly interpolated) surface anywhere along it is higher than the ray by more
    than ``bias`` pixels. Marching is vectorised over pixels, one step per pixel of travel,
    and ends once the ray is above the highest point. ``sources`` (H, W) bool: trace only from
    these pixels (default: every surface pixel). Returns (H, W) bool (NaN pixels False).
    """
    s = np.asarray(light, np.float64)
    z = np.asarray(depth, np.float64)
    valid = np.isfinite(z)
    out = np.zeros(z.shape, bool)
    horiz = float(np.hypot(s[0], s[1]))
    if horiz < 1e-6 or not valid.any():
        return out  # a light on the view axis casts no visible shadow (orthographic camera)
    if s[2] <= 0:
        out[valid] = True  # light behind the face plane: everything is dark
        return out
    d_col, d_row, rise = s[0] / horiz, -s[1] / horiz, s[2] / horiz
    low = np.nanmin(z) - 1e6  # empty pixels behave as a very low floor
    zf = np.where(valid, z, low)
    rows, cols = np.nonzero(valid if sources is None else valid & sources)
    z0 = z[rows, cols]
    zmax = np.nanmax(z)
    blocked = np.zeros(len(rows), bool)
    h, w = z.shape
    t = 1.0
    while True:
        ray = z0 + t * rise
        active = ~blocked & (ray < zmax)
        if not active.any():
            break
        r = rows[active] + t * d_row
        c = cols[active] + t * d_col
        inside = (r >= 0) & (r <= h - 1) & (c >= 0) & (c <= w - 1)
        if not inside.any():
            break
        zs = ndimage.map_coordinates(zf, [r, c], order=1, mode="nearest")
        hit = inside & (zs > ray[active] + bias)
        idx = np.flatnonzero(active)
        blocked[idx[hit]] = True
        t += 1.0
    out[rows, cols] = blocked
    return out


def shadow_maps(depth: np.ndarray, normals: np.ndarray, light: np.ndarray, bias: float = 0.05,
                candidates: np.ndarray | None = None) -> ShadowMaps:
    """Cast and attached shadow maps of a surface. depth (H, W); normals (H, W, 3); light (3,).
    candidates (H, W) bool: the only pixels that may be in cast shadow (e.g. the dark ones of
    an image), so rays are traced from them alone; default every pixel."""
    facing = np.einsum("hwc,c->hw", np.nan_to_num(normals), np.asarray(light, np.float64))
    valid = np.isfinite(depth) & np.all(np.isfinite(normals), axis=-1)
    attached = valid & (facing <= 0)
    sources = valid & ~attached if candidates is None else valid & ~attached & candidates
    cast = cast_shadow(depth, light, bias=bias, sources=sources) & valid & ~attached
    return ShadowMaps(cast=cast, attached=attached)


def confirm_with_image(maps: ShadowMaps, intensity: np.ndarray, dark_threshold: float) -> ShadowMaps:
    """Reconcile traced cast shadows with the image they must explain.

    A pixel clearly lit in the image (``intensity > dark_threshold``) cannot be in cast
    shadow, so it is removed; a dark pixel facing the light that is connected (8-neighbours,
    through dark pixels) to a traced cast shadow joins it. Dark pixels NOT connected to any
    traced shadow stay lit: they are dark albedo (brows, beard), the distinction the
    paper draws with the recovered shape. intensity (H, W) remapped brightness.
    """
    dark = np.asarray(intensity) <= dark_threshold
    cast = maps.cast & dark
    candidates = dark & ~maps.attached
    labels, _ = ndimage.label(candidates, structure=np.ones((3, 3), bool))
    seeds = np.unique(labels[cast])
    grown = np.isin(labels, seeds[seeds > 0])
    return ShadowMaps(cast=grown & candidates, attached=maps.attached)
