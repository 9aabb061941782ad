"""The albedo the relighting knows beyond what the photo shows lit: the skin's albedo carried over the face by
the fit's map (``expected_albedo``), what a fill paints with where the photo holds no signal, and the face's
detail seen across its midline (``mirrored_detail``) that such a fill takes, so it is not a flat tone.

Arrays are on the photo's pixel grid (H, W[, C]), linear.
"""
from __future__ import annotations

import cv2
import numpy as np

from ..photo.align import Alignment, scalar_to_input
from .fields import brightness, local_average, smoothstep, weighted_blur

# lit skin brighter than this x its median is shine, not measured for the expected albedo; which is never brighter
# than this percentile of the lit skin's
SHINY = 1.3
CEILING = 90.0
# a filled pixel's detail seen across the face is kept within this range of its local level (``mirrored_detail``)
DETAIL_RANGE = (0.5, 2.0)
# the albedo of the side the light reaches less is raised toward its mirror's (``mirror_raise``), both averaged
# over this many interocular distances, by at most this factor, where the trusted skin around either covers
# this share (a ramp); not within this many interocular distances of the face's midline; as far as a new light
# brightens the pixel, S' / S over this ramp (docs/relighting.md)
LIFT_SIGMA = 0.06
LIFT_CAP = 1.6
LIFT_SUPPORT = (0.2, 0.4)
LIFT_AXIS = 0.05
LIFT_AMPLIFICATION = (1.0, 1.2)
LIFT_STEP = 4.0  # the lift is computed on a grid of sigma / this pixels (at least the box's)


