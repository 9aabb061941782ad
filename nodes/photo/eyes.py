"""Eye centres in a face photo, for aligning it to the model grid.

Method (OpenCV's Haar eye cascade, shipped with opencv-python-headless 4.x):
1. the cascade runs on the photo and on a contrast-equalised copy (CLAHE on the log image), so
   an eye on the shadowed side of a side-lit face is still found;
2. detections of one eye (nested boxes, both images) are merged; candidates in the upper
   65 % of the photo are paired: roughly level (|dy| <= 0.25 dx),
   similar in size, 0.2 to 0.8 of the photo's width apart; the best-scoring pair wins;
3. with only one eye found (the other lost in deep shadow), the other is its mirror image
   about the photo's vertical centre line (a frontal face, roughly centred);
4. with none, ``detect_eyes`` returns None and the caller falls back to a centred frontal crop.
"""
from __future__ import annotations

from functools import lru_cache
from itertools import combinations

import cv2
import numpy as np


@lru_cache(maxsize=1)
def _cascade() -> cv2.CascadeClassifier:
    path = cv2.data.haarcascades + "haarcascade_eye.xml"
    c = cv2.CascadeClassifier(path)
    if c.empty():
        raise RuntimeError(f"OpenCV's eye cascade is missing ({path}): install opencv-python-headless 4.x")
    return c


def eye_candidates(image: np.ndarray) -> np.ndarray:
    """(n, 3) candidate eyes ``[x, y, size]`` in pixels from the cascade on ``image`` (H, W) in [0, 1]."""
    img8 = (np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8)
    logimg = np.log1p(np.asarray(image, np.float32) * 255.0) / np.log(256.0)
    eq = cv2.createCLAHE(clipLimit=3.0, tileGridSize=(4, 4)).apply((logimg * 255 + 0.5).astype(np.uint8))
    h, w = img8.shape
    lo, hi = max(8, int(0.06 * w)), max(12, int(0.4 * w))
    found = []
    cascade = _cascade()
    for im in (img8, eq):
        for x, y, bw, bh in cascade.detectMultiScale(im, scaleFactor=1.05, minNeighbors=3, minSize=(lo, lo),
                                                    maxSize=(hi, hi)):
            found.append((x + bw / 2.0, y + bh / 2.0, float(bw)))
    return merge_overlapping(np.array(found, np.float64).reshape(-1, 3))


def merge_overlapping(candidates: np.ndarray, reach: float = 0.6) -> np.ndarray:
    """Merge detections of one eye (from the two images, or nested boxes): candidates whose
    centres lie within ``reach`` x the larger size become their mean. (n, 3) -> (m, 3)."""
    groups: list[list[np.ndarray]] = []
    for c in candidates[np.argsort(-candidates[:, 2])] if len(candidates) else []:
        for g in groups:
            if np.hypot(*(g[0][:2] - c[:2])) < reach * g[0][2]:
                g.append(c)
                break
        else:
            groups.append([c])
    return np.array([np.mean(g, axis=0) for g in groups], np.float64).reshape(-1, 3)


def pick_eyes(candidates: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray | None, str]:
    """The eye pair among ``candidates`` (see module docstring): ``(eyes (2, 2) image-left
    first, how)`` or ``(None, why)``."""
    h, w = shape
    c = candidates[candidates[:, 1] < 0.65 * h] if len(candidates) else candidates
    best, best_score = None, -np.inf
    for a, b in combinations(range(len(c)), 2):
        p, q = sorted((c[a], c[b]), key=lambda e: e[0])
        dx, dy = q[0] - p[0], abs(q[1] - p[1])
        ratio = max(p[2], q[2]) / min(p[2], q[2])
        if not (0.2 * w <= dx <= 0.8 * w) or dy > 0.25 * dx or ratio > 1.8:
            continue
        # level, alike, high in the frame, and centred about the middle of the photo
        score = -dy / dx - 0.5 * np.log(ratio) - 0.5 * (p[1] + q[1]) / (2 * h) \
            - abs((p[0] + q[0]) / 2 - w / 2) / w
        if score > best_score:
            best, best_score = np.array([p[:2], q[:2]]), score
    if best is not None:
        return best, "eyes found"
    if len(c):
        e = c[np.argmax(c[:, 2])]  # the largest single detection
        mirror = np.array([w - 1 - e[0], e[1]])
        pair = np.array(sorted([e[:2], mirror], key=lambda v: v[0]))
        if pair[1, 0] - pair[0, 0] >= 0.2 * w:
            return pair, "one eye found, the other mirrored"
    return None, "no eyes found"


def detect_eyes(image: np.ndarray) -> tuple[np.ndarray | None, str]:
    """Eye centres ``[[x1, y1], [x2, y2]]`` (pixels, image-left eye first) of the face in
    ``image`` (H, W) float in [0, 1], and how they were found; ``(None, why)`` on failure."""
    return pick_eyes(eye_candidates(image), image.shape[:2])
