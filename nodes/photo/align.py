"""Alignment between an input photo's pixel grid and the model's canonical grid.

An ``Alignment`` is the similarity (uniform scale, in-plane rotation, translation) taking a
model pixel ``(col, row)`` to an input pixel. Images are resampled onto the model grid with
it, and every output is mapped back through its inverse, with vectors (normals, light)
rotated and heights scaled to the input's pixel units.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..geometry.similarity import two_point_similarity


@dataclass(frozen=True)
class Alignment:
    """``matrix``: (2, 3) float64 model pixel -> input pixel; ``how``: how it was found.

    A similarity, or a similarity composed with a small vertical stretch (``stretch_vertically``:
    a face longer or shorter than the model's). Vectors (normals, light) follow its rotation only:
    the fit explains the shading the photo shows, so its normals are already the photo's."""

    matrix: np.ndarray
    how: str

    @property
    def scale(self) -> float:
        """Input pixels per model pixel (the geometric mean of the two axes' scales)."""
        return float(np.sqrt(abs(np.linalg.det(self.matrix[:, :2]))))

    @property
    def rotation(self) -> np.ndarray:
        """(2, 2) rotation part, pixel axes: ``matrix / scale`` for a similarity, else the polar factor."""
        lin = self.matrix[:, :2]
        if abs(lin[0, 0] - lin[1, 1]) + abs(lin[0, 1] + lin[1, 0]) < 1e-12 * max(self.scale, 1e-12):
            return lin / self.scale
        u, _, vt = np.linalg.svd(lin)
        return u @ vt

    def cropped(self, x0: float, y0: float) -> Alignment:
        """The same placement on the photo cropped at column ``x0``, row ``y0`` (the crop's pixel
        ``(0, 0)`` is the photo's ``(x0, y0)``)."""
        return Alignment(self.matrix - np.array([[0.0, 0.0, x0], [0.0, 0.0, y0]]), self.how)

    def points_to_input(self, points: np.ndarray) -> np.ndarray:
        """(M, 2) model-grid points ``(col, row)`` -> (M, 2) input pixels ``(x, y)``."""
        return np.asarray(points, np.float64) @ self.matrix[:, :2].T + self.matrix[:, 2]

    def vector_to_input(self, v: np.ndarray) -> np.ndarray:
        """Rotate camera-frame vectors (..., 3) from the model's frame to the input's."""
        return _rotate_xy(v, self.rotation)

    def vector_to_model(self, v: np.ndarray) -> np.ndarray:
        """Rotate camera-frame vectors (..., 3) from the input's frame to the model's."""
        return _rotate_xy(v, self.rotation.T)


IDENTITY = Alignment(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), "identity")  # the photo is on the model grid


def _rotate_xy(v: np.ndarray, rot_pix: np.ndarray) -> np.ndarray:
    """Apply a 2x2 rotation given in (col, row) pixel axes to the (x, y) of camera vectors."""
    v = np.asarray(v, np.float64)
    flip = np.array([1.0, -1.0])  # camera y is up, rows go down
    xy = (v[..., :2] * flip) @ rot_pix.T * flip
    return np.concatenate([xy, v[..., 2:3]], axis=-1)


def centred_alignment(input_shape: tuple[int, int], grid: tuple[int, int]) -> Alignment:
    """Assume the input is a frontal face crop framed like the model grid.

    The model grid is scaled uniformly to fit inside the input and centred in it.
    """
    hi, wi = input_shape[:2]
    hm, wm = grid
    s = min(wi / wm, hi / hm)
    tx = (wi - 1) / 2 - s * (wm - 1) / 2
    ty = (hi - 1) / 2 - s * (hm - 1) / 2
    return Alignment(np.array([[s, 0.0, tx], [0.0, s, ty]]), "centred crop")


def eyes_alignment(eyes_input: np.ndarray, eyes_model: np.ndarray, how: str = "eyes") -> Alignment:
    """The similarity putting the model's canonical eyes (2, 2) on the input's eyes (2, 2).

    Eyes are ``[[x, y], [x, y]]`` pixel coordinates (x = column), image-left eye first.
    """
    try:
        return Alignment(two_point_similarity(eyes_model, eyes_input).matrix, how)
    except ValueError:
        raise ValueError("the two eye positions coincide") from None


