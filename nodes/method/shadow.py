"""Shadow caster: cast and attached shadows of a height field under a distant light."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class ShadowMaps:
    """``cast``: (H, W) bool, light blocked by another part of the surface (and facing it);
    ``attached``: (H, W) bool, surface facing away from the light (n . s <= 0); ``near``: (H, W) bool,
    the part of ``cast`` found only from rays the surface nearly blocks (``near_cast``), or None."""

    cast: np.ndarray
    attached: np.ndarray
    near: np.ndarray | None = None

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
    return _march(depth, light, bias, sources, 0.0) > 0.0


# a relit photo's cast shadow: its edge ramps over this margin either side (pixels of height, ``cast_margin``), which
# at a light 45 degrees from the view axis is about a model pixel's width across the edge
SOFT_CAST_REACH = 0.5


def cast_margin(depth: np.ndarray, light: np.ndarray, bias: float = 0.05, reach: float = SOFT_CAST_REACH) -> np.ndarray:
    """How far each pixel's ray toward the light passes under the height field: the most the surface rises
    above it along the way, less ``bias``, in pixels of height, within [-``reach``, ``reach``]; > 0 exactly
    where ``cast_shadow`` is True. depth, light, bias as ``cast_shadow``. Returns (H, W) float32, NaN off
    the surface.

    Unlike the shadow's yes or no it is continuous across the shadow's edge, so a finer grid (a photo)
    interpolates it and thresholds it there (``soft_cast``): the edge runs between the model's pixels
    instead of as a staircase of them across the cheek."""
    margin = _march(depth, light, bias, None, reach)
    return np.where(np.isfinite(depth), np.clip(margin, -reach, reach), np.nan).astype(np.float32)


def soft_cast(margin: np.ndarray, reach: float = SOFT_CAST_REACH) -> np.ndarray:
    """(...) float32 in [0, 1]: how much of a pixel the cast shadow covers, from its interpolated
    ``cast_margin`` (a linear ramp over ``reach`` either side of the edge; 0 where NaN)."""
    return np.clip(0.5 + 0.5 * np.nan_to_num(margin, nan=-reach) / reach, 0.0, 1.0).astype(np.float32)


def _march(depth: np.ndarray, light: np.ndarray, bias: float, sources: np.ndarray | None,
           reach: float) -> np.ndarray:
    """(H, W) float64: each traced pixel's margin (``cast_margin``), marched until it is over ``reach``
    (a yes-or-no shadow: ``reach`` 0 stops at the first block), the ray is too high for any point to rise
    ``reach`` above it, or it leaves the grid; -inf where no step was taken or the pixel is not traced."""
    s = np.asarray(light, np.float64)
    z = np.asarray(depth, np.float64)
    valid = np.isfinite(z)
    out = np.full(z.shape, -np.inf)
    horiz = float(np.hypot(s[0], s[1]))
    if horiz < 1e-6 or not valid.any():
        return out  # a light on the view axis casts no visible shadow (orthographic camera)
    if s[2] <= 0:
        out[valid] = np.inf  # light behind the face plane: everything is dark
        return out
    d_col, d_row, rise = s[0] / horiz, -s[1] / horiz, s[2] / horiz
    low = np.nanmin(z) - 1e6  # empty pixels behave as a very low floor
    zf = np.where(valid, z, low)
    rows, cols = np.nonzero(valid if sources is None else valid & sources)
    top = np.nanmax(z) - bias + reach  # a ray above this stays over every point by more than the reach
    best = np.full(len(rows), -np.inf)
    h, w = z.shape
    # the rays still marching, compacted as they end: each step costs what its live rays do (15 % less time
    # than masking the full arrays each step)
    live, z0, r0, c0 = np.arange(len(rows)), z[rows, cols], rows.astype(np.float64), cols.astype(np.float64)
    t = 1.0
    while live.size:
        ray = z0 + t * rise
        r = r0 + t * d_row
        c = c0 + t * d_col
        going = (ray < top) & (r >= 0) & (r <= h - 1) & (c >= 0) & (c <= w - 1)
        if not going.all():
            live, z0, r0, c0, ray, r, c = (a[going] for a in (live, z0, r0, c0, ray, r, c))
            if not live.size:
                break
        # zs - (ray + bias) > 0 exactly when zs > ray + bias (IEEE subtraction is never 0 between unequal values)
        margin = ndimage.map_coordinates(zf, [r, c], order=1, mode="nearest") - (ray + bias)
        if reach > 0:
            best[live] = np.maximum(best[live], margin)
            done = best[live] > reach
        else:  # yes or no: a ray ends at its first block, and only a block's margin is kept
            done = margin > 0.0
            best[live[done]] = margin[done]
        if done.any():
            live, z0, r0, c0 = (a[~done] for a in (live, z0, r0, c0))
        t += 1.0
    out[rows, cols] = best
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


def far_darker(intensity: np.ndarray, shading: np.ndarray, face: np.ndarray, relative: float = 0.45,
               min_shading: float = 0.4, floor: float = 0.0) -> np.ndarray:
    """(H, W) bool: face pixels far darker than the shape lets them be, ``I < relative x rho x S``,
    with ``rho`` the face's typical albedo (the median of ``I / S`` where ``S >= min_shading``)
    and ``S = max(n . s, 0)``. A photo's shadows keep some ambient light, so they are far darker
    than predicted without being black; dark skin (brows, beard) is too, and is told apart from
    shadow by connection to the shape's own shadows (``confirm_with_image``).
    intensity, shading (H, W); face (H, W) bool. floor: the shading is taken as at least this, so a
    pixel facing away from the light is dark only when it is dark in absolute terms too."""
    I = np.nan_to_num(np.asarray(intensity, np.float64))
    S = np.clip(np.nan_to_num(np.asarray(shading, np.float64)), 0.0, None)
    bright = face & (S >= min_shading)
    if bright.sum() < 20:
        return np.zeros_like(face)
    rho = float(np.median(I[bright] / S[bright]))
    return face & (I < relative * rho * np.maximum(S, floor))


def confirm_with_image(maps: ShadowMaps, intensity: np.ndarray, dark_threshold: float,
                       far_dark: np.ndarray | None = None) -> ShadowMaps:
    """Reconcile traced cast shadows with the image they must explain.

    A pixel clearly lit in the image (``intensity > dark_threshold``) cannot be in cast
    shadow, so it is removed; a dark pixel facing the light that is connected (8-neighbours,
    through dark pixels) to a traced cast shadow joins it. Dark pixels NOT connected to any
    traced shadow stay lit: they are dark albedo (brows, beard), the distinction the
    paper draws with the recovered shape. intensity (H, W) remapped brightness.
    far_dark (H, W) bool (``far_darker``): pixels far darker than predicted count as dark too, so
    a photo's real shadows, which ambient light keeps above ``dark_threshold``, are found; dark
    regions that run on from the attached side join the attached shadow (the real surface turns
    from the light sooner than the fitted one).
    """
    dark = np.asarray(intensity) <= dark_threshold
    if far_dark is not None:
        dark = dark | far_dark
    candidates = dark & ~maps.attached
    labels, _ = ndimage.label(candidates, structure=np.ones((3, 3), bool))
    seeds = np.unique(labels[maps.cast & dark])
    cast = np.isin(labels, seeds[seeds > 0]) & candidates
    attached = maps.attached
    if far_dark is not None:  # dark regions running on from the attached side: the surface turns away sooner
        beside = np.unique(labels[ndimage.binary_dilation(maps.attached) & candidates & ~cast])
        attached = attached | (np.isin(labels, beside[beside > 0]) & candidates & ~cast)
    return ShadowMaps(cast=cast, attached=attached)


# the fitted surface is smoother than a face and its nose lower: a ray toward the light passing over it by under this
# many pixels of travel (its height over the surface over its rise per pixel) may be blocked by the real one
# (``near_cast``; docs/relighting.md); a dark region so seeded that covers more than this share of the face is the
# face's own dark (a beard under a light from above: 7 % of it), not a narrow shadow (a nose's at 25 degrees, 0.3 %)
NEAR_CAST = 0.5
NEAR_CAST_AREA = 0.02
# ... nor within this many interocular distances of the lips, where a moustache or a goatee is (``near_cast_kept_out``)
NEAR_CAST_MOUTH = 0.2


def near_cast(maps: ShadowMaps, depth: np.ndarray, light: np.ndarray, intensity: np.ndarray, dark_threshold: float,
              far_dark: np.ndarray, features: np.ndarray | None = None, travel: float = NEAR_CAST,
              largest: float = NEAR_CAST_AREA) -> ShadowMaps:
    """Confirmed shadows ``maps`` (``confirm_with_image``) and the dark regions a ray nearly blocked seeds
    (also given alone, as ``near``).

    At a light near the view axis the nose casts a narrow shadow the fitted nose, too low, does not: no
    traced cast shadow seeds it, and its darkness stays in the albedo. Rays from the dark pixels are traced
    again, blocked where the surface comes within ``travel`` pixels of travel of them (``travel x`` their
    rise per pixel of height; at a grazing light, whose traced shadows already reach, that is little), and
    the dark regions they seed join the cast shadow, off ``features`` (H, W) bool grown by a pixel (the face
    mesh's eyes, brows and lips: dark by their albedo, which a guess must not claim; None: none) and each no
    larger than ``largest`` of the face (a larger one is the face's own dark: a beard). depth, light as
    ``shadow_maps``; intensity, dark_threshold, far_dark as ``confirm_with_image``."""
    s = np.asarray(light, np.float64)
    horiz = float(np.hypot(s[0], s[1]))
    if horiz < 1e-6 or s[2] <= 0:
        return maps
    off = np.zeros(np.shape(depth), bool) if features is None else ndimage.binary_dilation(features)
    dark = ((np.asarray(intensity) <= dark_threshold) | far_dark) & ~off & ~maps.attached & ~maps.cast
    if not dark.any():
        return maps
    near = cast_shadow(depth, s, bias=-travel * s[2] / horiz, sources=dark & np.isfinite(depth))
    seeded = confirm_with_image(ShadowMaps(near, maps.attached), np.where(off, np.inf, intensity), dark_threshold,
                                far_dark & ~off).cast & ~off & ~maps.attached
    labels, area = _component_areas(seeded)
    seeded &= (area <= largest * np.isfinite(depth).sum())[labels]
    return ShadowMaps(cast=maps.cast | seeded, attached=maps.attached, near=seeded)


def _component_areas(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``mask``'s 8-connected regions: (labels (H, W) int, 0 off the mask; each label's area in pixels)."""
    labels, n = ndimage.label(mask, structure=np.ones((3, 3), bool))
    return labels, np.bincount(labels.ravel(), minlength=n + 1)
