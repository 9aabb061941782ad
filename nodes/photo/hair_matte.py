"""Where a photo shows hair: MediaPipe's hair segmentation (Tkachenka et al., "Real-time Hair segmentation and
recoloring on Mobile GPUs", 2019), run by LiteRT.

The model (``data/hair_segmentation.tflite``, Apache-2.0, ``data/NOTICE``) sees a 512 x 512 RGB image in [0, 1]
and a fourth channel, the previous frame's hair mask (zeros for a still), the picture stretched to that square; it
gives two logits per pixel, hair against not. It uses three of MediaPipe's own operators, which LiteRT runs and
OpenCV's dnn loads but gets wrong (a nearly empty mask): where LiteRT is not installed there is no matte
(``available``). On a whole group photo its mask bleeds into the background, so a face is shown to it in a square
around its head (``HEAD_REACH`` times the face's box each way).

Everything here is in photo pixels: x = column, y = row (down).
"""
from __future__ import annotations

import cv2
import numpy as np

from .mediapipe import DATA, NetPool, _litert

HAIR_FILE = DATA / "hair_segmentation.tflite"
HAIR_SIDE = 512  # the model's input, square
# the square shown to the model: the face box's larger side times this, around the box's centre
HEAD_REACH = 2.0

HAIR = NetPool(HAIR_FILE, litert_only=True)


def available() -> bool:
    """Whether the hair matte can be made here (LiteRT installed)."""
    return _litert() is not None


def hair_share(rgb: np.ndarray) -> np.ndarray:
    """(H, W) float32 in [0, 1]: how sure the hair segmentation is that each pixel of ``rgb`` ((H, W, 3) float in
    [0, 1], as the file shows it: sRGB-encoded for an sRGB photo) is hair; the image stretched to 512 x 512 and the
    answer brought back to its size. ``RuntimeError`` without LiteRT (``available``)."""
    h, w = rgb.shape[:2]
    small = cv2.resize(np.asarray(rgb, np.float32), (HAIR_SIDE, HAIR_SIDE), interpolation=cv2.INTER_AREA)
    small = small.reshape(HAIR_SIDE, HAIR_SIDE, -1)
    if small.shape[-1] != 3:
        small = np.repeat(small[..., :1], 3, axis=-1)
    x = np.concatenate([np.clip(small, 0.0, 1.0), np.zeros((HAIR_SIDE, HAIR_SIDE, 1), np.float32)], axis=-1)
    (logits,) = HAIR.forward(x.astype(np.float32)[None], ["conv2d_transpose_4"])
    logits = np.asarray(logits, np.float32).reshape(HAIR_SIDE, HAIR_SIDE, 2)
    share = 1.0 / (1.0 + np.exp(-np.clip(logits[..., 1] - logits[..., 0], -60.0, 60.0)))
    return cv2.resize(share.astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR)


def hair_in_box(photo: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """(y1 - y0, x1 - x0) float32 in [0, 1]: ``hair_share`` over ``box`` ``(y0, y1, x0, x1)`` of ``photo`` ((H, W, C)
    as a camera saves it: uint8, or float in [0, 1]), the model shown the square ``HEAD_REACH`` times the box around
    it (black past the photo's edge); only that square is read."""
    y0, y1, x0, x1 = (int(v) for v in box)
    H, W = photo.shape[:2]
    half = 0.5 * HEAD_REACH * max(y1 - y0, x1 - x0, 1)
    cy, cx = 0.5 * (y0 + y1), 0.5 * (x0 + x1)
    sy0, sy1, sx0, sx1 = (int(round(v)) for v in (cy - half, cy + half, cx - half, cx + half))
    square = np.zeros((sy1 - sy0, sx1 - sx0, photo.shape[-1] if photo.ndim == 3 else 1), np.float32)
    py0, py1, px0, px1 = max(sy0, 0), min(sy1, H), max(sx0, 0), min(sx1, W)
    square[py0 - sy0:py1 - sy0, px0 - sx0:px1 - sx0] = np.atleast_3d(photo)[py0:py1, px0:px1]
    if np.asarray(photo).dtype == np.uint8:
        square /= np.float32(255.0)
    share = hair_share(square)
    return share[y0 - sy0:y1 - sy0, x0 - sx0:x1 - sx0]
