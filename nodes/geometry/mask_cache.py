"""Things computed once per face mask and kept: a stream asks for the same region every frame."""
from __future__ import annotations

import hashlib
from typing import Callable, TypeVar

import numpy as np

T = TypeVar("T")

MAX_ENTRIES = 16
_CACHE: dict[tuple, object] = {}


def per_mask(kind: str, mask: np.ndarray, build: Callable[[np.ndarray], T]) -> T:
    """``build(mask)`` for this ``kind`` and this mask's content (H, W) bool, computed on the
    first call and kept for the last ``MAX_ENTRIES`` (kind, mask) pairs. Callers must not
    modify what ``build`` returns (arrays in it should be made read-only)."""
    m = np.asarray(mask, bool)
    key = (kind, m.shape, hashlib.sha1(np.packbits(m).tobytes()).hexdigest())
    hit = _CACHE.get(key)
    if hit is None:
        if len(_CACHE) >= MAX_ENTRIES:
            _CACHE.pop(next(iter(_CACHE)))
        hit = _CACHE[key] = build(m)
    return hit  # type: ignore[return-value]
