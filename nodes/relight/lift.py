"""A face relit as the photo times a change of light: ``relit = I x G``, ``G = e L' / L_p``.

``L_p`` is the light the photo shows (``photo_light``): the fitted shading with the room's light, times what
the photo's own shadows leave (``evidence``), and never darker than the skin the photo shows says (where the
fitted shape turns from the light too soon, its shading is too dark: the skin there is lit). ``L'`` is the new
light's, ``e`` the exposure that keeps the photo's lit skin at its level. Both lights are smooth over the face
but for shadows' edges, so the photo's own texture (pores, stubble, freckles, a beard, make-up) is kept, and a
shadow is lifted by a smooth gain over it.

Only where the photo holds no usable signal (``signal``: at its noise floor) and the light is to be raised
there (``FILL_LIFT``) is a pixel painted (``fill_weight``): the expected albedo, with texture, under the new
light. A pixel the light leaves as it is keeps its own value, however dark (a pupil, a nostril).

The photo's shine (a highlight, the light's reflection) is taken out before the ratio and put back as far as
the new light keeps it (``shine.shine_kept``).

Arrays are on the face's box at the photo's resolution (h, w[, C]), linear.
"""
from __future__ import annotations

import numpy as np

from .fields import brightness, local_average, smoothstep, weighted_blur

# a file's values are known to about this much (0-1: 1.5 levels of 255 for quantisation, a sensor's and a JPEG's
# noise); lifted, that noise may show up to the first of ``NOISE_SHOWN`` and no more than the second (a ramp, in the
# file's own levels); a pixel lifted by more than the first of ``LIFTED`` must know its light to the first of ``RELATIVE_NOISE``
# of itself, and is noise past the second; its own texture is noise past ``TEXTURE_NOISE``
FILE_NOISE = 1.5 / 255.0
NOISE_SHOWN = (4.5 / 255.0, 9.0 / 255.0)
RELATIVE_NOISE = (0.15, 0.3)
LIFTED = (1.5, 2.0)
TEXTURE_NOISE = (0.05, 0.15)
# a pixel lifted by more than the first of these takes the colour of the albedo a fill would paint, fully past the
# second (``relit_face``)
CHROMA_LIFT = (3.0, 10.0)
# the change of light never lifts a pixel more than this (a deeper shadow is filled)
MAX_GAIN = 16.0
# the photo is kept as it is under a new light this many degrees from the photo's, and relit fully from the second on
# (``shadows_kept``); an elevation's degrees count this much
KEEP_ANGLE = (5.0, 30.0)
ELEVATION_WEIGHT = 0.5
# skin with at least this direct light (n . s) is lit: the relit face's exposure is matched on it
LIT_SHADING = 0.3


def brightened(new_lighting: np.ndarray, fitted: np.ndarray, correction: np.ndarray) -> np.ndarray:
    """(h, w, C) float32 a new light's lighting (``new_lighting`` (h, w), the fitted shape's under it, with the room's
    light) with what the photo showed brighter than the fitted shading under its own light (``correction`` (h, w, C)
    of ``fitted`` (h, w)) added: that is the room's light, there whatever the lamp does. What the photo showed darker
    is its shadows, which a new light takes away."""
    new = np.asarray(new_lighting, np.float32)[..., None]
    more = np.asarray(fitted, np.float32)[..., None] * np.maximum(np.asarray(correction, np.float32) - 1.0, 0.0)
    return (new + more).astype(np.float32)


def shadows_kept(light: np.ndarray, new_light: np.ndarray) -> float:
    """How far the photo is kept as it is under ``new_light`` (3,), the photo's being ``light`` (3,): all of it under the
    photo's own light (its shadows and its shading, which the fitted shape's never match at their edges), none under
    a light ``KEEP_ANGLE``'s end or further from it (a smooth ramp between, in degrees). The angle counts a light's
    elevation ``ELEVATION_WEIGHT`` as much as its azimuth: a face's albedo is nearly the same on both sides, so a photo
    shows a light's side well, but runs from brows to lips to beard downward, which an elevation fitted to it takes
    up (faces lit evenly from the front were read lit from 20-50 degrees above)."""
    def angles(v: np.ndarray) -> tuple[float, float]:
        v = np.asarray(v, np.float64) / np.linalg.norm(v)
        return float(np.degrees(np.arctan2(-v[0], v[2]))), float(np.degrees(np.arcsin(np.clip(v[1], -1.0, 1.0))))
    (az, el), (new_az, new_el) = angles(light), angles(new_light)
    apart = float(np.hypot(az - new_az, ELEVATION_WEIGHT * (el - new_el)))
    return 1.0 - float(smoothstep(apart, *KEEP_ANGLE))


