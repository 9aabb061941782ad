"""A relit face put back into its photo: the layer one face gives for one light (``FaceLayer``), how the face's
change of light runs on into the photo around it (``outside_gain``) and fades in at its border
(``inner_alpha``), and every face's layer composed into the photo (``compose``). Pixels no layer changes are the
photo's, bit for bit.

Arrays are on the photo's pixel grid (H, W[, C]), linear; a layer's on its own box of it.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .fields import blur, smoothstep

# the relit face fades into the photo over this share of the feather inside its border (``inner_alpha``)
INNER_FEATHER = 0.4
# outside the face the photo follows the face's change of light within this range: up to 4x (a face's shadowed
# side brightened 16x would otherwise light its dark background up as a halo), down to 0.15x (a face relit into
# shadow darkens its ear, hair and neck with it)
RATIO_OUTSIDE = (0.15, 4.0)
# ... but on the face's own skin beyond the model (inside the face mesh's outline, past the model's mask: the jaw
# and cheeks of a face the model does not reach) up to this: it is the face, lit as its rim is. What bounds it is
# the relit rim's level beside it (``beyond_ratio``); this only keeps a black pixel's gain finite
RATIO_BEYOND = 64.0
# ... that reach fading back to ``RATIO_OUTSIDE`` over this share of the feather either side of that skin's border
BEYOND_EDGE = 0.25
# the face's change of light at its border is measured on its rim, this share of the feather wide (``face_rim``)
RIM_SHARE = 0.35


@dataclass(frozen=True)
class FaceLayer:
    """One relit face, to be put into its photo (``compose``). box: ``(y0, y1, x0, x1)`` the photo
    pixels it covers; inside: (h, w) bool the face; relit: (h, w, C) the relit face (used inside);
    gain: (h, w, C) the factor the photo is multiplied by outside the face (exactly 1 beyond the
    feather, so the photo there is untouched)."""

    box: tuple[int, int, int, int]
    inside: np.ndarray
    relit: np.ndarray
    gain: np.ndarray
    alpha: np.ndarray | None = None


def inner_alpha(face: np.ndarray, feather_px: float, inside: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32: how much of the relit face a face pixel shows, 1 beyond ``INNER_FEATHER`` x
    ``feather_px`` from the face's border and falling smoothly to 0 at it; the rest is the photo
    times the face's change of light there (``outside_gain``). A face relit far brighter than its
    shadowed border in the photo (the jaw at +-70) fades into it instead of ending on a cut. inside (H, W): each
    pixel's distance inside ``face`` when the caller has it (``cv2.distanceTransform``, precise), else measured."""
    if inside is None:
        inside = cv2.distanceTransform(face.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return smoothstep(inside, 0.0, max(INNER_FEATHER * feather_px, 1.0))


def face_rim(face: np.ndarray, width_px: float) -> np.ndarray:
    """(H, W) bool: the pixels of ``face`` (H, W) bool within ``width_px`` of its border (at least one)."""
    inside = cv2.distanceTransform(face.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return face & (inside <= max(width_px, 1.0))


def _padded_box(rows: np.ndarray, cols: np.ndarray, pad: int, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """``(y0, y1, x0, x1)``: the box of pixels ``rows``, ``cols`` (non-empty) grown by ``pad``, within ``shape``."""
    return (max(0, int(rows.min()) - pad), min(shape[0], int(rows.max()) + 1 + pad),
            max(0, int(cols.min()) - pad), min(shape[1], int(cols.max()) + 1 + pad))


def beyond_reach_box(beyond: np.ndarray | None, feather_px: float) -> tuple[np.ndarray, int, int] | None:
    """How far the face's change of light may exceed ``RATIO_OUTSIDE`` (up to ``RATIO_BEYOND``), in the box of
    ``beyond`` (H, W) bool, the face's own skin past the model's face, grown by the reach: ``(reach (h, w) float32
    in [0, 1], y0, x0)``, 1 on that skin and falling to 0 within ``BEYOND_EDGE`` of the feather ``feather_px`` of
    it; None when there is none. A 4-megapixel photo's layer is 2 megapixels; this box, a ring's, is less."""
    if beyond is None or not beyond.any():
        return None
    edge = max(BEYOND_EDGE * feather_px, 1.0)
    y0, y1, x0, x1 = _padded_box(np.nonzero(beyond.any(axis=1))[0], np.nonzero(beyond.any(axis=0))[0],
                                 int(np.ceil(edge)) + 1, beyond.shape)
    distance = cv2.distanceTransform((~beyond[y0:y1, x0:x1]).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return (1.0 - smoothstep(distance, 0.0, edge)).astype(np.float32), y0, x0


def beyond_reach(beyond: np.ndarray | None, feather_px: float) -> np.ndarray | None:
    """(H, W) float32 in [0, 1]: ``beyond_reach_box`` on the whole of ``beyond``'s grid (0 outside its box)."""
    box = beyond_reach_box(beyond, feather_px)
    if box is None:
        return None
    crop, y0, x0 = box
    reach = np.zeros(beyond.shape, np.float32)
    reach[y0:y0 + crop.shape[0], x0:x0 + crop.shape[1]] = crop
    return reach


def beyond_ratio(ratio: np.ndarray, photo: np.ndarray, level: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """The face's change of light ``ratio`` (..., C) held within ``RATIO_OUTSIDE``, or up to ``RATIO_BEYOND``
    as far as ``reach`` (..., 1) allows (geometrically: ``hi (RATIO_BEYOND / hi) ** reach``, so the photo just past
    that skin, where the reach fades, is lifted little more than ``RATIO_OUTSIDE`` allows); past ``RATIO_OUTSIDE``
    no brighter than the relit rim's ``level`` (..., C) beside it (the ratio is the rim's average: a jaw brighter
    in the photo than its rim would overshoot it). Where the ratio is within ``RATIO_OUTSIDE`` it is kept as it is.
    Any leading shape: images or pixel lists."""
    lo, hi = RATIO_OUTSIDE
    r = np.clip(ratio, lo, np.float32(hi) * np.float32(RATIO_BEYOND / hi) ** reach)
    return np.minimum(r, np.maximum(np.float32(hi), level / np.maximum(photo, np.float32(1e-6)))).astype(np.float32)


@dataclass(frozen=True)
class Surround:
    """What carries a face's change of light into the photo around it whatever the light (``surround``), so each
    light pays only for its own relit face (``gain``): the rim's weights ``w``
    (H, W, 1), their blur ``support`` (H, W) over ``sigma`` pixels and the photo's ``photo_rim`` (H, W, C), floored;
    the face's own skin past the model's face (``at`` its pixels, ``reach`` (n, 1) and ``img_at`` (n, C) there, or
    None); ``whole`` (H, W) bool where the ratio itself applies and ``fade`` (H, W, 1) how far it reaches beyond."""

    w: np.ndarray
    sigma: float
    support: np.ndarray
    photo_rim: np.ndarray
    at: tuple[np.ndarray, np.ndarray] | None
    reach: np.ndarray | None
    img_at: np.ndarray | None
    whole: np.ndarray
    fade: np.ndarray

    def gain(self, face_image: np.ndarray) -> np.ndarray:
        """(H, W, C) ``outside_gain`` for the relit face ``face_image`` (H, W, C): the only part a light changes."""
        relit = np.nan_to_num(np.atleast_3d(np.asarray(face_image, np.float32)))
        num = blur(relit * self.w, self.sigma)
        ratio = num / self.photo_rim
        if self.at is not None:
            level = num[self.at] / np.maximum(self.support[self.at], 1e-12)[:, None]
            beyond_at = beyond_ratio(ratio[self.at], self.img_at, level, self.reach)
        np.clip(ratio, *RATIO_OUTSIDE, out=ratio)
        if self.at is not None:
            ratio[self.at] = beyond_at
        return np.where(self.whole[..., None], ratio,
                        np.where(self.fade > 0, 1.0 + self.fade * (ratio - 1.0), np.float32(1.0))).astype(np.float32)


def surround(photo: np.ndarray, face: np.ndarray, feather_px: float, beyond: np.ndarray | None = None,
             person: np.ndarray | None = None) -> Surround:
    """``outside_gain``'s part that no light changes, for ``photo`` (H, W, C), ``face`` (H, W) bool and its
    arguments."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    sigma = max(feather_px / 2.0, 1.0)
    rim = face_rim(face, RIM_SHARE * feather_px).astype(np.float32)
    w = rim[..., None]
    support = blur(rim, sigma)
    photo_rim = np.maximum(blur(img * w, sigma), np.maximum(1e-3 * support, 1e-12)[..., None])
    box = beyond_reach_box(beyond, feather_px)
    at = reach = img_at = None
    if box is not None:  # the face's own skin and the reach beyond it, pixel by pixel (a thin ring)
        crop, y0, x0 = box
        ry, rx = np.nonzero(crop > 0)
        at = (ry + y0, rx + x0)
        reach, img_at = crop[ry, rx][:, None], img[at]
    whole = face if box is None else face | beyond  # where the ratio itself applies
    # the fade runs from the face's own outline: run from the model's face, it had ended where that outline lies a
    # feather beyond it (a portrait's cheek), and the skin relit into shadow met the photo's lit edge of the cheek
    distance = cv2.distanceTransform((~whole).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    fade = (1.0 - smoothstep(distance, 0.0, feather_px))[..., None] * (support[..., None] > 1e-3)
    if person is not None:  # a wall lit up or darkened around a relit face is a halo
        fade *= np.asarray(person, np.float32)[..., None]
    return Surround(w, sigma, support, photo_rim, at, reach, img_at, whole, fade)


def outside_gain(photo: np.ndarray, face_image: np.ndarray, face: np.ndarray, feather_px: float,
                 beyond: np.ndarray | None = None, person: np.ndarray | None = None) -> np.ndarray:
    """(H, W, C) the factor that carries a face's change of light into the photo around it: the
    face's relighting ratio (relit / photo, averaged over the face's rim, ``RIM_SHARE`` of the feather
    wide, within ``RATIO_OUTSIDE``) fading to exactly 1 over ``feather_px`` from the face, so the change runs on
    into the hair and neck without a seam and the photo beyond is untouched; inside the face, the
    ratio itself (what ``inner_alpha`` blends toward at the border). photo, face_image (H, W, C);
    face (H, W) bool; beyond (H, W) bool or None: the face's own skin past ``face`` (its outline beyond the
    model), which takes the ratio itself, up to ``RATIO_BEYOND`` (``beyond_reach``), the fade running from its
    edge; person (H, W) float in [0, 1]
    or None: how sure a segmentation is that each pixel is the person, not the background: the change of light
    around the face reaches only as far (hair and neck follow the face, the wall behind it keeps its light).
    A caller relighting one face under several lights keeps its ``surround`` and asks it for each light's
    (``Surround.gain``)."""
    return surround(photo, face, feather_px, beyond, person).gain(face_image)


def compose(photo: np.ndarray, layers: list[FaceLayer]) -> np.ndarray:
    """(H, W, C) float32 ``photo`` with every face of ``layers`` put back: first each face's
    ``gain`` on the photo around it (overlapping feathers multiply), then each face's own relit
    pixels, which no other face's feather touches. Pixels no layer changes are the photo's, bit for bit."""
    source = np.atleast_3d(photo)
    out = np.array(source, np.float32, copy=True)
    for layer in layers:
        y0, y1, x0, x1 = layer.box
        region = out[y0:y1, x0:x1]
        changed = np.any(layer.gain != 1.0, axis=-1) & ~layer.inside
        region[changed] = np.clip(region[changed] * layer.gain[changed], 0.0, 1.0)
    for layer in layers:
        y0, y1, x0, x1 = layer.box
        relit = layer.relit
        if layer.alpha is not None:  # the face's border fades into the photo, its light changed as around it
            a = layer.alpha[..., None]
            relit = a * relit + (1.0 - a) * source[y0:y1, x0:x1] * layer.gain
        out[y0:y1, x0:x1][layer.inside] = np.clip(relit[layer.inside], 0.0, 1.0)
    return out


def composite(photo: np.ndarray, face_image: np.ndarray, face: np.ndarray, feather_px: float) -> np.ndarray:
    """(H, W, C) the photo with one relit face put back (``compose`` of its one layer)."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    relit = np.atleast_3d(np.asarray(face_image, np.float32))
    layer = FaceLayer((0, img.shape[0], 0, img.shape[1]), np.asarray(face, bool), relit,
                      outside_gain(img, relit, face, feather_px))
    return compose(img, [layer])
