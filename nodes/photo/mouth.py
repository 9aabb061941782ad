"""The face's length from its mouth line, for aligning a photo beyond its two eyes.

Two eye centres fix scale, rotation and position, not the face's proportions: a face whose mouth
sits closer to its eyes than the model's puts the model's nose, lips and chin in the wrong
place, and the robust fit's prior keeps it from moving them far. The lips' parting line is the
darkest horizontal feature of a face near its vertical midline under any light (the upper lip
shades it from above, the lower lip's edge is dark): its row on the model grid, against the
model's mouth row, gives the vertical stretch that the alignment then applies
(``photo.align.stretch_vertically``).

Measured on the Yale B subjects (README, "Real photographs"): with the stretch the normals are
1.5 / 1.2 / 0.7 / 0.2 deg closer to photometric stereo at (+-25, 0) / (+-50, 0) / (+-70, 0) /
(+-35, +15); an oracle choosing the best of five stretches per photo gains 1.1 deg at +-25..70.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage


def mouth_row(grid_image: np.ndarray, mouth: np.ndarray, eye_row: float, band: float = 0.22,
              search: float = 0.3, smooth: float = 5.0, reach: int = 3, prior: float | None = 0.15) -> float:
    """Row of the lips' parting line in an image on the model grid (model pixels).

    grid_image: (Hm, Wm) brightness on the model grid (eyes on the model's eyes); mouth: (2,)
    the model's mouth centre ``[x, y]``; eye_row: the model's eye row. Each row of a band of
    columns about ``mouth[0]`` (``band`` x the eye-to-mouth distance to each side) is averaged
    after dividing by its Gaussian-smoothed surroundings (``smooth`` px, so that shading and albedo
    that vary slowly drop out). The parting line is a valley of that profile: darker than both the
    rows ``reach`` px above and below it (the lips), which the edge of the nose's cast shadow (a
    step) is not. Within ``search`` x the eye-to-mouth distance of the model's mouth row, the
    valley deepest after weighting by a Gaussian prior on its distance from that row (``prior`` x
    the eye-to-mouth distance: 2.5 x the 6 % by which real faces' lengths vary, leaving room for
    the eyes' own error) wins, refined to sub-pixel by a parabola; ``prior`` None: the deepest.
    Without the prior, a valley near the search's end (a nostril's shadow, the chin's crease)
    could outweigh the parting line: Yale B subject 03's normals went 18.1 -> 13.5 deg at
    (-35, +15) and 18.8 -> 15.4 at (+85, +20) with it, and no other subject or light moved.
    """
    g = np.asarray(grid_image, np.float64)
    span = float(mouth[1] - eye_row)
    c0 = max(int(round(mouth[0] - band * span)), 0)
    c1 = min(int(round(mouth[0] + band * span)) + 1, g.shape[1])
    local = ndimage.gaussian_filter(g, smooth)
    profile = np.mean(g[:, c0:c1] / np.maximum(local[:, c0:c1], 1e-3), axis=1)
    depth = np.full(profile.shape, -np.inf)
    depth[reach:-reach] = np.minimum(profile[:-2 * reach], profile[2 * reach:]) - profile[reach:-reach]
    r0 = max(int(np.floor(mouth[1] - search * span)), reach + 1)
    r1 = min(int(np.ceil(mouth[1] + search * span)) + 1, g.shape[0] - reach - 1)
    score = depth[r0:r1]
    if prior is not None and np.any(score > 0):
        weight = np.exp(-0.5 * ((np.arange(r0, r1) - mouth[1]) / (prior * span)) ** 2)
        score = np.where(score > 0, score * weight, -np.inf)
    r = r0 + int(np.argmax(score))
    a, b, c = depth[r - 1], depth[r], depth[r + 1]
    denom = a - 2 * b + c
    offset = 0.5 * (a - c) / denom if np.isfinite(denom) and denom < -1e-12 else 0.0
    return float(r + np.clip(offset, -0.5, 0.5))


def face_length_factor(grid_image: np.ndarray, mouth: np.ndarray, eye_row: float,
                       limits: tuple[float, float] = (0.85, 1.15)) -> float:
    """The eye-to-mouth distance of the face in ``grid_image`` over the model's, clipped to
    ``limits`` (about 2.5 standard deviations of real faces: ICT-FaceKit identities vary by 6 %)."""
    row = mouth_row(grid_image, mouth, eye_row)
    return float(np.clip((row - eye_row) / (mouth[1] - eye_row), *limits))
