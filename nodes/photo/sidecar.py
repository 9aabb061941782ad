"""A photo's sidecar: the optional ``<stem>.json`` beside it, giving its light and eyes."""
from __future__ import annotations

import errno
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .input_error import InputError
from .lights import checked_light

MAX_SIDECAR_BYTES = 64 << 10  # a sidecar holds a light and two eyes: a few dozen bytes


@dataclass(frozen=True)
class Sidecar:
    """Optional ``<stem>.json`` next to an input: ``light`` (3,) and ``eyes`` (2, 2)."""

    light: np.ndarray | None = None
    eyes: np.ndarray | None = None


def sidecar_path(path: str | os.PathLike) -> Path:
    """Where the sidecar of the image ``path`` would be: ``<stem>.json`` beside it."""
    return Path(path).with_suffix(".json")


def read_sidecar(path: str | os.PathLike) -> Sidecar:
    """``<stem>.json`` beside ``path``, if any. Raises ``InputError`` when it is malformed."""
    p = Path(path)
    side = sidecar_path(p)
    try:
        if not side.is_file():
            return Sidecar()
    except OSError as exc:
        if exc.errno == errno.ENAMETOOLONG:  # a 255-byte image name: its sidecar's name cannot exist
            return Sidecar()
        raise InputError(f"{p}: cannot look for its sidecar {side.name} ({exc.strerror or exc})") from None
    raw = _sidecar_bytes(p, side)
    try:
        # utf-8-sig: a byte-order mark (some editors write one) is not part of the JSON
        data = json.loads(raw.decode("utf-8-sig"))
        if not isinstance(data, dict):
            raise ValueError("top level is not an object")
        light = checked_light(data["light"], "light") if "light" in data else None
        eyes = None
        if "eyes" in data:
            eyes = np.asarray(data["eyes"], np.float64)
            if eyes.shape != (2, 2) or not np.all(np.isfinite(eyes)):
                raise ValueError("eyes must be [[x1, y1], [x2, y2]]")
    except (ValueError, TypeError, OverflowError, UnicodeDecodeError, RecursionError) as exc:
        raise InputError(f"{p}: malformed sidecar {side.name} ({' '.join(str(exc).split())})") from None
    return Sidecar(light=light, eyes=eyes)


def _sidecar_bytes(p: Path, side: Path) -> bytes:
    """The sidecar's bytes, no more than ``MAX_SIDECAR_BYTES`` of them read whatever it claims or grows to."""
    try:
        size = side.stat().st_size
        if size > MAX_SIDECAR_BYTES:
            raise InputError(f"{p}: its sidecar {side.name} is {size} bytes, over the {MAX_SIDECAR_BYTES}-byte limit "
                             "(a sidecar holds a light and two eyes)")
        with side.open("rb") as fh:
            raw = fh.read(MAX_SIDECAR_BYTES + 1)
    except OSError as exc:
        raise InputError(f"{p}: its sidecar {side.name} cannot be read ({exc.strerror or exc})") from None
    if len(raw) > MAX_SIDECAR_BYTES:
        raise InputError(f"{p}: its sidecar {side.name} is over the {MAX_SIDECAR_BYTES}-byte limit")
    return raw
