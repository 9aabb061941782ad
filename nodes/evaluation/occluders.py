"""Shadows the face does not cast, laid over a photo as an occluder between the light and the face would: a hat's
brim across the brow and eyes, leaves' dapples, a hand's. Each is drawn on the photo's grid from the face's eyes and
scaled by their distance; the photo is multiplied by what it leaves of the light (the ``ambient`` share in its core,
all of it outside, a penumbra between) and, in colour, the shade is a little cooler (lit by the sky or the room).
Nothing here is stored: shadows are made when an evaluation or a test asks for them.

Arrays are (H, W[, C]) float32 linear; eyes (2, 2) ``[[x, y], [x, y]]`` photo pixels.
"""
from __future__ import annotations

import cv2
import numpy as np

KINDS = ("brim", "leaves", "hand")
# the shade's colour against the light's, RGB (a blue sky's fill): applied in colour only
SHADE_TINT = (0.94, 0.98, 1.06)


def _frame(eyes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(centre (2,), across (2,) unit, down (2,) unit, iod): the eyes' midpoint, the axis from the first eye to the
    second, the face's downward axis and the eyes' distance in pixels."""
    e = np.asarray(eyes, np.float64)
    across = e[1] - e[0]
    iod = float(np.hypot(*across))
    across /= iod
    down = np.array([-across[1], across[0]])
    if down[1] < 0:
        down = -down
    return e.mean(axis=0), across, down, iod


def _coordinates(shape: tuple[int, int], eyes: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(u, v, iod): each pixel's place across and down the face from the eyes' midpoint, in interocular distances."""
    centre, across, down, iod = _frame(eyes)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    dx, dy = xx - centre[0], yy - centre[1]
    return (dx * across[0] + dy * across[1]) / iod, (dx * down[0] + dy * down[1]) / iod, iod


def brim(shape: tuple[int, int], eyes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(H, W) float32 in {0, 1}: a brim's shadow, everything above a gently curved, tilted edge that runs between
    the brows and the nose's middle."""
    u, v, _ = _coordinates(shape, eyes)
    edge = rng.uniform(-0.35, 0.45) + rng.uniform(-0.25, 0.25) * u + rng.uniform(0.1, 0.35) * u**2
    return (v < edge).astype(np.float32)


def leaves(shape: tuple[int, int], eyes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(H, W) float32 in {0, 1}: dappled shade, blobs a few tenths of the eyes' distance wide over 35-60 % of the
    photo."""
    _, _, iod = _coordinates(shape, eyes)
    noise = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), rng.uniform(0.08, 0.16) * iod)
    return (noise < np.quantile(noise, rng.uniform(0.35, 0.6))).astype(np.float32)


def hand(shape: tuple[int, int], eyes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(H, W) float32 in {0, 1}: a hand's shadow, a palm and four fingers, over one side of the face from below or
    beside it."""
    centre, across, down, iod = _frame(eyes)
    side = rng.choice([-1.0, 1.0])
    palm = centre + iod * (side * rng.uniform(0.5, 0.9) * across + rng.uniform(0.7, 1.1) * down)
    reach = -down * np.cos(a := rng.uniform(-0.5, 0.5)) - side * across * np.sin(a) * 0.6  # the fingers point up
    reach /= np.hypot(*reach)
    out = np.zeros(shape, np.uint8)
    axes = (round(0.45 * iod), round(0.38 * iod))
    angle = float(np.degrees(np.arctan2(reach[1], reach[0])))
    cv2.ellipse(out, (round(palm[0]), round(palm[1])), axes, angle, 0, 360, 1, -1)
    sideways = np.array([-reach[1], reach[0]])
    for k, length in zip((-1.5, -0.5, 0.5, 1.5), (0.7, 0.85, 0.8, 0.6)):
        base = palm + reach * 0.3 * iod + sideways * k * 0.2 * iod
        tip = base + reach * length * iod
        cv2.line(out, (round(base[0]), round(base[1])), (round(tip[0]), round(tip[1])), 1,
                 max(1, round(0.16 * iod)), cv2.LINE_AA)
    return out.astype(np.float32)


def occluder(kind: str, shape: tuple[int, int], eyes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(H, W) float32 in {0, 1}: where ``kind`` (one of ``KINDS``) blocks the light."""
    draw = {"brim": brim, "leaves": leaves, "hand": hand}
    if kind not in draw:
        raise ValueError(f"unknown shadow kind {kind!r}: one of {', '.join(KINDS)}")
    return draw[kind](shape, eyes, rng)


def lay_shadow(photo: np.ndarray, blocked: np.ndarray, ambient: float, penumbra_px: float) -> np.ndarray:
    """(H, W[, C]) float32 ``photo`` in the shadow of ``blocked`` (H, W) in [0, 1]: multiplied by ``1 - (1 - ambient)
    b``, ``b`` the occluder blurred over ``penumbra_px`` (its penumbra); in colour the shade takes ``SHADE_TINT``."""
    b = np.asarray(blocked, np.float32)
    if penumbra_px > 0:
        b = cv2.GaussianBlur(b, (0, 0), penumbra_px)
    left = np.float32(1.0) - np.float32(1.0 - ambient) * b
    img = np.asarray(photo, np.float32)
    if img.ndim == 3 and img.shape[-1] == 3:
        tint = np.asarray(SHADE_TINT, np.float32)
        return (img * (left[..., None] * (1.0 + b[..., None] * (tint - 1.0)))).astype(np.float32)
    return (img * left).astype(np.float32)