def smooth_change(change: np.ndarray, face: np.ndarray, sigma_px: float) -> np.ndarray:
    """(h, w, C) float32 a light or a change of it (``change`` (h, w, C)) averaged over ``sigma_px`` within the
    ``face`` (h, w) bool, in log (ratios average so): the fitted shape is no finer than its model grid, and a ratio
    of two of its shadings is sharp where either is small (a nostril's wing, under the lip); the photo keeps its own
    finer shading. 1 off the face."""
    log = np.log(np.maximum(np.asarray(change, np.float32), np.float32(1e-4)))
    average, _ = weighted_blur(np.where(face[..., None], log, 0.0), np.asarray(face, np.float32), sigma_px)
    return np.where(face[..., None], np.exp(average), np.float32(1.0)).astype(np.float32)


def photo_light(lighting: np.ndarray) -> np.ndarray:
    """(h, w, C) float32 the light the photo shows (``ShadowEvidence.lighting``: the fitted shading with the room's
    light, corrected by the skin), kept off zero."""
    return np.maximum(np.asarray(lighting, np.float32), np.float32(1e-3)).astype(np.float32)


def precision(file_values: np.ndarray, encoding: str = "linear") -> np.ndarray:
    """(h, w) float32: how well each pixel's light is known, as a share of itself, from its value in its file
    (``file_values`` (h, w), 0-1, in the file's ``encoding``, "srgb" or "linear"): ``FILE_NOISE`` in the file is
    ``FILE_NOISE d ln(light) / d ln(v) / v`` of the light (sRGB's curve multiplies it by up to 2.4)."""
    v = np.maximum(np.asarray(file_values, np.float32), np.float32(1e-4))
    slope = np.float32(1.0)
    if encoding == "srgb":  # light = ((v + 0.055) / 1.055) ** 2.4 above the curve's linear toe
        slope = np.where(v > 0.04045, np.float32(2.4) * v / (v + np.float32(0.055)), np.float32(1.0))
    return (slope * np.float32(FILE_NOISE) / v).astype(np.float32)


def signal(relative: np.ndarray) -> np.ndarray:
    """(h, w) float32 in [0, 1]: how much of a pixel's texture is the photo's, not noise, by its ``relative``
    (``precision``) against ``TEXTURE_NOISE``: what is kept of a pixel's own albedo, whatever the light."""
    return (np.float32(1.0) - smoothstep(relative, *TEXTURE_NOISE)).astype(np.float32)


def usable(relative: np.ndarray, lift: np.ndarray, encoding: str = "linear") -> np.ndarray:
    """(h, w) float32 in [0, 1]: how far a pixel can be lifted by ``lift`` (h, w) and still be shown: the noise its file
    holds (``FILE_NOISE``), raised with it (in the file's encoding: ``lift`` itself for a linear file, its 2.4th root
    for sRGB, whose curve spends its levels on the dark), under ``NOISE_SHOWN``; and, lifted at all (``LIFTED``), its
    light known better than ``RELATIVE_NOISE`` (``relative``, ``precision``): a lifted shadow at the noise floor is
    noise, JPEG blocks and banding, not skin. A dark pixel the light does not raise keeps its own value, however dark
    (a pupil, a nostril, dark skin)."""
    g = np.maximum(np.asarray(lift, np.float32), np.float32(1.0))
    raised = g if encoding != "srgb" else np.power(g, np.float32(1.0 / 2.4))
    shown = np.float32(1.0) - smoothstep(np.float32(FILE_NOISE) * raised, *NOISE_SHOWN)
    known = np.float32(1.0) - smoothstep(relative, *RELATIVE_NOISE) * smoothstep(g, *LIFTED)
    return (shown * known).astype(np.float32)


def held_to_skin(lift: np.ndarray, photo: np.ndarray, skin: np.ndarray, sigma_px: float,
                 margin: float = 1.25) -> np.ndarray:
    """(h, w) float32 in (0, 1]: the factor that holds what is not ``skin`` (h, w) bool (eyes, brows, lips, teeth,
    nostrils, hair, a beard) to at most ``margin`` x the ``lift`` (h, w, the change of light) of the skin around it,
    and, unless that keeps it as bright as the photo has it, relit no brighter than ``margin`` x the relit skin around
    it (both averaged over ``sigma_px``, and over four times that where no skin is so near); 1 on skin and where no
    skin is near. The fitted shape's shading there (a socket, under a lip, inside a mouth) can be far darker than the
    photo's, and brightened by it a brow or an eyelid glowed; and what is bright in a shadow (an eye's reflection of
    the lamp, teeth) lifted as the shadow's skin shone white. photo (h, w, C) linear."""
    w = np.asarray(skin, np.float32)
    y = brightness(np.atleast_3d(photo))
    far = np.full(lift.shape, 1e9, np.float32)
    around = local_average(np.where(skin, lift, 0.0), w, sigma_px, far)
    relit_around = local_average(np.where(skin, lift * y, 0.0), w, sigma_px, far)
    bound = np.minimum(np.float32(margin) * around,
                       np.maximum(np.float32(1.0), np.float32(margin) * relit_around / np.maximum(y, np.float32(1e-4))))
    held = np.minimum(np.float32(1.0), bound / np.maximum(lift, np.float32(1e-6)))
    return np.where(skin, np.float32(1.0), np.nan_to_num(held, nan=1.0)).astype(np.float32)


