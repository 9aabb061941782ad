"""The 2-D similarity (scale, rotation, translation) that takes two points onto two others: how
a face is placed by its two eyes, a photo's onto the model grid and a mesh's onto the canonical
pixels alike."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Similarity:
    """``p -> scale * rotation @ (p - origin) + target``: ``origin`` goes to ``target``.

    scale: float; rotation: (2, 2); origin, target: (2,) points.
    """

    scale: float
    rotation: np.ndarray
    origin: np.ndarray
    target: np.ndarray

    def apply(self, points: np.ndarray) -> np.ndarray:
        """(M, 2) points mapped."""
        return (np.asarray(points, np.float64) - self.origin) @ self.rotation.T * self.scale + self.target

    @property
    def matrix(self) -> np.ndarray:
        """(2, 3) affine matrix ``[A | t]`` of the same map, ``p -> A p + t``."""
        lin = self.scale * self.rotation
        return np.column_stack([lin, self.target - lin @ self.origin])


def two_point_similarity(src: np.ndarray, dst: np.ndarray) -> Similarity:
    """The similarity taking ``src[0]`` to ``dst[0]`` and ``src[1]`` to ``dst[1]`` (each (2, 2),
    one point a row). Raises ``ValueError`` when either pair coincides."""
    src = np.asarray(src, np.float64)
    dst = np.asarray(dst, np.float64)
    vs, vd = src[1] - src[0], dst[1] - dst[0]
    ns, nd = np.linalg.norm(vs), np.linalg.norm(vd)
    if ns < 1e-9 or nd < 1e-9:
        raise ValueError("the two points coincide")
    ang = np.arctan2(vd[1], vd[0]) - np.arctan2(vs[1], vs[0])
    rotation = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    return Similarity(float(nd / ns), rotation, src[0], dst[0])
