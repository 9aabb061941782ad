"""A no-reference measure of what a relighting did to a face besides changing its light.

A change of light is smooth across a face at the scale of its features: on an evenly lit face relit
frontally, the relit photo over the input is a smooth field. What is not smooth in that ratio is harm:
a beard or a brow taken for shadow and repainted, a pasted patch, a blotch, a hard outline. So, over an
ellipse placed by the eyes (``face_ellipse``):

- ``r = ln(Y_relit + EPS) - ln(Y_input + EPS)``, ``Y`` the linear luminance;
- its high-pass ``r - blur(r)``, the blur Gaussian over ``HIGH_PASS`` eye distances, normalised over the
  ellipse (``r m`` blurred over ``m`` blurred), so the ellipse's edge adds nothing;
- ``H``: the RMS of that high-pass over the ellipse, in % (a log ratio of 0.05 is a 5 % change);
  ``P``: the share of the ellipse where its magnitude exceeds ``BLOTCH`` (20 %).

A strong change of light raises H legitimately (new shadow edges, fine shading), so H judges faces lit
evenly (``halves_ratio`` within ``EVEN``) relit frontally. ``light_move`` says whether a side light
still moved the light: the blurred log ratio, image-left half minus image-right half. H is blind to colour: a
white light changes a skin's level, never its colour, so ``colour_shift`` measures that apart: the RMS change of
the skin's chromaticity (``ln R/G``, ``ln B/G``) over the ellipse, in % (pink skin turned grey-green by a
relighting reads 7 %, kept pink 4 %; a JPEG's colour noise alone a few %).

Two measures judge any light, side light too. A relighting lifts a shadow and changes the shading: it
takes edges away (a shadow's rim) and adds none but the new light's own, and a white light never changes
the skin's colour at a fine scale. ``added_edges`` is the share of the face where the relit photo has an edge the input
has not (a pasted patch's rim, a painted slab's outline); ``colour_blotches`` the RMS of the high-passed
change of chromaticity (orange or green blotches, coloured speckle in a beard, a grey-blue patch).
``flattened`` is the share of the face the file holds at its top that the relit face darkens: the file says only
that it was at least that bright, so darkened it comes back as one flat tone (a grey plateau over a clipped forehead).

Arrays are (H, W) linear luminance or (H, W, 3) linear RGB on the photo's grid; eyes are (2, 2) photo
pixels ``[[x, y], [x, y]]`` (either order).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..photo.evenness import EVEN, Ellipse, face_ellipse, halves_ratio, luminance
from .fields import weighted_blur

HIGH_PASS = 0.15  # the high-pass's Gaussian, eye distances
BLOTCH = 0.20  # a high-passed log ratio beyond this is a blotch (P)
# added to linear luminance before the log: a pixel at a few levels of 255 is noise, and its ratio means nothing
EPS = 2e-3
# ``added_edges``: the log luminance (floored at ``EDGE_FLOOR``, linear) smoothed over ``EDGE_BLUR`` eye distances, an
# edge where its slope exceeds the input's by ``EDGE_STEP`` (log units per eye distance): a patch's rim or a paint's
# outline (on the people set relit frontally, the faces seen damaged read up to 7.5 % of the face, the others at
# most 2.1 %)
EDGE_FLOOR = 0.01
EDGE_BLUR = 0.02
EDGE_STEP = 2.0
# ``colour_blotches``: a pixel of the input darker than this (linear luminance, a few levels of an 8-bit sRGB file)
# has no colour to keep: black, or the file's noise
COLOUR_FLOOR = 0.002
# ``flattened``: a pixel with a channel at or over this (linear) is at its file's top (255 of an 8-bit sRGB file), and
# one relit this share darker or more is darkened
FILE_TOP = 0.995
DARKENED = 0.1


@dataclass(frozen=True)
class Harm:
    """One face's scores: ``h`` and ``p`` in %, ``halves`` the ratio of its halves' mean luminance in the input
    (>= 1), ``move`` the light's move (``light_move``; None when not asked)."""

    h: float
    p: float
    halves: float
    move: float | None = None

    @property
    def even(self) -> bool:
        return self.halves <= 1.0 + EVEN


def _masked_blur(values: np.ndarray, mask: np.ndarray, sigma: float) -> np.ndarray:
    """(h, w[, C]) the Gaussian average of ``values`` (h, w[, C]) over ``mask`` (h, w) (normalised there), taken on a
    shrunk grid as every wide blur of the relighting is (``fields.blur``: a high-pass's blur of 0.15 eye distances
    is 26 pixels wide on a webcam face, and the honesty step judging each frame of a clip blurred at full size spent
    a fifth of the frame's time here)."""
    average, _ = weighted_blur(values, mask.astype(np.float32), sigma)
    return average