def stretch_vertically(al: Alignment, factor: float, about_row: float, how: str) -> Alignment:
    """``al`` after stretching the model grid by ``factor`` along its rows about ``about_row``
    (model pixels): a face whose features below (and above) that row lie ``factor`` times as far
    from it as the model's. ``factor`` 1 returns ``al`` unchanged."""
    if factor == 1.0:
        return al
    stretch = np.array([[1.0, 0.0, 0.0], [0.0, factor, about_row * (1.0 - factor)], [0.0, 0.0, 1.0]])
    return Alignment((np.vstack([al.matrix, [0.0, 0.0, 1.0]]) @ stretch)[:2], how)


def inside_input(al: Alignment, input_shape: tuple[int, int], grid: tuple[int, int]) -> np.ndarray:
    """(Hm, Wm) bool: model pixels whose place in the input lies inside the photo."""
    r0, r1, c0, c1 = grid_reach(al, grid, input_shape, 2)
    ones = np.ones((r1 - r0, c1 - c0), np.float32)
    inside = cv2.warpAffine(ones, al.cropped(c0, r0).matrix, (grid[1], grid[0]),
                            flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return inside >= 0.999


def grid_reach(al: Alignment, grid: tuple[int, int], shape: tuple[int, int], reach: int) -> tuple[int, int, int, int]:
    """``(row0, row1, col0, col1)``: the photo's (H, W) pixels the model grid (Hm, Wm) covers under ``al``,
    grown by ``reach`` pixels and cut to the photo; the whole photo when the grid lies wholly off it."""
    corners = al.points_to_input(np.array([[-1, -1], [grid[1], -1], [-1, grid[0]], [grid[1], grid[0]]], np.float64))
    c0, r0 = np.maximum(np.floor(corners.min(axis=0)).astype(int) - reach, 0)
    c1, r1 = np.minimum(np.ceil(corners.max(axis=0)).astype(int) + reach + 1, [shape[1], shape[0]])
    if c1 <= c0 or r1 <= r0:
        return 0, shape[0], 0, shape[1]
    return int(r0), int(r1), int(c0), int(c1)


def to_model_grid(image: np.ndarray, al: Alignment, grid: tuple[int, int]) -> np.ndarray:
    """Resample an input image (H, W) or (H, W, C) onto the model grid (area-averaged when shrinking). Only the
    photo's pixels the grid reaches (and the blur's) are touched: a 4-megapixel photo costs what its
    face does."""
    img = image if hasattr(image, "shape") else np.asarray(image)  # (a ``Decoded8`` decodes only the crop)
    sigma = 0.5 * np.sqrt(al.scale**2 - 1.0) if al.scale > 1.5 else 0.0
    r0, r1, c0, c1 = grid_reach(al, grid, img.shape, int(np.ceil(4 * sigma)) + 2)  # OpenCV's kernel: 4 sigma
    crop = np.asarray(img[r0:r1, c0:c1], np.float32)
    if sigma:
        # pre-blurred so a large photo is averaged, not aliased, when sampled at the model grid
        crop = cv2.GaussianBlur(crop, (0, 0), sigma)
    return cv2.warpAffine(crop, al.cropped(c0, r0).matrix, (grid[1], grid[0]),
                          flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)


def _to_input(values: np.ndarray, al: Alignment, shape: tuple[int, int], interp: int) -> np.ndarray:
    return cv2.warpAffine(np.asarray(values, np.float32), al.matrix, (shape[1], shape[0]), flags=interp,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)


# a mask is smoothed over this many model pixels before it is brought to the photo: its border is then a curve,
# not a staircase of model pixels (several photo pixels each: a jagged jaw line in the relit photo)
MASK_SMOOTH = 1.0
# a field is brought to the photo wherever this much of the nearby model pixels are in its mask (renormalised
# there): a little beyond the smoothed mask, so that mask never reaches a photo pixel the field leaves unknown
FIELD_REACH = 0.2


def mask_to_input(mask: np.ndarray, al: Alignment, shape: tuple[int, int]) -> np.ndarray:
    """Model-grid mask (Hm, Wm) bool -> input-grid mask (H, W) bool, its border smoothed over
    ``MASK_SMOOTH`` model pixels."""
    soft = cv2.GaussianBlur(mask.astype(np.float32), (0, 0), MASK_SMOOTH)
    # where a field of the mask is known (``scalar_to_input``): the smoothed border never runs past it
    known = _to_input(mask.astype(np.float32), al, shape, cv2.INTER_LINEAR) >= FIELD_REACH
    return (_to_input(soft, al, shape, cv2.INTER_LINEAR) >= 0.5) & known


def scalar_to_input(values: np.ndarray, mask: np.ndarray, al: Alignment, shape: tuple[int, int],
                    nearest: bool = False) -> np.ndarray:
    """Model-grid field (Hm, Wm), NaN off ``mask`` -> input grid (H, W), known wherever ``FIELD_REACH``
    of the nearby model pixels are in ``mask`` (renormalised: a little beyond ``mask_to_input``'s border),
    NaN elsewhere."""
    v = np.where(mask, np.nan_to_num(values), 0.0)
    out = _to_input(v, al, shape, cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR)
    wts = _to_input(mask.astype(np.float32), al, shape, cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR)
    inside = wts >= (0.5 if nearest else FIELD_REACH)
    out = np.where(inside, out / np.maximum(wts, 1e-6), np.nan)  # renormalise at the edge
    return out.astype(np.float32)


def normals_to_input(normals: np.ndarray, mask: np.ndarray, al: Alignment, shape: tuple[int, int]) -> np.ndarray:
    """Model-grid normals (Hm, Wm, 3) -> input grid (H, W, 3), rotated with the similarity."""
    comps = [scalar_to_input(normals[..., i], mask, al, shape) for i in range(3)]
    n = al.vector_to_input(np.stack(comps, axis=-1))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return n.astype(np.float32)


def normals_to_model(normals: np.ndarray, valid: np.ndarray, al: Alignment,
                     grid: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Input-grid normals (H, W, 3), camera frame, known where ``valid`` (H, W) -> the model
    grid: ``(normals (Hm, Wm, 3) rotated into the model's frame, known (Hm, Wm) bool)``; a model
    pixel is known when every input pixel it averages is."""
    v = np.asarray(valid, bool)
    comps = np.stack([to_model_grid(np.where(v, normals[..., i], 0.0), al, grid) for i in range(3)], axis=-1)
    known = (to_model_grid(v.astype(np.float32), al, grid) >= 0.999) & inside_input(al, v.shape, grid)
    n = al.vector_to_model(comps)
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    return np.where(known[..., None], n, np.nan).astype(np.float32), known


def face_box(mask: np.ndarray, al: Alignment, shape: tuple[int, int], margin: float = 0.0) -> tuple[int, int, int, int]:
    """``(row0, row1, col0, col1)``: the input pixels the model-grid ``mask`` (Hm, Wm) covers under
    ``al``, grown by ``margin`` pixels and cut to the input ``shape`` (H, W). A field brought to the
    photo (``scalar_to_input``) reaches at most one model pixel beyond its mask: ``reach_margin``."""
    rows, cols = np.nonzero(mask)
    corners = np.array([[cols.min(), rows.min()], [cols.max(), rows.min()], [cols.min(), rows.max()],
                        [cols.max(), rows.max()]], np.float64)
    mapped = al.points_to_input(corners)
    lo, hi = mapped.min(axis=0) - margin - 1, mapped.max(axis=0) + margin + 2
    c0, r0 = int(max(0, np.floor(lo[0]))), int(max(0, np.floor(lo[1])))
    c1, r1 = int(min(shape[1], np.ceil(hi[0]))), int(min(shape[0], np.ceil(hi[1])))
    return r0, max(r1, r0 + 1), c0, max(c1, c0 + 1)


def reach_margin(al: Alignment) -> float:
    """Photo pixels a ``face_box`` must grow by to hold everything ``mask_to_input`` and
    ``scalar_to_input`` can mark as known (one model pixel, interpolated, plus one for rounding)."""
    return al.scale + 1.0