def expected_albedo(photo: np.ndarray, lighting: np.ndarray, lit_skin: np.ndarray, coarse: np.ndarray,
                    face: np.ndarray, sigma_px: float) -> np.ndarray:
    """(H, W, C) float32 the skin's albedo the relighting expects at each face pixel, smooth: the fit's albedo
    map ``coarse`` (H, W, on the photo's grid, NaN off ``face``) brought to the level and colour of the skin the
    photo shows lit (``lit_skin`` (H, W) bool: ``I / lighting`` there, ``lighting`` (H, W) the fitted shading with
    the room's light; its shine left out: brighter than ``SHINY`` x the lit skin's median), matched over ``sigma_px``
    photo pixels (coarse to fine, ``local_average``), the face's median ratio where no lit skin is near, and never
    brighter than the lit skin's ``CEILING`` percentile. NaN off ``face``. It says what a shadowed pixel's skin would
    show lit, and is what a fill paints with (in the fit's own detail, the coarse map's)."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    measured = img / np.maximum(np.asarray(lighting, np.float32), np.float32(1e-3))[..., None]
    fill = float(np.nanmedian(coarse[face])) if face.any() else 1.0
    base = np.maximum(np.nan_to_num(np.asarray(coarse, np.float32), nan=fill), np.float32(1e-3))
    ratio = measured / base[..., None]
    use = np.asarray(lit_skin, bool) & face
    if use.sum() < 20:
        return np.where(face[..., None], base[..., None] * np.ones_like(ratio), np.nan).astype(np.float32)
    level = brightness(measured)
    use &= level <= np.float32(SHINY) * np.float32(np.median(level[use]))  # a highlight is the light's, not the skin's
    typical = np.median(ratio[use], axis=0)
    gain = local_average(ratio, use.astype(np.float32), sigma_px, np.broadcast_to(typical, ratio.shape))
    out = base[..., None] * gain
    ceiling = np.percentile(measured[use], CEILING, axis=0).astype(np.float32)
    return np.where(face[..., None], np.minimum(out, ceiling), np.nan).astype(np.float32)


def smooth_coarse(coarse: np.ndarray, face: np.ndarray, sigma_px: float) -> np.ndarray:
    """(H, W) the fit's albedo map ``coarse`` (on the photo grid, NaN off ``face``) averaged over a
    Gaussian of ``sigma_px`` photo pixels within ``face`` (normalised there, so a constant stays
    constant up to the face's edge); NaN off ``face``.

    The fit's map lives on the model grid, whose pixels are 1-3 photo pixels on a portrait. Brought
    to the photo as it is, the steps where its measured, mirrored and filled parts meet show in the
    fill as a staircase of the model grid's pixels (about a model pixel is what it takes; its detail
    is no finer than that anyway, and the photo's own detail is kept where it is measured)."""
    f = np.asarray(face, bool)
    values = np.where(f, np.nan_to_num(np.asarray(coarse, np.float32)), np.float32(0.0))
    average, _ = weighted_blur(values, f.astype(np.float32), sigma_px)
    return np.where(f, average, np.nan).astype(np.float32)


def reflection_map(shape: tuple[int, int], midline: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(map_x, map_y), each (H, W) float32: where each pixel of an (H, W) box falls when mirrored across the
    line through the two points ``midline`` (2, 2) ``[x, y]`` of the box (a face's vertical symmetry axis),
    for ``cv2.remap``."""
    a = np.asarray(midline[0], np.float64)
    d = np.asarray(midline[1], np.float64) - a
    d /= max(float(np.linalg.norm(d)), 1e-9)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    px, py = xx - a[0], yy - a[1]
    t = px * d[0] + py * d[1]
    return (a[0] + 2.0 * t * d[0] - px).astype(np.float32), (a[1] + 2.0 * t * d[1] - py).astype(np.float32)


def mirror_map(mask: np.ndarray, mirror: np.ndarray, to_box: Alignment, shape: tuple[int, int]
               ) -> tuple[np.ndarray, np.ndarray]:
    """(map_x, map_y), each (h, w) float32: where each pixel of a face's box falls mirrored across the face, for
    ``cv2.remap``, through the model grid: ``mirror`` (N,) int, each of the N pixels of the model's ``mask`` (Hm, Wm)
    bool, its mirror's index among them (-1: none; a turned face's, ``ShapeModel.mirror``), brought to the box's
    pixels by ``to_box`` (an ``Alignment``: model pixel -> box pixel; its field reaches a little past the mask, NaN
    beyond: mapped to -1, off the box). A frontal face's is ``reflection_map``."""
    rows, cols = np.nonzero(mask)
    index = np.asarray(mirror, np.int64)
    target_row = np.full(mask.shape, np.nan, np.float32)
    target_col = np.full(mask.shape, np.nan, np.float32)
    seen = index >= 0
    target_row[rows[seen], cols[seen]] = rows[index[seen]]
    target_col[rows[seen], cols[seen]] = cols[index[seen]]
    known = np.isfinite(target_row)
    r = scalar_to_input(target_row, known, to_box, shape)
    c = scalar_to_input(target_col, known, to_box, shape)
    m = to_box.matrix
    x = m[0, 0] * c + m[0, 1] * r + m[0, 2]
    y = m[1, 0] * c + m[1, 1] * r + m[1, 2]
    return np.nan_to_num(x, nan=-1.0).astype(np.float32), np.nan_to_num(y, nan=-1.0).astype(np.float32)


def mirrored(values: np.ndarray, trust: np.ndarray, mirror: tuple[np.ndarray, np.ndarray]
             ) -> tuple[np.ndarray, np.ndarray]:
    """The face seen across its midline: ``values`` (h, w, C) and ``trust`` (h, w) in [0, 1] at each pixel's mirror
    (``mirror``: a ``reflection_map`` or ``mirror_map``), 0 trust where the mirror falls off the box."""
    v = np.ascontiguousarray(np.atleast_3d(values), np.float32)
    out = cv2.remap(v, mirror[0], mirror[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    t = cv2.remap(np.ascontiguousarray(trust, np.float32), mirror[0], mirror[1], cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return out.reshape(v.shape), np.clip(t, 0.0, 1.0)


def axis_distance(shape: tuple[int, int], axis: np.ndarray) -> np.ndarray:
    """(H, W) float32: each pixel's distance, in pixels, from the line through the two points ``axis``
    (2, 2) ``[x, y]`` of an (H, W) box."""
    a = np.asarray(axis[0], np.float64)
    d = np.asarray(axis[1], np.float64) - a
    d /= max(float(np.linalg.norm(d)), 1e-9)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    return np.abs((xx - a[0]) * d[1] - (yy - a[1]) * d[0]).astype(np.float32)


def mirrored_detail(measured: np.ndarray, weight: np.ndarray, mirror: tuple[np.ndarray, np.ndarray],
                    fine_px: float, coarse_px: float) -> tuple[np.ndarray, np.ndarray]:
    """The measured albedo's detail seen across the face, for a fill that has none of its own.

    measured (H, W, C) ``I / lighting``; weight (H, W) in [0, 1] how far it is trusted; mirror: the
    ``reflection_map`` of the box. The detail is a band of the measured albedo, its average over
    ``fine_px`` over its average over ``coarse_px`` (trusted pixels only; the coarse scale is what the
    fit's map already holds, the fine one leaves out pores and noise, which a mirror would only add to the
    other side's own), in [``DETAIL_RANGE``]; 1 where nothing is trusted. Returns (detail (H, W, C) of the
    mirror pixel, its trust (H, W): the mirror pixel's weight, as a ramp from 0.5 to 1)."""
    w = np.asarray(weight, np.float32)
    coarse, _ = weighted_blur(measured, w, coarse_px)
    fine = weighted_blur(measured, w, fine_px)[0] if fine_px > 0 else np.asarray(measured, np.float32)
    band = np.where((w > 0.5)[..., None], fine / np.maximum(coarse, np.float32(1e-4)), np.float32(1.0))
    band = np.clip(band, *DETAIL_RANGE).astype(np.float32)
    seen = cv2.remap(band, mirror[0], mirror[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=1.0).reshape(band.shape)
    trust = cv2.remap(w, mirror[0], mirror[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return seen, np.clip(2.0 * trust - 1.0, 0.0, 1.0).astype(np.float32)


def mirror_raise(albedo: np.ndarray, weight: np.ndarray, axis: np.ndarray, shading: np.ndarray, sigma_px: float,
                reach: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How much the albedo of the side a photo's light reaches less may be raised toward its mirror pixel's across
    the face's ``axis`` (2, 2) ``[x, y]`` (``reflection_map``): ``(ratio (H, W, C) in [1, LIFT_CAP], strength (H, W)
    in [0, 1])``, the raise being ``ratio ** (strength x how far a new light brightens the pixel)`` (``lifted``).
    ``ratio``: the mirror's level over the pixel's, both averaged over ``sigma_px`` (``weighted_blur`` by ``weight``
    (H, W), the trusted skin).

    An error ``e`` in the fitted shading ``S`` leaves ``e / S`` in ``I / S``, and the fitted normals of the far flank
    of the nose and the cheek beyond it lean toward the light (the model's surface is smoother than a face): their
    albedo holds a shadow the relighting then brightens by ``S' / S``. A face's albedo is nearly symmetric at this
    scale, and the mirror pixel, lit more, is measured with a smaller error. ``strength``: how much less lit the pixel
    is than its mirror, ``(S_m - S) / S_m``, times ``reach`` (H, W) in [0, 1] (0 where the mirror says nothing: near
    the midline, off the face), where the trusted skin around both covers ``LIFT_SUPPORT``. albedo (H, W, C); shading
    (H, W) ``S`` with the room's light. Smooth fields: computed on a grid ``LIFT_STEP`` times finer than ``sigma_px`` (a
    4-megapixel face's box a ninth of its pixels), then brought back (bilinear)."""
    a = np.nan_to_num(np.asarray(albedo, np.float32))  # NaN off the face
    h, w = a.shape[:2]
    step = max(1, int(sigma_px // LIFT_STEP))
    hs, ws = h // step, w // step
    if min(hs, ws) < 2:
        step, hs, ws = 1, h, w

    def small(v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, np.float32)[:hs * step, :ws * step]
        return v if step == 1 else cv2.resize(v, (ws, hs), interpolation=cv2.INTER_AREA).reshape((hs, ws) + v.shape[2:])

    wt = small(weight)
    mean = small(a * np.asarray(weight, np.float32)[..., None]) / np.maximum(wt, np.float32(1e-12))[..., None]
    level, around = weighted_blur(mean, wt, sigma_px / step)
    # pixel centres: a small pixel's is (i + 0.5) step - 0.5 of the box's
    mirror = reflection_map((hs, ws), (np.asarray(axis, np.float64) + 0.5) / step - 0.5)

    def across(v: np.ndarray) -> np.ndarray:
        return cv2.remap(v, mirror[0], mirror[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                         borderValue=0.0).reshape(v.shape)

    s = small(shading)
    s_seen = across(s)
    strength = np.clip((s_seen - s) / np.maximum(s_seen, np.float32(1e-3)), 0.0, 1.0) * small(reach)
    # measured on both sides: the trusted skin around the pixel and around its mirror
    strength *= smoothstep(around, *LIFT_SUPPORT) * smoothstep(across(around), *LIFT_SUPPORT)
    ratio = np.clip(across(level) / np.maximum(level, np.float32(1e-4)), 1.0, LIFT_CAP)
    return _full(ratio, step, (h, w)), _full(strength, step, (h, w))


def _full(values: np.ndarray, step: int, shape: tuple[int, int]) -> np.ndarray:
    """(H, W[, C]) a field computed on a grid ``step`` times coarser brought back to ``shape`` (bilinear; the last rows
    and columns past a whole step take the edge's)."""
    v = np.asarray(values, np.float32)
    if step > 1:
        v = cv2.resize(v, (v.shape[1] * step, v.shape[0] * step), interpolation=cv2.INTER_LINEAR).reshape(
            (v.shape[0] * step, v.shape[1] * step) + v.shape[2:])
    pad = ((0, shape[0] - v.shape[0]), (0, shape[1] - v.shape[1])) + ((0, 0),) * (v.ndim - 2)
    return np.pad(v, pad, mode="edge") if v.shape[:2] != tuple(shape) else v


def lifted(ratio: np.ndarray, strength: np.ndarray, amplification: np.ndarray) -> np.ndarray:
    """(H, W, C) float32 >= 1: ``mirror_raise``'s raise under a new light that brightens each pixel by
    ``amplification`` (H, W) (``S' / S``, over ``LIFT_AMPLIFICATION``): a photo relit with its own light keeps its own
    pixels."""
    k = np.asarray(strength, np.float32) * smoothstep(amplification, *LIFT_AMPLIFICATION)
    return np.power(np.asarray(ratio, np.float32), k[..., None]).astype(np.float32)
