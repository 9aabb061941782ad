"""How a photo's numbers relate to light. Lambert's law holds for light, and a camera's JPEG or PNG
stores it sRGB-encoded (about its 2.2nd root): the method works on linear values, decoded from the
photo's encoding, and every image it writes goes back to that encoding.

A colour photo (3 channels) and any JPEG are taken as sRGB, another grey one as linear (Yale B's PGMs
are a camera's linear data; the project's renders are written linear), unless ``--encoding`` says
otherwise.
"""
from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

ENCODINGS = ("auto", "srgb", "linear")
# the luminance of linear sRGB primaries (ITU-R BT.709): what a grey camera would see of them
LINEAR_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)


def linear_luminance(rgb: np.ndarray) -> np.ndarray:
    """(H, W) luminance of linear RGB (H, W, 3), float32."""
    return np.asarray(rgb, np.float32) @ LINEAR_LUMA


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] -> linear light in [0, 1] (IEC 61966-2-1), float32."""
    v = np.asarray(v, np.float32)
    low = v / np.float32(12.92)
    high = np.power((np.maximum(v, np.float32(0.04045)) + np.float32(0.055)) / np.float32(1.055), np.float32(2.4))
    return np.where(v <= np.float32(0.04045), low, high).astype(np.float32)


def linear_to_srgb(v: np.ndarray) -> np.ndarray:
    """Linear light in [0, 1] -> sRGB-encoded values in [0, 1], float32 (clipped to [0, 1] first)."""
    v = np.clip(np.asarray(v, np.float32), 0.0, 1.0)
    low = v * np.float32(12.92)
    high = np.float32(1.055) * np.power(np.maximum(v, np.float32(0.0031308)), np.float32(1.0 / 2.4)) - np.float32(0.055)
    return np.where(v <= np.float32(0.0031308), low, high).astype(np.float32)


def swapped_rb(values: np.ndarray) -> np.ndarray:
    """(H, W, 3) RGB as OpenCV's BGR, or BGR as RGB, contiguous: by OpenCV where it can (a 4-megapixel photo in half
    a millisecond, where numpy's reversed copy takes 10)."""
    if values.dtype in (np.uint8, np.uint16, np.float32):
        return cv2.cvtColor(np.ascontiguousarray(values), cv2.COLOR_BGR2RGB)
    return np.ascontiguousarray(values[..., ::-1])


@lru_cache(maxsize=2)
def _decode_table(levels: int) -> np.ndarray:
    return srgb_to_linear(np.arange(levels, dtype=np.float64) / (levels - 1))


def decode_samples(samples: np.ndarray, full: float) -> np.ndarray:
    """Integer or float samples on the scale 0..``full``, sRGB-encoded -> linear float32 in [0, 1];
    8- and 16-bit samples by a table (a 4-megapixel photo in milliseconds)."""
    s = np.asarray(samples)
    if s.dtype == np.uint8 and full == 255.0:
        return _decode_table(256)[s]
    if s.dtype == np.uint16 and full == 65535.0:
        return _decode_table(65536)[s]
    return srgb_to_linear(np.clip(s.astype(np.float32) / np.float32(full), 0.0, 1.0))


class Decoded8:
    """(H, W, 3) float32 linear light of 8-bit sRGB values ``rgb8`` (H, W, 3) uint8, decoded where it is read:
    ``view[r0:r1, c0:c1]`` (any index) decodes that part alone, by ``decode_samples``'s table, so a
    4-megapixel photo's 48 MB of floats are never held whole; ``np.asarray(view)`` decodes all of it.
    The same values as ``decode_samples(rgb8, 255)``, bit for bit. Read-only."""

    ndim = 3
    dtype = np.dtype(np.float32)

    def __init__(self, rgb8: np.ndarray):
        self.rgb8 = rgb8

    @property
    def shape(self) -> tuple[int, ...]:
        return self.rgb8.shape

    def __len__(self) -> int:
        return self.rgb8.shape[0]

    def __getitem__(self, key) -> np.ndarray:
        return _decode_table(256)[self.rgb8[key]]

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        values = _decode_table(256)[self.rgb8]
        return values if dtype is None else values.astype(dtype, copy=False)


def decoded_luminance(rgb8: np.ndarray, rows: int = 256) -> np.ndarray:
    """(H, W) float32 ``linear_luminance`` of 8-bit sRGB values (H, W, 3), ``rows`` rows at a time: the
    whole photo's linear floats never exist at once."""
    out = np.empty(rgb8.shape[:2], np.float32)
    table = _decode_table(256)
    for r in range(0, rgb8.shape[0], rows):
        out[r:r + rows] = linear_luminance(table[rgb8[r:r + rows]])
    return out


def resolve(encoding: str, channels: int) -> str:
    """``"srgb"`` or ``"linear"``: what ``encoding`` ("auto", "srgb", "linear") means for a photo of
    ``channels`` channels (auto: colour is sRGB, grey is linear)."""
    if encoding not in ENCODINGS:
        raise ValueError(f"unknown encoding {encoding!r}: {', '.join(ENCODINGS)}")
    if encoding != "auto":
        return encoding
    return "srgb" if channels == 3 else "linear"
