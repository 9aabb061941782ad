"""Ordinary-photo scenes made from face crops: each crop scaled, turned, tinted and pasted into a
larger colour frame, so that a crop with ground truth (a Yale B photo and its frontal twin) can be
scored where it sits in a photo as it is scored alone. Scenes are made in linear light (Yale B's
crops are) and saved sRGB-encoded, as a camera saves a photo. Nothing here is stored: scenes are
made when a test or benchmark asks for them.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..photo.encoding import linear_to_srgb

SKIN_TINTS = ((1.0, 0.78, 0.62), (0.92, 0.72, 0.58), (0.75, 0.55, 0.42), (1.0, 0.85, 0.75))  # RGB gains


@dataclass(frozen=True)
class Pasted:
    """Where a crop (h, w) went in a scene: ``matrix`` (2, 3) crop pixel -> scene pixel (a
    similarity); ``tint`` (3,) the RGB gain its grey was given."""

    matrix: np.ndarray
    shape: tuple[int, int]
    tint: tuple[float, float, float]

    @property
    def scale(self) -> float:
        return float(np.sqrt(abs(np.linalg.det(self.matrix[:, :2]))))

    def points(self, xy: np.ndarray) -> np.ndarray:
        """(n, 2) crop pixels -> scene pixels."""
        return np.asarray(xy, np.float64) @ self.matrix[:, :2].T + self.matrix[:, 2]

    def warp(self, image: np.ndarray, scene_shape: tuple[int, int], nearest: bool = False) -> np.ndarray:
        """A crop-sized array (h, w[, C]) carried into the scene (H, W[, C]); 0 beyond the crop."""
        flags = cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR
        src = np.asarray(image, np.float32)
        if self.scale < 0.7 and not nearest:  # shrinking: average first, as a camera would
            src = cv2.GaussianBlur(src, (0, 0), 0.5 * np.sqrt(1.0 / self.scale**2 - 1.0))
        return cv2.warpAffine(src, self.matrix, (scene_shape[1], scene_shape[0]), flags=flags,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def background(shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """(H, W, 3) float32 RGB in [0, 1]: a photo's surroundings without a face: smooth colour
    gradients, a few blurred coloured shapes and a little texture."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    corners = rng.uniform(0.15, 0.85, (4, 3)).astype(np.float32)
    u, v = (xx / max(w - 1, 1))[..., None], (yy / max(h - 1, 1))[..., None]
    img = (corners[0] * (1 - u) * (1 - v) + corners[1] * u * (1 - v) + corners[2] * (1 - u) * v + corners[3] * u * v)
    for _ in range(8):
        c = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        axes = (int(rng.integers(w // 20, w // 4)), int(rng.integers(h // 20, h // 4)))
        layer = np.zeros((h, w), np.float32)
        cv2.ellipse(layer, c, axes, float(rng.uniform(0, 180)), 0, 360, 1.0, -1)
        layer = cv2.GaussianBlur(layer, (0, 0), 3)[..., None]
        img = img * (1 - 0.7 * layer) + 0.7 * layer * rng.uniform(0.05, 0.95, 3).astype(np.float32)
    img += 0.02 * cv2.GaussianBlur(rng.standard_normal((h, w, 3)).astype(np.float32), (0, 0), 1.0)
    return np.clip(img, 0.0, 1.0).astype(np.float32)


def placement(crop_shape: tuple[int, int], width_share: float, scene_shape: tuple[int, int], centre: tuple[float, float],
              roll_deg: float, tint: tuple[float, float, float]) -> Pasted:
    """The similarity that makes a crop ``width_share`` of the scene's width, turned by ``roll_deg``
    (counter-clockwise as seen) about its centre, which lands on ``centre`` (x, y) of the scene."""
    h, w = crop_shape
    s = width_share * scene_shape[1] / w
    a = np.radians(roll_deg)
    lin = s * np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])  # y down: counter-clockwise as seen
    c = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    return Pasted(np.column_stack([lin, np.asarray(centre, np.float64) - lin @ c]), (h, w), tint)


HAIR = (0.16, 0.11, 0.08)  # RGB of the head drawn behind a crop


def paste(scene: np.ndarray, crop: np.ndarray, where: Pasted, edge_px: float = 3.0, head: bool = True) -> np.ndarray:
    """``scene`` (H, W, 3) with the grey ``crop`` (h, w) in [0, 1] pasted by ``where`` (tinted), its
    border blended over ``edge_px`` scene pixels; returns the new scene. ``head``: first a head's
    dark outline (hair, ears, neck: an ellipse a little larger than the crop, and a neck below it),
    as a face in a photo has around it: a tight crop alone on a background is a face cut out of its
    head, which the face detector finds only larger."""
    h, w = where.shape
    if head:
        pad = int(round(0.4 * w))
        big = np.zeros((h + 2 * pad, w + 2 * pad), np.float32)
        cv2.ellipse(big, (pad + w // 2, pad + int(0.42 * h)), (int(0.62 * w), int(0.66 * h)), 0, 0, 360, 1.0, -1)
        cv2.rectangle(big, (pad + int(0.22 * w), pad + int(0.8 * h)), (pad + int(0.78 * w), h + 2 * pad - 1), 1.0, -1)
        shifted = Pasted(where.matrix @ np.array([[1.0, 0.0, -pad], [0.0, 1.0, -pad], [0.0, 0.0, 1.0]]),
                         big.shape, where.tint)
        a = cv2.GaussianBlur(shifted.warp(big, scene.shape[:2]), (0, 0), max(1.0, 0.01 * w * where.scale))[..., None]
        scene = scene * (1 - a) + a * np.asarray(HAIR, np.float32)
    a = where.warp(crop_alpha(where, edge_px), scene.shape[:2])[..., None]
    grey = where.warp(np.asarray(crop, np.float32), scene.shape[:2])
    face = grey[..., None] * np.asarray(where.tint, np.float32)
    return np.clip(scene * (1 - a) + face * a, 0.0, 1.0).astype(np.float32)


def crop_alpha(where: Pasted, edge_px: float = 3.0) -> np.ndarray:
    """(h, w) float32 in [0, 1]: how much of each crop pixel ``paste`` puts over the scene: 1 inside, a
    blend with the scene over its border's ``edge_px`` scene pixels."""
    h, w = where.shape
    alpha = np.zeros((h, w), np.float32)
    margin = max(1, int(np.ceil(edge_px / max(where.scale, 1e-6))))
    alpha[margin:h - margin, margin:w - margin] = 1.0
    return cv2.GaussianBlur(alpha, (0, 0), max(margin / 2.0, 0.5))


def encode(scene: np.ndarray, path, quality: int | None = 92) -> None:
    """Write an RGB scene of linear light in [0, 1] as a camera would: sRGB-encoded, JPEG at
    ``quality`` (None: PNG)."""
    bgr = (linear_to_srgb(scene)[..., ::-1] * 255 + 0.5).astype(np.uint8)
    params = [cv2.IMWRITE_JPEG_QUALITY, quality] if quality is not None else []
    if not cv2.imwrite(str(path), bgr, params):
        raise OSError(f"{path}: cannot be written")


def free_centre(crop_shape: tuple[int, int], width_share: float, roll_deg: float, scene_shape: tuple[int, int],
                rng: np.random.Generator, taken: list[np.ndarray] = (), tries: int = 200) -> tuple[float, float] | None:
    """A centre (x, y) for a crop of ``crop_shape`` made ``width_share`` of the scene's width and
    turned by ``roll_deg`` that keeps all of it inside the scene and off the boxes ``taken`` (each
    ``x0, y0, x1, y1``); None when none was found in ``tries`` draws."""
    h, w = crop_shape
    s = width_share * scene_shape[1] / w
    a = np.radians(roll_deg)
    half = 0.5 * s * np.array([w * abs(np.cos(a)) + h * abs(np.sin(a)), w * abs(np.sin(a)) + h * abs(np.cos(a))])
    lo, hi = half + 2.0, np.array([scene_shape[1], scene_shape[0]], np.float64) - half - 2.0
    if np.any(hi < lo):
        return None
    for _ in range(tries):
        c = rng.uniform(lo, hi)
        box = np.concatenate([c - half, c + half])
        if all(box[2] < t[0] or box[0] > t[2] or box[3] < t[1] or box[1] > t[3] for t in taken):
            return float(c[0]), float(c[1])
    return None
