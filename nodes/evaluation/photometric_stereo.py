"""Robust Lambertian photometric stereo: normals and albedo from many images under known lights.

Used to build ground truth for real photographs (``evaluation.yaleb``), not by the method itself.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..geometry.reflectance import lambertian


@dataclass
class StereoResult:
    """normals (H, W, 3) float32 camera frame, NaN where not ``valid``; albedo (H, W) float32
    (brightness per unit shading); valid (H, W) bool: enough trusted samples and a good fit;
    used (H, W) int: samples kept per pixel; residual (H, W): RMS of the kept samples' misfit."""

    normals: np.ndarray
    albedo: np.ndarray
    valid: np.ndarray
    used: np.ndarray
    residual: np.ndarray


def _solve(images: np.ndarray, lights: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Per-pixel weighted least squares for ``g = albedo * n``; images/keep (M, P); -> (P, 3)."""
    w = keep.astype(np.float64)
    gram = np.einsum("mp,mi,mj->pij", w, lights, lights)
    rhs = np.einsum("mp,mp,mi->pi", w, images, lights)
    gram += 1e-9 * np.eye(3)
    return np.linalg.solve(gram, rhs[..., None])[..., 0]


def photometric_stereo(images: np.ndarray, lights: np.ndarray, dark: float = 0.03, bright: float = 0.98,
                       min_samples: int = 6, outlier_k: float = 2.5, rounds: int = 3) -> StereoResult:
    """Lambertian photometric stereo with shadowed, saturated and outlying samples left out.

    images: (M, H, W) brightness in [0, 1] (ambient already removed); lights: (M, 3) unit
    vectors toward each light, camera frame. A sample is trusted when ``dark < I < bright``;
    after a first fit, samples the fit predicts in attached shadow (``n . s <= 0.05``) and those
    whose misfit exceeds ``outlier_k`` times the pixel's robust scale (specular shine,
    cast shadow the threshold missed) are dropped and the fit repeated, ``rounds`` times.
    """
    imgs = np.asarray(images, np.float64)
    m, h, w = imgs.shape
    L = np.asarray(lights, np.float64)
    flat = imgs.reshape(m, -1)
    keep = (flat > dark) & (flat < bright)
    g = _solve(flat, L, keep)
    for _ in range(rounds):
        pred = L @ g.T  # (M, P)
        resid = np.abs(flat - pred)
        scale = 1.4826 * np.median(np.where(keep, resid, np.nan), axis=0)
        scale = np.nan_to_num(np.maximum(scale, 0.01), nan=0.01)
        keep = (flat > dark) & (flat < bright) & (pred > 0.05 * np.linalg.norm(g, axis=1)) & (resid <= outlier_k * scale)
        g = _solve(flat, L, keep)
    used = keep.sum(axis=0)
    albedo = np.linalg.norm(g, axis=1)
    normals = g / np.maximum(albedo[:, None], 1e-12)
    resid = np.sqrt(np.sum(np.where(keep, (flat - L @ g.T) ** 2, 0.0), axis=0) / np.maximum(used, 1))
    valid = (used >= min_samples) & (albedo > 1e-3) & (normals[:, 2] > 0)
    normals[~valid] = np.nan
    return StereoResult(normals.reshape(h, w, 3).astype(np.float32), albedo.reshape(h, w).astype(np.float32),
                        valid.reshape(h, w), used.reshape(h, w), resid.reshape(h, w).astype(np.float32))


def render(result: StereoResult, light: np.ndarray) -> np.ndarray:
    """(H, W) Lambertian image of the stereo surface under ``light`` (3,), 0 where not valid."""
    return np.where(result.valid, lambertian(np.nan_to_num(result.normals), light, np.nan_to_num(result.albedo)), 0.0)


def register_translation(image: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
    """Shift ``image`` (H, W) by the sub-pixel translation that best matches ``reference``
    (phase correlation, Hann window); returns ``(shifted image, (dx, dy))``."""
    a = np.asarray(reference, np.float32)
    b = np.asarray(image, np.float32)
    win = cv2.createHanningWindow(a.shape[::-1], cv2.CV_32F)
    (dx, dy), _ = cv2.phaseCorrelate(a, b, win)
    mat = np.array([[1.0, 0.0, -dx], [0.0, 1.0, -dy]])
    shifted = cv2.warpAffine(b, mat, a.shape[::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return shifted, (float(dx), float(dy))
