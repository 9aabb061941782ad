"""Eye centres in a face photo, for aligning it to the model grid.

Method (OpenCV's Haar eye cascade, shipped with opencv-python-headless 4.x):
1. the cascade runs on the photo and on a contrast-equalised copy (CLAHE on the log image), so
   an eye on the shadowed side of a side-lit face is still found;
2. detections of one eye (nested boxes, both images) are merged; candidates in the upper
   65 % of the photo are paired: roughly level (|dy| <= 0.25 dx),
   similar in size, 0.2 to 0.8 of the photo's width apart; the best-scoring pair wins;
3. with only one eye found (the other lost in deep shadow), the other is its mirror image
   about the photo's vertical centre line (a frontal face, roughly centred);
4. with none, ``detect_eyes`` returns None and the caller falls back to a centred frontal crop;
5. each eye is then moved from its box's centre to its iris centre (``iris_centre``), which is
   what the model's eye points are (ICT-FaceKit's iris centres): a cascade's box sits a few
   pixels off the iris, and differently under each light.
"""
from __future__ import annotations

from functools import lru_cache
from itertools import combinations

import cv2
import numpy as np

from .align import Alignment, to_model_grid


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
    candidates = eye_candidates(image)
    eyes, how = pick_eyes(candidates, image.shape[:2])
    if eyes is None:
        return None, how
    # a mirrored eye is a guess: what lies near it need not be an eye (a lit face's edge, hair)
    seen = [bool(np.any(np.all(np.isclose(candidates[:, :2], e), axis=1))) for e in eyes]
    return refine_eyes(image, eyes, seen), how


# iris-centre search, in units of the interocular distance (IOD) of the cascade's pair
IRIS_PATCH = 0.16  # half-width of the patch around each box centre
IRIS_REACH = 0.11  # the iris centre is looked for this close to the box centre
IRIS_SCALE = 100.0  # the patch is resampled so that the IOD is this many pixels (fixed cost, any photo size)
IRIS_DARK_SIGMA = 0.02  # the darkness prior's blur
IRIS_HIGHLIGHT = 0.02  # specks of shine up to this radius are taken out first
SHADOWED_EYE = 0.15  # an eye patch whose median is under this x the face's bright level is in shadow: no iris to see


def iris_centre(patch: np.ndarray, reach: float, dark_sigma: float, highlight: float = 0.0) -> tuple[float, float] | None:
    """(x, y) pixels in ``patch`` (h, w) [0, 1] of the dark disc's centre, by means of gradients
    (Timm & Barth, "Accurate eye centre localisation by means of gradients", VISAPP 2011): the
    point that the most image gradients point away from (a dark iris on a brighter eye white and
    lids), weighted by how dark the point is; searched within ``reach`` pixels of the patch's
    centre. None where the patch has too few strong gradients (an eye deep in shadow)."""
    g = np.asarray(patch, np.float32)
    if highlight > 0:  # a grey opening takes the cornea's specks of shine out, whose edges point inward
        size = 2 * int(round(highlight)) + 1
        g = cv2.morphologyEx(g, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size)))
    gy, gx = np.gradient(g)
    mag = np.hypot(gx, gy)
    strong = mag > mag.mean() + 0.3 * mag.std()
    if strong.sum() < 8 or float(mag.max()) < 1e-4:
        return None
    ys, xs = (v.astype(np.float32) for v in np.nonzero(strong))
    ux, uy = gx[strong] / mag[strong], gy[strong] / mag[strong]
    h, w = g.shape
    iy, ix = np.nonzero(np.hypot(*np.mgrid[:h, :w] - np.array([(h - 1) / 2, (w - 1) / 2])[:, None, None]) <= reach)
    cy, cx = iy.astype(np.float32), ix.astype(np.float32)
    # (centres, gradient pixels): the displacement d from each centre to each pixel, d . u over |d|
    along = (xs * ux + ys * uy)[None, :] - np.outer(cx, ux) - np.outer(cy, uy)
    dist2 = (xs * xs + ys * ys)[None, :] - 2.0 * (np.outer(cx, xs) + np.outer(cy, ys)) + (cx * cx + cy * cy)[:, None]
    agree = np.maximum(along, 0.0) ** 2 / np.maximum(dist2, 1e-6)  # gradients point outward from a dark centre
    score = np.mean(agree, axis=1)
    dark = 1.0 - cv2.GaussianBlur(g, (0, 0), dark_sigma) / max(float(g.max()), 1e-6)
    best = int(np.argmax(score * dark[iy, ix]))
    return float(ix[best]), float(iy[best])


def refine_eyes(image: np.ndarray, eyes: np.ndarray, which: tuple[bool, bool] | list[bool] = (True, True)) -> np.ndarray:
    """(2, 2) ``eyes`` (box centres, pixels) moved to their iris centres (``iris_centre``) in
    ``image`` (H, W) [0, 1]. An eye in shadow (its patch's median under ``SHADOWED_EYE`` of the
    face's bright level, the 95th percentile between brows and mouth) shows no iris, only the
    shadow's edges, and stays where the cascade put it; so does one whose patch leaves the photo
    or shows no iris, and one that ``which`` (2,) bool leaves out."""
    img = np.asarray(image, np.float32)
    eyes = np.asarray(eyes, np.float64)
    iod = float(np.hypot(*(eyes[1] - eyes[0])))
    if iod < 8:
        return eyes
    h, w = img.shape
    (x0, x1), (y0, y1) = np.sort(eyes[:, 0]), np.sort(eyes[:, 1])
    face = img[max(int(y0 - 0.3 * iod), 0):min(int(y1 + 1.0 * iod) + 1, h),
               max(int(x0 - 0.5 * iod), 0):min(int(x1 + 0.5 * iod) + 1, w)]
    bright = float(np.percentile(face, 95)) if face.size else 0.0
    zoom = IRIS_SCALE / iod  # patch pixels per photo pixel
    half = int(round(IRIS_PATCH * IRIS_SCALE))
    r = IRIS_PATCH * iod
    out = eyes.copy()
    for k, (x, y) in enumerate(eyes):
        if not which[k] or x - r < 0 or y - r < 0 or x + r > w - 1 or y + r > h - 1:
            continue
        # the eye's surroundings resampled as the photo is onto the model grid (area-averaged when a
        # large photo shrinks): patch pixel (u, v) shows photo (x + (u - half) / zoom, y + (v - half) / zoom)
        xa, ya = max(int(x - r) - 2, 0), max(int(y - r) - 2, 0)
        crop = img[ya:int(y + r) + 3, xa:int(x + r) + 3]
        to_crop = Alignment(np.array([[1 / zoom, 0.0, x - xa - half / zoom], [0.0, 1 / zoom, y - ya - half / zoom]]),
                            "iris patch")
        patch = to_model_grid(crop, to_crop, (2 * half + 1, 2 * half + 1))
        if float(np.median(patch)) < SHADOWED_EYE * bright:
            continue
        found = iris_centre(patch, IRIS_REACH * IRIS_SCALE, IRIS_DARK_SIGMA * IRIS_SCALE, IRIS_HIGHLIGHT * IRIS_SCALE)
        if found is not None:
            out[k] = (x + (found[0] - half) / zoom, y + (found[1] - half) / zoom)
    return out