def fill_weight(usable_now: np.ndarray, paintable: np.ndarray) -> np.ndarray:
    """(h, w) float32 in [0, 1]: how far each pixel is painted: where it cannot be lifted as far as the new light asks
    (``usable_now`` (h, w), ``usable``), on ``paintable`` (h, w) bool."""
    return ((np.float32(1.0) - np.asarray(usable_now, np.float32)) * paintable).astype(np.float32)


def exposure(photo: np.ndarray, relit: np.ndarray, lit_skin: np.ndarray, relit_skin: np.ndarray) -> float:
    """The factor that gives a relit face the exposure of the photo's own lit skin: the median brightness of
    ``photo`` (h, w, C) on ``lit_skin`` (h, w) bool over that of ``relit`` (unexposed) on ``relit_skin``; 1 when either
    is nearly empty. Relit by its own light the photo comes back as it was; a face lit from 70 deg relit frontally
    would otherwise be three times as bright as the skin the photo shows, the lamp being the same."""
    return exposure_gain(exposure_target(photo, lit_skin), relit, relit_skin)


def exposure_target(photo: np.ndarray, lit_skin: np.ndarray) -> float | None:
    """The median brightness of ``photo`` (h, w, C) on ``lit_skin`` (h, w) bool; None when that is nearly empty."""
    if lit_skin.sum() < 50:
        return None
    return float(np.median(brightness(np.atleast_3d(photo))[lit_skin]))


def exposure_gain(want: float | None, relit: np.ndarray, relit_skin: np.ndarray) -> float:
    """``want`` (``exposure_target``) over the median brightness of ``relit`` (h, w, C) on ``relit_skin``; 1 when either
    is unknown or nearly empty."""
    if want is None or relit_skin.sum() < 50:
        return 1.0
    have = float(np.median(brightness(np.atleast_3d(relit))[relit_skin]))
    return want / have if have > 1e-6 else 1.0


def relit_face(photo: np.ndarray, gain: np.ndarray, painted: np.ndarray, weight: np.ndarray,
               shine: np.ndarray | None = None, keep: np.ndarray | None = None,
               colour: np.ndarray | None = None) -> np.ndarray:
    """(h, w, C) float32 the face relit: ``(I - sh) G + sh k``, ``G`` the change of light (``gain`` (h, w, C), at most
    ``MAX_GAIN``), painted (``painted`` (h, w, C)) as far as ``weight`` (h, w, ``fill_weight``) says. photo (h, w, C)
    linear; shine (h, w, C) ``sh`` the photo's shine, in light (None: none); keep (h, w) ``k`` how much of it the new
    light keeps (``shine.shine_kept``); colour (h, w, C) or None: the colour a lifted pixel takes as far as it is
    lifted (``CHROMA_LIFT``: a JPEG keeps little colour in the dark, and a shadow's colour lifted ten times came back
    teal or green), keeping its brightness."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    g = np.minimum(np.asarray(gain, np.float32), np.float32(MAX_GAIN))
    if shine is None:
        kept = img * g
    else:
        sh = np.minimum(np.asarray(shine, np.float32), img)
        kept = (img - sh) * g + sh * np.asarray(keep, np.float32)[..., None]
    if colour is not None and img.shape[-1] == 3:
        k = smoothstep(brightness(g), *CHROMA_LIFT)[..., None]
        y = brightness(kept)[..., None]
        c = np.nan_to_num(np.asarray(colour, np.float32))
        target = c / np.maximum(brightness(c), np.float32(1e-5))[..., None]
        own = kept / np.maximum(y, np.float32(1e-6))
        kept = y * (own + k * (target - own))
    w = np.asarray(weight, np.float32)[..., None]
    return (kept + w * (np.nan_to_num(np.asarray(painted, np.float32)) - kept)).astype(np.float32)