def log_ratio(before: np.ndarray, after: np.ndarray, ellipse: Ellipse) -> np.ndarray:
    """(h, w) float32 ``ln(Y_after + EPS) - ln(Y_before + EPS)`` on the ellipse's crop."""
    y0, y1, x0, x1 = ellipse.box
    b = luminance(before)[y0:y1, x0:x1]
    a = luminance(after)[y0:y1, x0:x1]
    return (np.log(np.maximum(a, 0.0) + np.float32(EPS)) - np.log(np.maximum(b, 0.0) + np.float32(EPS))
            ).astype(np.float32)


def harm(before: np.ndarray, after: np.ndarray, eyes: np.ndarray, within: np.ndarray | None = None) -> Harm:
    """``Harm`` of ``after`` (the relit photo) against ``before`` (the input), both linear, on the face whose
    eyes are ``eyes`` (2, 2) photo pixels; with ``within`` (H, W) bool, over the part of the ellipse inside it only
    (a turned face's ellipse reaches past its outline, and the face's change of light against the background
    there is a step, not harm)."""
    ellipse = face_ellipse(eyes, np.shape(before)[:2], 3.0 * HIGH_PASS)
    m = _face_mask(ellipse, within)
    if not m.any():
        raise ValueError(f"eyes {np.asarray(eyes).tolist()}: the face's ellipse is outside the photo")
    r = log_ratio(before, after, ellipse)
    high = (r - _masked_blur(r, m, HIGH_PASS * ellipse.iod))[m]
    h = 100.0 * float(np.sqrt(np.mean(high.astype(np.float64) ** 2)))
    p = 100.0 * float(np.mean(np.abs(high) > BLOTCH))
    return Harm(h, p, halves_ratio(before, ellipse))


def _face_mask(ellipse: Ellipse, within: np.ndarray | None) -> np.ndarray:
    """(h, w) bool: the ellipse's mask on its crop, within ``within`` (H, W) bool on the photo when given."""
    m = ellipse.mask
    if within is not None:
        y0, y1, x0, x1 = ellipse.box
        m = m & np.asarray(within, bool)[y0:y1, x0:x1]
    return m


