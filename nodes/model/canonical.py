"""The canonical grid: where a face sits on the model grid. Every model, every training face and
every alignment of a photo puts the eye centres on these pixels."""
from __future__ import annotations

import numpy as np


def canonical_eyes(grid: tuple[int, int]) -> np.ndarray:
    """Canonical eye centres for a grid: ``[[x_left, y], [x_right, y]]`` in pixels (x = column).

    At 128x128: (46, 48) and (82, 48); the interocular distance is 0.28 of the width, which
    leaves the whole face from brow-top to chin inside the grid.
    """
    h, w = grid
    return np.array([[0.359375 * w, 0.375 * h], [0.640625 * w, 0.375 * h]])
