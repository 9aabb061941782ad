"""What came with a photo before any face is found: eyes and a light given by its sidecar or the user.

A sidecar (``<stem>.json``) is the photo's own and wins over what the run was given for every photo
(``--eyes``, ``--light``); a Yale B file name says its light. Pure functions of what was read.
"""
from __future__ import annotations

import numpy as np

from .input_error import InputError
from .lights import yaleb_light
from .sidecar import Sidecar


def given_eyes(source: str, shape: tuple[int, int], sidecar: Sidecar | None, eyes: np.ndarray | None,
               scale: float) -> tuple[np.ndarray, str] | None:
    """(2, 2) the eye centres given for the photo, in the pixels of the photo as read (``scale`` of them
    per pixel of the file: a photo read reduced), and where they came from ("sidecar eyes" | "given
    eyes"); None when none were given. ``InputError`` naming ``source`` when they cannot place a face
    in a photo of ``shape`` (H, W) (``check_eyes``)."""
    if sidecar is not None and sidecar.eyes is not None:
        found = np.asarray(sidecar.eyes, np.float64) * scale, "sidecar eyes"
    elif eyes is not None:
        found = np.asarray(eyes, np.float64) * scale, "given eyes"
    else:
        return None
    check_eyes(source, found[0], shape, found[1])
    return found


def check_eyes(source: str, eyes: np.ndarray, shape: tuple[int, int], what: str) -> None:
    """``InputError`` naming ``source`` when given eyes (2, 2) cannot place a face in a photo (H, W):
    not finite, one on the other, or outside the photo (by more than its size)."""
    e = np.asarray(eyes, np.float64)
    h, w = shape[:2]
    if e.shape != (2, 2) or not np.all(np.isfinite(e)):
        raise InputError(f"{source}: {what} must be four finite numbers [[x1, y1], [x2, y2]]")
    if np.linalg.norm(e[1] - e[0]) < 2.0:
        raise InputError(f"{source}: {what} are one on the other ({e.tolist()})")
    if np.any(e[:, 0] < -w) or np.any(e[:, 0] > 2 * w) or np.any(e[:, 1] < -h) or np.any(e[:, 1] > 2 * h):
        raise InputError(f"{source}: {what} {np.round(e, 1).tolist()} lie far outside the {w}x{h} photo")


def known_light(source: str, sidecar: Sidecar | None, light: str | np.ndarray) -> tuple[np.ndarray, str] | None:
    """(3,) the light when it is known before any face is, camera frame, and how ("sidecar" | "given" |
    "yaleb name"): a sidecar's, else ``light`` when it is a vector, else the Yale B name of ``source``
    when ``light`` is "yaleb"; None when it is to be estimated ("auto")."""
    if sidecar is not None and sidecar.light is not None:
        return sidecar.light, "sidecar"
    if isinstance(light, np.ndarray):
        return light, "given"
    if light == "yaleb":
        return yaleb_light(source), "yaleb name"
    return None
