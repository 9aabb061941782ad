"""What a recording holds: typed ``Event``s (one ``Kind`` each), ``OnMask`` values, and the
``Sink`` interface every file format implements. Knows nothing about faces."""
from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any, Sequence

import numpy as np


class Kind(StrEnum):
    """How an event's value is stored and shown."""

    ARRAY = "array"  # any array; a 1-D one is plotted per entry, a 2-D one shown as an image
    IMAGE = "image"  # (H, W) grey or (H, W, 3) RGB in [0, 1]
    DEPTH = "depth"  # (H, W) heights
    NORMALS = "normals"  # (H, W, 3) unit vectors
    MESH = "mesh"  # dict: vertices (V, 3), triangles (T, 3), colours (V, 3) uint8
    SCALARS = "scalars"  # dict name -> float
    FRAME = "frame"  # dict: source, status, meta; closes the frame


ARRAY_KINDS = frozenset({Kind.ARRAY, Kind.IMAGE, Kind.DEPTH, Kind.NORMALS})


@dataclass(frozen=True)
class Event:
    """One recorded item.

    frame: stream position; path: ``node/name``; kind: a ``Kind`` (its string is accepted);
    value: as the kind says, an array value may be an ``OnMask`` (the sinks put it on its grid
    on the recorder's thread); iteration: None for per-frame products.
    """

    frame: int
    path: str
    kind: Kind
    value: Any
    iteration: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "kind", Kind(self.kind))  # ValueError for an unknown kind


@dataclass(frozen=True)
class OnMask:
    """An array known only at the True pixels of a grid mask, e.g. values over a face.

    values: (N, ...) in the mask's row-major order; mask: (H, W) bool with N True pixels.
    Emitting one costs the producer an (N, ...) array instead of an (H, W, ...) grid; the
    recorder's thread scatters it (``grid``) with whatever fill each sink wants.
    """

    values: np.ndarray
    mask: np.ndarray

    def grid(self, fill: float = np.nan) -> np.ndarray:
        """(H, W, ...) of the values' dtype, ``fill`` off the mask."""
        rest = self.values.shape[1:]
        out = np.full((self.mask.size, *rest), fill, dtype=self.values.dtype)
        out[np.flatnonzero(self.mask)] = self.values  # integer rows: 3x faster than a boolean mask for (N, 3)
        return out.reshape(self.mask.shape + rest)


def value_nbytes(value: Any) -> int:
    """Bytes an event's value holds in arrays: an array's, or an ``OnMask``'s values' (the mask is
    shared between events); anything else (a dict of scalars, a record): 0."""
    if isinstance(value, OnMask):
        return int(value.values.nbytes)
    return int(value.nbytes) if isinstance(value, np.ndarray) else 0


class Sink:
    """Writes events somewhere. ``write`` runs on the recorder's thread only. ``paths``: the files
    it has written so far (none for a sink that keeps its events in memory)."""

    paths: Sequence[Path] = ()

    def name_frame(self, frame: int, name: str) -> None:
        """What frame ``frame`` is called (e.g. its input's stem), before its events come."""

    def write(self, event: Event) -> None: ...

    def frame_done(self, frame: int) -> None: ...

    def close(self) -> None: ...
