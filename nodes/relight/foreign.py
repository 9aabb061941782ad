"""Shadows the face does not cast: a hat's brim, leaves, a hand, another head (docs/relighting.md, "Shadows from
elsewhere").

Where the fitted shape is lit (out of its shadows' ``gate``), the photo's skin shows the fitted shading times its
albedo. A shadow thrown from elsewhere darkens it far below that, over a region, keeping its colour (a little cooler:
it is lit by the sky or the room). What is dark by its make (a beard, brows, eyes, glasses, hair, lips) is not skin
(``ShownLight.skin``) and is never read here; a region whose colour is not the lit skin's in shade is dropped too.

The skin's light is read against the lit skin's as the fitted shading predicts it (``log q``, its upper quantile
``LIT_QUANTILE`` taken as the lit level: more than half of a face may lie in dappled shade), not against the locally
matched albedo, which a wide shadow pulls down with it.

Arrays are on the face's box at the photo's resolution (h, w[, C]), linear; lengths in interocular distances.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from .evidence import DENOISE, closed, without_specks
from .fields import brightness, weighted_blur

# skin darker than this share of the lit skin's level under the fitted shading is in a shadow from elsewhere (an
# occluder's shade keeps 25-45 % of the light; skin's own darker patches, under-eye rings and blush, keep 70 %)
FOREIGN_DARK = 0.58
# the lit skin's level: this quantile of the skin's light over the fitted shading (a shape the model has wrong, or
# an albedo, darkens the skin gradually; a linear or quadratic level over the face followed a brim's shade down)
LIT_QUANTILE = 80
# gaps this wide are closed (a brow, a mole in the shade), and regions smaller than a square this wide dropped (a
# freckle, a pore's shadow, a nostril's rim)
FOREIGN_CLOSE = 0.04
FOREIGN_MIN_SIDE = 0.12
# a region whose skin is this far from the lit skin's colour (ln R/G or ln B/G, in shade toward the room's light) is
# dark by its make (a tattoo, a birthmark, make-up), not in shade
CHROMA_APART = 0.25
# the least skin a face needs for its shadows to be told
MIN_SKIN = 200


def foreign_shadows(photo: np.ndarray, lighting: np.ndarray, skin: np.ndarray, gate: np.ndarray, face: np.ndarray,
                    iod_px: float, own: np.ndarray | None = None) -> np.ndarray:
    """(h, w) bool: the shadows on a face's skin the fitted shape does not cast. photo (h, w, C) linear; lighting
    (h, w) the fitted shading with the room's light; skin (h, w) bool the pixels whose light is read; gate (h, w)
    bool where the fitted shape lets its own shadows fall (``evidence.shadow_gate``): seeds are out of it, a region
    runs on into it over skin as dark, but not into ``own`` (h, w) bool (the shape's own shadows, the face's rim; None:
    nowhere kept out); face (h, w) bool; iod_px: the face's interocular distance in pixels."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    read = np.asarray(skin, bool) & face
    open_skin = read & ~np.asarray(gate, bool)
    if open_skin.sum() < MIN_SKIN:
        return np.zeros(read.shape, bool)
    fitted = np.maximum(np.asarray(lighting, np.float32), np.float32(1e-4))
    log_q = np.log(np.maximum(brightness(img), np.float32(1e-5)) / fitted)
    level, support = weighted_blur(np.where(read, log_q, 0.0), read.astype(np.float32), max(DENOISE * iod_px, 1.0))
    lit = float(np.percentile(log_q[open_skin], LIT_QUANTILE))
    dark = read & (support > 0.05) & (level < lit + np.log(FOREIGN_DARK))
    # seeded out of the gate, a region runs on into it over skin as dark: leaves' and a brim's shade across the side
    # the light reaches less were found only to the gate's edge (at 25 deg, half of them)
    seeds = dark & open_skin
    if own is not None:
        dark &= ~np.asarray(own, bool)
    dark = ndimage.binary_propagation(seeds, structure=np.ones((3, 3), bool), mask=dark | seeds)
    region = without_specks(closed(dark, FOREIGN_CLOSE * iod_px) & face, (FOREIGN_MIN_SIDE * iod_px) ** 2)
    if img.shape[-1] == 3 and region.any():
        region = _of_skin_colour(img, region, read, level > lit + np.log(0.8))
    return region


def _of_skin_colour(img: np.ndarray, region: np.ndarray, read: np.ndarray, lit: np.ndarray) -> np.ndarray:
    """``region`` (h, w) bool without its parts whose skin (``read`` (h, w) bool) is not of the ``lit`` (h, w) bool
    skin's colour: median ln R/G or ln B/G more than ``CHROMA_APART`` from the lit skin's (bluer shade is allowed
    twice as far)."""
    lit_skin = read & lit
    if lit_skin.sum() < 50:
        return region
    log_rgb = np.log(np.maximum(img, np.float32(1e-5)))
    chroma = np.stack([log_rgb[..., 0] - log_rgb[..., 1], log_rgb[..., 2] - log_rgb[..., 1]], axis=-1)
    lit_chroma = np.median(chroma[lit_skin], axis=0)
    labels, n = ndimage.label(region, structure=np.ones((3, 3), bool))
    on_skin = np.where(read, labels, 0)
    index = np.arange(1, n + 1)
    counted = np.bincount(on_skin.ravel(), minlength=n + 1)[1:] >= 10
    apart_r = np.asarray(ndimage.median(chroma[..., 0], on_skin, index)) - lit_chroma[0]
    apart_b = np.asarray(ndimage.median(chroma[..., 1], on_skin, index)) - lit_chroma[1]
    bluer = np.where(apart_b > 0, 2.0, 1.0)
    keep = np.concatenate([[False], counted & (np.abs(apart_r) < CHROMA_APART)
                           & (np.abs(apart_b) < CHROMA_APART * bluer)])
    return keep[labels]


def found(membership: np.ndarray, face: np.ndarray, iod_px: float) -> dict[str, float]:
    """The shadows the face does not cast, as ``summary.json`` gives them: ``count`` (the separate regions of
    ``membership`` (h, w) more than half in, as large as one is looked for: ``FOREIGN_MIN_SIDE``) and ``area``
    (their share of the ``face`` (h, w) bool's pixels)."""
    inside = np.asarray(membership) > 0.5
    labels, n = ndimage.label(inside, structure=np.ones((3, 3), bool))
    count = int(np.sum(np.bincount(labels.ravel(), minlength=n + 1)[1:] >= (FOREIGN_MIN_SIDE * iod_px) ** 2))
    return {"count": count, "area": round(float(inside[face].mean()) if face.any() else 0.0, 4)}
