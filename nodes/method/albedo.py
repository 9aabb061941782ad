"""Albedo from the image and the recovered shape (Smith & Hancock, section 4.1 and 5.2).

``smooth_albedo``: the slowly varying part of the skin's albedo, which the fit divides out of
the image before it fits on (``FitConfig.albedo_rounds``). ``estimate_albedo``: the output map.
Where the surface is lit, ``albedo = I / (n . s)``. Under cast or attached shadow, or where
``n . s`` is too small for the division to be trusted, the value is taken from the mirror
pixel across the face's vertical axis (the paper's "facial symmetry" fill-in) when that one
is trusted; what is still missing is filled smoothly (harmonic interpolation). Unlike the paper,
a filled value is never brighter than the face's typical measured albedo (``FILL_CEILING``).
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..geometry.integrate import harmonic_fill

# Shading ``n . s`` below which dividing by it is not trusted: it amplifies errors of the normals and of
# the ambient light (docs/tuning.md, "Albedo"). Shared by the output albedo and the fit's smooth-albedo rounds.
MIN_SHADING = 0.4
# Filled (mirrored or interpolated) albedo is at most this x the median measured albedo. A measured value
# above the face's typical skin is more often shine or a normal turned too far from the light (a small
# n . s divided by) than brighter skin, and the other side of the face need not share it; the face's real
# detail is darker than its skin (brows, eyes, lips, nostrils), which the ceiling keeps (docs/tuning.md,
# "Albedo"). None: the paper's fill, values as measured.
FILL_CEILING = 1.0


def smooth_albedo(grid_mask: np.ndarray, intensity: np.ndarray, shading: np.ndarray, trusted: np.ndarray,
                  sigma_px: float, min_cover: float = 0.05) -> np.ndarray:
    """Smooth relative albedo over the N pixels of ``grid_mask`` (H, W): a normalised Gaussian
    average (``sigma_px`` model pixels) of ``intensity / shading`` over the ``trusted`` (N,)
    pixels, divided by its median there, so that 1 is the face's typical skin.

    intensity, shading (N,): brightness and ``n . s`` of a fitted shape. Pixels with less
    than ``min_cover`` of trusted weight around them (deep shadow) get 1. Returns (N,) in
    [1/3, 3]: dividing the image by it removes slow albedo changes, not the shading they sit on
    (the fitted shape's own shading is what the ratio divides out).
    """
    m = np.asarray(grid_mask, bool)
    t = np.asarray(trusted, bool)
    if t.sum() < 10:
        return np.ones(t.shape)
    ratio = np.zeros(m.shape)
    ratio[m] = np.where(t, np.asarray(intensity, np.float64) / np.maximum(shading, 1e-6), 0.0)
    cover = np.zeros(m.shape)
    cover[m] = t
    num = ndimage.gaussian_filter(ratio, sigma_px, mode="constant")[m]
    den = ndimage.gaussian_filter(cover, sigma_px, mode="constant")[m]
    albedo = np.where(den >= min_cover, num / np.maximum(den, 1e-12), np.nan)
    typical = np.nanmedian(albedo[t])
    return np.clip(np.nan_to_num(albedo / typical, nan=1.0), 1.0 / 3.0, 3.0)


def estimate_albedo(
    image: np.ndarray,
    normals: np.ndarray,
    light: np.ndarray,
    lit: np.ndarray,
    mask: np.ndarray,
    axis_col: float | np.ndarray,
    min_shading: float = MIN_SHADING,
    symmetric_fill: bool = True,
    boundary_px: int = 1,
    fill_ceiling: float | None = FILL_CEILING,
) -> tuple[np.ndarray, np.ndarray]:
    """Albedo map and how each pixel got its value.

    image (H, W) brightness in [0, 1]; normals (H, W, 3) camera frame; light (3,) unit;
    lit (H, W) bool (not in cast or attached shadow); mask (H, W) bool face;
    axis_col: column of the face's vertical symmetry axis (model grid), or (N,) int the mirror pixel of each
    of the N mask pixels (an index into them, -1: none; a turned face's, ``ShapeModel.mirror``). boundary_px: pixels
    this close to a predicted shadow are not trusted either (a shadow edge a pixel off
    would otherwise leave a black seam of albedo near 0). min_shading: see ``MIN_SHADING``;
    fill_ceiling: see ``FILL_CEILING`` (None: the paper's fill).
    Returns ``(albedo (H, W) float32, NaN off the mask; source (H, W) uint8:
    0 off-face, 1 measured, 2 mirrored, 3 smoothly filled)``.
    """
    m = np.asarray(mask, bool)
    shading = np.einsum("hwc,c->hw", np.nan_to_num(normals), np.asarray(light, np.float64))
    lit_core = ndimage.binary_erosion(lit, iterations=boundary_px, border_value=1) if boundary_px > 0 else lit
    trusted = m & lit_core & (shading >= min_shading)
    albedo = np.full(m.shape, np.nan)
    albedo[trusted] = np.asarray(image, np.float64)[trusted] / shading[trusted]
    source = np.where(trusted, 1, 0).astype(np.uint8)
    todo = m & ~trusted
    if symmetric_fill and todo.any():
        rows, cols = np.nonzero(todo)
        if np.ndim(axis_col) == 0:
            mr, mc = rows, np.rint(2.0 * axis_col - cols).astype(np.int64)
            ok = (mc >= 0) & (mc < m.shape[1])
        else:  # the mirror pixels of a turned face
            index = np.full(m.shape, -1, np.int64)
            index[m] = np.arange(int(m.sum()))
            mirror_flat = np.flatnonzero(m)[np.maximum(np.asarray(axis_col)[index[rows, cols]], 0)]
            mr, mc = np.divmod(mirror_flat, m.shape[1])
            ok = np.asarray(axis_col)[index[rows, cols]] >= 0
        ok[ok] = trusted[mr[ok], mc[ok]]
        albedo[rows[ok], cols[ok]] = albedo[mr[ok], mc[ok]]
        source[rows[ok], cols[ok]] = 2
        todo[rows[ok], cols[ok]] = False
    if todo.any():
        filled = harmonic_fill(np.where(m, albedo, np.nan), todo)
        albedo[todo] = filled[todo]
        source[todo] = 3
    if fill_ceiling is not None and trusted.any():
        ceiling = fill_ceiling * float(np.median(albedo[trusted]))
        albedo = np.where(source >= 2, np.minimum(albedo, ceiling), albedo)
    albedo = np.where(m, np.clip(albedo, 0.0, None), np.nan)
    return albedo.astype(np.float32), source
