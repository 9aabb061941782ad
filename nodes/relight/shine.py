"""The photo's shine: the light's own reflection on skin (a highlight, a glint), which stays with the light and
is not the skin's colour. A new light takes it away where it darkens the skin or moves the highlight.

Arrays are on the photo's pixel grid (H, W[, C]), linear.
"""
from __future__ import annotations

import cv2
import numpy as np

from .fields import weighted_blur

# shine: a skin pixel's brightness above this x its local skin level (averaged over ``SHEEN_SCALE`` interocular
# distances) is the photo's specular shine, not the skin's colour (``sheen``)
SHEEN_MARGIN = 1.1
SHEEN_SCALE = 0.15
# a glint (``glints``): skin's colour plus white to within this share of the pixel's colour, with at least this
# share of the skin's level around it under the white
GLINT_FIT = 0.05
GLINT_DIFFUSE = 0.4
# how sharp skin's shine is (``shine_lobe``): the Blinn-Phong exponent 2 / m^2 - 2 of the Beckmann roughness
# m = 0.35 measured on faces (Weyrich et al. 2006): the peak of a highlight keeps 13 % of itself under a light
# moved by 60 degrees, a cheek's shine beside it under 1 %
SHINE_LOBE = 14.0


def glints(photo: np.ndarray, skin: np.ndarray, where: np.ndarray, sigma_px: float,
           features: np.ndarray | None = None, reach_px: float | None = None) -> np.ndarray:
    """(H, W) bool: the pixels of ``where`` (H, W) bool that are skin with the light's white reflection on it, too
    white to pass ``skin``'s colour test. Each is brighter than the skin's level around it (the average over
    ``sigma_px`` of ``skin`` (H, W) bool) and its colour ``c`` (linear RGB) is the skin's median colour ``m`` times
    ``a`` plus white ``k (1, 1, 1)``, ``k > 0``, to within ``GLINT_FIT`` of ``|c|``; and its patch of such pixels
    holds one with skin under the white, at least ``GLINT_DIFFUSE`` of that level in ``a`` (a highlight's core is
    white, the skin's colour showing at its rim), within ``reach_px`` of it when given (a highlight is small: white
    hair or a wall that one touches is not taken whole). Not in ``features`` (H, W) bool (eyes, teeth, lips, brows:
    white or bright, and theirs). A grey photo has no colour to tell by: ``skin`` is all of it there, and none are.

    A highlight on a forehead or a cheek is whiter than the skin around it; told apart from the skin by its colour
    alone it was kept as the photo shows it, like an eye, and stayed as a pale patch on a cheek relit into shadow.
    A grey wall or white hair (no skin under the white at its rim) and a lip (not the skin's colour) are not."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    out = np.zeros(where.shape, bool)
    if img.shape[-1] != 3 or skin.sum() <= 50:
        return out
    m = np.median(img[skin], axis=0).astype(np.float64)
    m = m / max(float(m.mean()), 1e-6)  # the skin's colour at brightness 1 (mean of the channels)
    basis = np.stack([m, np.ones(3)], axis=1)  # (3, 2): skin, white
    cand = where & ~skin
    if features is not None:
        cand &= ~features
    if not cand.any():
        return out
    c = img[cand].astype(np.float64)  # (n, 3)
    ak = c @ np.linalg.pinv(basis).T  # (n, 2) least squares: c ~ a m + k 1
    fit_error = np.linalg.norm(c - ak @ basis.T, axis=1) / np.maximum(np.linalg.norm(c, axis=1), 1e-6)
    level, _ = weighted_blur(img.mean(axis=-1), skin.astype(np.float32), sigma_px)
    lv = level[cand].astype(np.float64)
    white = (fit_error < GLINT_FIT) & (ak[:, 1] > 0.0) & (c.mean(axis=1) > lv)
    patches = np.zeros(where.shape, np.uint8)
    patches[cand] = white
    seeds = np.zeros(where.shape, bool)
    seeds[cand] = white & (ak[:, 0] >= GLINT_DIFFUSE * lv)
    count, labels = cv2.connectedComponents(patches, connectivity=8)
    keep = np.zeros(count, bool)
    keep[np.unique(labels[seeds])] = True
    keep[0] = False
    out = keep[labels]
    if reach_px is not None and seeds.any():
        out &= cv2.distanceTransform((~seeds).astype(np.uint8), cv2.DIST_L2, 3) <= reach_px
    return out


def sheen(albedo: np.ndarray, skin: np.ndarray, trusted: np.ndarray, sigma_px: float,
          margin: float = SHEEN_MARGIN) -> np.ndarray:
    """(H, W, C) float32 >= 0: the photo's shine in its measured albedo: on ``skin`` (H, W) bool, how far the
    albedo (H, W, C) rises above ``margin`` x its local level (the average over ``sigma_px`` of the ``trusted``
    (H, W) bool skin around it); 0 elsewhere. A highlight on a cheek, read as albedo, stays where it is whatever
    the new light, and glowed on a cheek relit into shadow (``shine_kept``)."""
    a = np.nan_to_num(np.atleast_3d(np.asarray(albedo, np.float32)))
    w = (skin & trusted).astype(np.float32)
    level, _ = weighted_blur(a, w, sigma_px)
    # again with the shine held down to the margin: a highlight would otherwise raise the level it is measured on
    level, _ = weighted_blur(np.minimum(a, np.float32(margin) * level), w, sigma_px)
    excess = np.clip(a - np.float32(margin) * level, 0.0, None)
    return np.where(skin[..., None], excess, np.float32(0.0)).astype(np.float32)


def shine_kept(lighting: np.ndarray, new_lighting: np.ndarray, lobe: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32 in [0, 1]: the share of the photo's shine a new light keeps: ``S'/S`` (a pixel going into
    shadow loses it) and at most ``lobe`` (``shine_lobe``: its highlight moves away). lighting, new_lighting (H, W)
    the photo's and the new light's."""
    keep = np.asarray(new_lighting, np.float32) / np.maximum(np.asarray(lighting, np.float32), np.float32(1e-3))
    if lobe is not None:
        keep = np.minimum(keep, lobe)
    return np.clip(keep, 0.0, 1.0).astype(np.float32)


def shine_lobe(normals: np.ndarray, light: np.ndarray, new_light: np.ndarray,
               exponent: float = SHINE_LOBE) -> np.ndarray:
    """(H, W) float32 in [0, 1]: how much of the photo's shine stays where it is under a new light. A highlight is
    the light's reflection toward the camera, brightest where the normal is halfway between the light and the
    view (Blinn-Phong: ``(n . h)^k``); under the new light that place moves to the new halfway vector ``h'``,
    and a pixel keeps ``((n . h') / (n . h))^k`` of its shine, at most all of it (no shine is made where the
    photo shows none). The photo's own light keeps it all. normals (H, W, 3), light and new_light (3,) unit,
    camera frame (the view, toward the camera, is +z)."""
    n = np.asarray(normals, np.float32)
    view = np.array([0.0, 0.0, 1.0])
    h = np.asarray(light, np.float64) + view
    h_new = np.asarray(new_light, np.float64) + view
    old = n @ (h / max(np.linalg.norm(h), 1e-9)).astype(np.float32)
    new = n @ (h_new / max(np.linalg.norm(h_new), 1e-9)).astype(np.float32)
    ratio = np.clip(new, 0.0, None) / np.maximum(old, np.float32(1e-3))
    return np.where(old > 1e-3, np.minimum(ratio, np.float32(1.0)) ** np.float32(exponent), np.float32(1.0)
                    ).astype(np.float32)
