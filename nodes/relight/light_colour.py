"""The colour of the light the photo shows on a face, against its lit skin's.

A face's shade is lit by the room (a wall, the sky, a green screen behind the head), not by the lamp, and its skin
takes that light's colour: a shadow dims and cools skin, or greens it. A relighting that lifts the shade by one gain
in every channel keeps the room's colour in it, and the lifted half of the face comes back grey-green beside the pink
lit half. The light a relighting adds is the lamp's, the lit skin's colour.

With ``P`` a pixel (per channel), ``c`` the skin's colour around it and ``r`` the lit skin's (chromaticities,
brightness 1): the skin's albedo's colour is ``r`` under the lamp's light, so the room's light gives it ``c``. A
change of light by ``g`` (its brightness) adds ``(g - 1) Y`` of the lamp's light to a pixel of brightness ``Y``:
``P' = P (1 + (g - 1) r / c)`` per channel (``tinted``), exact when the skin's albedo has one colour, and the photo's
own detail (a freckle's colour, stubble) kept as the ratio. Where the skin is lit, ``r / c`` is 1 and nothing
changes; under the photo's own light ``g`` is 1 and nothing changes.

Only light added is coloured so. Light taken away (``g < 1``) would be the lamp's too, but what is left of a pixel
darkened to a third is the difference of two near quantities, and the skin's own colour read as the light's (a
blush, the redder skin beside a nose) came out of it threefold: the astronaut relit from 60 degrees took orange and
blue blotches over her darkened half. A darkened pixel keeps its colour (the room's colour in the new shade is not
known where the photo shows the skin lit).

Arrays are on the face's box at the photo's resolution (h, w[, 3]), linear.
"""
from __future__ import annotations

import numpy as np

from .fields import brightness, local_average

# the skin's colour around a pixel is read over this many interocular distances (wider than a freckle, a pore, the
# stubble's shadow; narrower than the face's half)
TINT_SIGMA = 0.15
# the lit skin: the skin whose light the photo shows at this percentile or over (of the face's skin)
LIT_PERCENTILE = 70
# the change of colour a channel takes is bounded so (a coloured make-up or a blush read as the light's colour is
# not taken for more)
TINT_RANGE = (0.75, 1.35)


def light_tint(photo: np.ndarray, skin: np.ndarray, lighting: np.ndarray, sigma_px: float) -> np.ndarray | None:
    """(h, w, 3) float32 ``r / c``, normalised to brightness 1: the lit skin's colour over the skin's colour around
    each pixel (the light's colour there against the lamp's); None for a grey photo or too little skin.
    photo: (h, w, C) linear; skin: (h, w) bool, the face's skin; lighting: (h, w[, C]) the light the photo shows
    (its brightness tells the lit skin); sigma_px: photo pixels the skin's colour is read over."""
    img = np.asarray(photo, np.float32)
    skin = np.asarray(skin, bool)
    if img.ndim != 3 or img.shape[-1] != 3 or skin.sum() < 100:
        return None
    level = local_average(img, skin.astype(np.float32), sigma_px, np.zeros_like(img))
    colour = level / np.maximum(brightness(level), np.float32(1e-6))[..., None]
    light = brightness(np.atleast_3d(np.asarray(lighting, np.float32)))
    lit = skin & (light >= np.percentile(light[skin], LIT_PERCENTILE))
    ref = np.median(colour[lit], axis=0)
    tint = np.clip(ref / np.maximum(colour, np.float32(1e-4)), *TINT_RANGE)
    return (tint / brightness(tint)[..., None]).astype(np.float32)


def tinted(gain: np.ndarray, tint: np.ndarray | None) -> np.ndarray:
    """(h, w, C) float32 ``gain`` (h, w, C), a change of light per channel, with the light it adds of the lamp's
    colour: ``1 + (g - 1) t`` where ``g > 1``, ``g`` where it darkens (module docstring); ``gain`` itself without a
    ``tint`` (h, w, 3)."""
    g = np.asarray(gain, np.float32)
    if tint is None or g.shape[-1] != 3:
        return g
    return np.where(g > 1.0, np.float32(1.0) + (g - np.float32(1.0)) * tint, g).astype(np.float32)