def added_edges(before: np.ndarray, after: np.ndarray, eyes: np.ndarray, within: np.ndarray | None = None,
                new_light: np.ndarray | None = None) -> float:
    """The share (%) of the face's ellipse from ``eyes`` (2, 2) photo pixels (within ``within`` (H, W) bool, if
    given) where ``after`` has an edge ``before`` has not: the slope of log luminance (``EDGE_FLOOR`` added, to
    ``after``'s times the smooth change of light; smoothed over ``EDGE_BLUR`` eye distances; per eye distance) of
    ``after`` exceeds ``before``'s by ``EDGE_STEP``, beyond the slope of ``new_light`` (H, W), the new light's
    shading, when given (its terminator and cast shadows are edges it adds rightly). ``before``, ``after`` (H, W) or
    (H, W, 3) linear."""
    ellipse = face_ellipse(eyes, np.shape(before)[:2], 3.0 * HIGH_PASS)
    m = _face_mask(ellipse, within)
    if not m.any():
        return 0.0
    y0, y1, x0, x1 = ellipse.box

    def slope(image: np.ndarray, floor) -> np.ndarray:
        log = np.log(np.maximum(luminance(image)[y0:y1, x0:x1], 0.0) + floor).astype(np.float32)
        log = cv2.GaussianBlur(log, (0, 0), EDGE_BLUR * ellipse.iod)
        gx, gy = cv2.Sobel(log, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(log, cv2.CV_32F, 0, 1, ksize=3)
        return np.hypot(gx, gy) * np.float32(ellipse.iod / 8.0)  # Sobel's 3x3 weighs a unit slope 8

    # the floor lifted with the light (the smooth part of the change): a shadow's noise and an 8-bit file's levels
    # lifted are the photo's own, not edges added (Yale B's sRGB shadows from 70 degrees read 5-9 % without it)
    lift = np.exp(_masked_blur(log_ratio(before, after, ellipse), m, HIGH_PASS * ellipse.iod))
    added = slope(after, np.float32(EDGE_FLOOR) * lift) - slope(before, np.float32(EDGE_FLOOR))
    if new_light is not None:
        added -= slope(new_light, np.float32(EDGE_FLOOR))
    return 100.0 * float(np.mean(added[m] > EDGE_STEP))


def chromaticity(image: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """(h, w, 2) float32 ``ln R/G`` and ``ln B/G`` (``EPS`` added) of ``image`` (H, W, 3) linear on ``box``
    ``(y0, y1, x0, x1)``."""
    y0, y1, x0, x1 = box
    v = np.log(np.maximum(np.asarray(image, np.float32)[y0:y1, x0:x1], 0.0) + np.float32(EPS))
    return np.stack([v[..., 0] - v[..., 1], v[..., 2] - v[..., 1]], axis=-1)


def colour_blotches(before: np.ndarray, after: np.ndarray, eyes: np.ndarray,
                    within: np.ndarray | None = None) -> float:
    """The RMS (%) over the face's ellipse (as ``added_edges``) of the high-passed change of chromaticity (``ln
    R/G`` and ``ln B/G`` of linear RGB, ``EPS`` added; the high-pass ``harm``'s): what a white light's change
    cannot do. Pixels of ``before`` darker than ``COLOUR_FLOOR`` (linear luminance) are left out: their colour is the
    file's noise, or none (a black shadow lifted to skin read as 11 % of a render's face). 0 for grey photos."""
    if np.ndim(before) < 3 or np.shape(before)[-1] != 3:
        return 0.0
    ellipse = face_ellipse(eyes, np.shape(before)[:2], 3.0 * HIGH_PASS)
    y0, y1, x0, x1 = ellipse.box
    m = _face_mask(ellipse, within) & (luminance(before)[y0:y1, x0:x1] > COLOUR_FLOOR)
    if not m.any():
        return 0.0
    d = chromaticity(after, ellipse.box) - chromaticity(before, ellipse.box)
    high = (d - _masked_blur(d, m, HIGH_PASS * ellipse.iod))[m]
    return 100.0 * float(np.sqrt(np.sum(np.mean(high.astype(np.float64) ** 2, axis=0))))


def light_move(before: np.ndarray, after: np.ndarray, eyes: np.ndarray) -> float:
    """How far a new light moved the light across the face: the blurred log ratio (``HIGH_PASS`` eye distances,
    over the ellipse) averaged over the image-left half of the ellipse, less its average over the right half.
    Positive when the image's left brightened against its right (a light from the image's left)."""
    ellipse = face_ellipse(eyes, np.shape(before)[:2], 3.0 * HIGH_PASS)
    m = ellipse.mask
    smooth = _masked_blur(log_ratio(before, after, ellipse), m, HIGH_PASS * ellipse.iod)
    left, right = smooth[m & (ellipse.side > 0)], smooth[m & (ellipse.side <= 0)]
    if not left.size or not right.size:
        return float("nan")
    return float(left.mean() - right.mean())


def colour_shift(before: np.ndarray, after: np.ndarray, eyes: np.ndarray) -> float:
    """The RMS change (%) of chromaticity (``ln R/G``, ``ln B/G`` of linear RGB, ``EPS`` added) from ``before`` to
    ``after`` (H, W, 3) over the face's ellipse from ``eyes`` (2, 2) photo pixels; 0 for grey photos."""
    if np.ndim(before) < 3 or np.shape(before)[-1] != 3:
        return 0.0
    ellipse = face_ellipse(eyes, np.shape(before)[:2], 0.0)
    m = ellipse.mask
    d = (chromaticity(after, ellipse.box) - chromaticity(before, ellipse.box))[m]
    return 100.0 * float(np.sqrt(np.mean(np.sum(d.astype(np.float64) ** 2, axis=-1)))) if d.size else 0.0


def flattened(before: np.ndarray, after: np.ndarray, within: np.ndarray) -> float:
    """The share (%) of ``within`` (H, W) bool where ``before`` (H, W[, C]) is at its file's top (``FILE_TOP``, any
    channel) and ``after`` (same shape) is darker by ``DARKENED`` or more (linear luminance): a region the file cut
    at its top, relit darker, is one flat tone (its texture is what the file cut)."""
    if not within.any():
        return 0.0
    top = np.any(np.atleast_3d(before) >= FILE_TOP, axis=-1)
    darker = luminance(after) <= (1.0 - DARKENED) * luminance(before)
    return 100.0 * float(np.count_nonzero(top & darker & within)) / float(np.count_nonzero(within))
