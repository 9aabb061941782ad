"""A light as it is given: a vector toward it or its azimuth and elevation (text or numbers), or an
Extended Yale B file's name; checked and made a (3,) unit vector, camera frame (conventions.md)."""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..geometry.reflectance import light_from_angles
from .input_error import InputError

_YALEB = re.compile(r"_P\d+A([+-]\d{3})E([+-]\d{2})")


def yaleb_angles(path: str | os.PathLike) -> tuple[int, int]:
    """(azimuth, elevation) in degrees from an Extended Yale B name ``..._P00A+035E-20...``;
    lights behind the face are returned too (``yaleb_light`` refuses them)."""
    m = _YALEB.search(Path(path).name)
    if not m:
        raise InputError(f"{path}: name has no Yale B light (expected _PnnA+aaaE+ee)")
    a, e = int(m.group(1)), int(m.group(2))
    if abs(a) > 180 or abs(e) > 90:
        raise InputError(f"{path}: impossible Yale B angles A={a} E={e}")
    return a, e


def yaleb_light(path: str | os.PathLike) -> np.ndarray:
    """Light from an Extended Yale B name ``..._P00A+035E-20...`` (conventions.md)."""
    a, e = yaleb_angles(path)
    try:
        return checked_light(light_from_angles(a, e), f"Yale B light A={a} E={e}")
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None


def parse_light(text: str) -> np.ndarray:
    """``"x,y,z"`` (a vector) or ``"A,E"`` (azimuth, elevation in degrees, ``light_from_angles``) ->
    (3,) unit vector toward the light, camera frame."""
    try:
        v = np.array([float(t) for t in text.split(",")], np.float64)
    except ValueError:
        raise ValueError(f"light {text!r} is not two angles A,E (degrees) or three numbers x,y,z") from None
    return checked_light(v, f"light {text!r}")


MAX_AZIMUTH = 180.0
MAX_ELEVATION = 90.0


def checked_light(v: np.ndarray, what: str) -> np.ndarray:
    """Validate and normalise a light: three numbers are a vector toward it (camera frame), two are
    its azimuth and elevation in degrees (the Yale B convention, ``light_from_angles``: azimuth > 0
    toward the image's left, elevation > 0 up); raise ``ValueError`` naming ``what``."""
    try:
        v = np.asarray(v, np.float64).reshape(-1)
    except (OverflowError, TypeError, ValueError):  # a 400-digit integer, a string, a ragged list
        raise ValueError(f"{what}: must be two angles (azimuth, elevation in degrees) or three finite numbers") from None
    if v.shape == (2,) and np.all(np.isfinite(v)):
        if abs(v[0]) > MAX_AZIMUTH or abs(v[1]) > MAX_ELEVATION:
            raise ValueError(f"{what}: azimuth must be within +-{MAX_AZIMUTH:g} and elevation within "
                             f"+-{MAX_ELEVATION:g} degrees")
        v = light_from_angles(v[0], v[1])
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{what}: must be two angles (azimuth, elevation in degrees) or three finite numbers")
    with np.errstate(over="ignore"):
        n = np.linalg.norm(v)
    if not np.isfinite(n):  # the norm of 1e308s overflows: to the largest component first
        v = v / np.max(np.abs(v))
        n = np.linalg.norm(v)
    if n < 1e-9:
        raise ValueError(f"{what}: is the zero vector")
    v = v / n
    if v[2] <= 0:
        raise ValueError(f"{what}: points away from the camera (z <= 0): the face would be unlit")
    return v
