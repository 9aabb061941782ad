"""The light a face gets, as the fitted shape explains it: a point light's ``n . s`` and the room's share of the
light (ambient), on the face's box at the photo's resolution.

``Shading`` holds what every light shares (the normals on the photo's grid, the room's light); ``lighting``
gives ``a + (1 - a) S`` for any light, ``S = max(n . s, 0)`` less the share of each pixel its cast shadow covers.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

# the share of the light a face gets from the room, not the lamp (ambient, fill): a face relit from the side has its
# shadowed side this bright, as a photo's is, not black. Fitted to the photo's skin within this range
# (``fit_ambient``), the default where too little skin tells
DEFAULT_AMBIENT = 0.15
AMBIENT_RANGE = (0.01, 0.9)
# ... of the shares explaining the skin within this share of the best, the one nearest the default (``fit_ambient``)
AMBIENT_TOLERANCE = 0.1
# ... on skin this far inside the face's border (interocular distances), its brightness averaged over this many
AMBIENT_RIM = 0.1
AMBIENT_SIGMA = 0.05


def with_ambient(shading: np.ndarray, ambient: float) -> np.ndarray:
    """(H, W) float32 the light a surface gets from a point light (``shading``, ``n . s`` clipped at
    0) and the room around it: ``a + (1 - a) S``."""
    return (np.float32(ambient) + np.float32(1.0 - ambient) * np.asarray(shading, np.float32)).astype(np.float32)


@dataclass(frozen=True)
class Shading:
    """The fitted shape's shading on a face's box (h, w): ``normals`` (h, w, 3) float32 unit, camera frame (0 off
    the face); ``ambient`` the room's share of the light; ``light`` (3,) unit toward the photo's light."""

    normals: np.ndarray
    ambient: float
    light: np.ndarray

    def direct(self, light: np.ndarray | None = None) -> np.ndarray:
        """(h, w) float32 ``max(n . s, 0)`` for ``light`` (3,) (None: the photo's)."""
        s = self.light if light is None else np.asarray(light, np.float64) / np.linalg.norm(light)
        return np.clip(self.normals @ s.astype(np.float32), 0.0, None)

    def lighting(self, light: np.ndarray | None = None, cast: np.ndarray | None = None) -> np.ndarray:
        """(h, w) float32 ``a + (1 - a) S``: ``S`` the ``direct`` light less the share ``cast`` (h, w) in [0, 1] of
        each pixel its cast shadow covers (None: none)."""
        direct = self.direct(light)
        if cast is not None:
            direct = direct * (np.float32(1.0) - np.asarray(cast, np.float32))
        return with_ambient(direct, self.ambient)


def fit_ambient(photo: np.ndarray, direct: np.ndarray, skin: np.ndarray, sigma_px: float) -> float:
    """The room's share of the light that best explains the photo's skin: the ``a`` of ``AMBIENT_RANGE`` whose
    shading ``a + (1 - a) S`` (``S`` = ``direct`` (h, w), the fitted ``max(n . s, 0)``) fits the skin's brightness
    (``photo`` (h, w, C) linear, averaged over ``sigma_px`` of the ``skin`` (h, w) bool: pores and noise are no
    shading) best up to one albedo, in log (least squares, a grid of ``a``); ``DEFAULT_AMBIENT`` when too little skin
    tells. A soft light (a window, a softbox, a cloudy sky) leaves little shading and fits a large ``a``; a lamp in a
    dark room, a small one. The light's direction alone, fitted to a softly lit face's albedo (a shiny forehead, a
    beard), came out steep, and its shading taken out of the photo and put back from the front repainted the face."""
    w = np.asarray(skin, bool)
    if w.sum() < 100:
        return DEFAULT_AMBIENT
    level = _skin_level(photo, w, sigma_px)
    # the shading averaged over the skin as the photo is: at the skin's edge the average is one-sided, and the
    # shading's own there (not the pixel's) is what the photo's level is made of (a + (1 - a) S is linear in S)
    s = _skin_level(np.asarray(direct, np.float32), w, sigma_px, log=False)
    candidates = np.geomspace(*AMBIENT_RANGE, 48)
    errors = np.array([np.var(level - np.log(a + (1.0 - a) * s)) for a in candidates])
    # a light near the view axis leaves the skin little shading to tell the room's share by (an evenly lit webcam
    # face fitted 0.01 where 0.15 explained it within 5 %, and a side light then drew black shadows): of the shares
    # that explain the skin within ``AMBIENT_TOLERANCE`` of the best, the one nearest the default (in log)
    near = candidates[errors <= errors.min() * (1.0 + AMBIENT_TOLERANCE)]
    return float(near[np.argmin(np.abs(np.log(near / DEFAULT_AMBIENT)))])


def _skin_level(photo: np.ndarray, skin: np.ndarray, sigma_px: float, log: bool = True) -> np.ndarray:
    """(n,) float64 ln of the photo's brightness (``photo`` (h, w[, C]) linear) averaged over ``sigma_px`` of the
    ``skin`` (h, w) bool, at each of its pixels (the average itself with ``log=False``)."""
    grey = np.atleast_3d(np.asarray(photo, np.float32)).mean(axis=-1)
    num = cv2.GaussianBlur(np.where(skin, grey, 0.0).astype(np.float32), (0, 0), max(sigma_px, 1.0))
    den = cv2.GaussianBlur(skin.astype(np.float32), (0, 0), max(sigma_px, 1.0))
    level = num[skin] / np.maximum(den[skin], 1e-6)
    return (np.log(np.maximum(level, 1e-5)) if log else level).astype(np.float64)


