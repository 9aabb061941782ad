"""Loader: images to float brightness in [0, 1], and where the light and eyes come from."""
from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from nodes.reflectance import light_from_angles

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".pgm", ".ppm", ".pnm", ".tif", ".tiff", ".bmp", ".npy"}
_YALEB = re.compile(r"_P\d+A([+-]\d{3})E([+-]\d{2})")


class InputError(ValueError):
    """A problem with one input; the message names the file and the problem on one line."""


@dataclass(frozen=True)
class Sidecar:
    """Optional ``<stem>.json`` next to an input: ``light`` (3,) and ``eyes`` (2, 2)."""

    light: np.ndarray | None = None
    eyes: np.ndarray | None = None


def load_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image as (H, W) float32 brightness in [0, 1].

    PNG / JPEG / PGM / TIFF / BMP, 8 or 16 bit or float, grey or colour (to luminance, ITU-R
    BT.601 weights as OpenCV's ``BGR2GRAY``), an alpha channel ignored; or a ``.npy``
    (H, W) array of finite floats in [0, 1] (read without pickles). Raises ``InputError``.
    """
    p = Path(path)
    if p.suffix.lower() == ".npy":
        try:
            arr = np.load(p, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise InputError(f"{p}: not a readable .npy array ({exc})") from None
        if arr.ndim != 2 or not np.issubdtype(arr.dtype, np.number):
            raise InputError(f"{p}: .npy input must be a 2-D numeric array, got {arr.dtype} {arr.shape}")
        arr = arr.astype(np.float32)
        if not np.all(np.isfinite(arr)):
            raise InputError(f"{p}: .npy input holds NaN or infinite values")
        return np.clip(arr, 0.0, 1.0)
    raw = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if raw is None:
        raise InputError(f"{p}: cannot be read as an image")
    if raw.ndim == 3:
        if raw.shape[2] == 4:
            raw = raw[..., :3]
        raw = cv2.cvtColor(raw, cv2.COLOR_BGR2GRAY) if raw.shape[2] == 3 else raw[..., 0]
    if raw.dtype == np.uint8:
        img = raw.astype(np.float32) / 255.0
    elif raw.dtype == np.uint16:
        img = raw.astype(np.float32) / 65535.0
    elif np.issubdtype(raw.dtype, np.floating):
        img = raw.astype(np.float32)
        if not np.all(np.isfinite(img)):
            raise InputError(f"{p}: image holds NaN or infinite values")
    else:
        raise InputError(f"{p}: unsupported pixel type {raw.dtype}")
    return np.clip(img, 0.0, 1.0)


def yaleb_light(path: str | os.PathLike) -> np.ndarray:
    """Light from an Extended Yale B name ``..._P00A+035E-20...`` (conventions.md)."""
    m = _YALEB.search(Path(path).name)
    if not m:
        raise InputError(f"{path}: name has no Yale B light (expected _PnnA+aaaE+ee)")
    a, e = int(m.group(1)), int(m.group(2))
    if abs(a) > 180 or abs(e) > 90:
        raise InputError(f"{path}: impossible Yale B angles A={a} E={e}")
    return light_from_angles(a, e)


def parse_light(text: str) -> np.ndarray:
    """``"x,y,z"`` -> (3,) unit vector toward the light, camera frame."""
    try:
        v = np.array([float(t) for t in text.split(",")], np.float64)
    except ValueError:
        raise ValueError(f"light {text!r} is not three numbers x,y,z") from None
    return checked_light(v, f"light {text!r}")


def checked_light(v: np.ndarray, what: str) -> np.ndarray:
    """Validate and normalise a light vector; raise ``ValueError`` naming ``what``."""
    v = np.asarray(v, np.float64).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{what}: must be three finite numbers")
    n = np.linalg.norm(v)
    if n < 1e-9:
        raise ValueError(f"{what}: is the zero vector")
    v = v / n
    if v[2] <= 0:
        raise ValueError(f"{what}: points away from the camera (z <= 0): the face would be unlit")
    return v


def read_sidecar(path: str | os.PathLike) -> Sidecar:
    """``<stem>.json`` beside ``path``, if any. Raises ``InputError`` when it is malformed."""
    p = Path(path)
    side = p.with_suffix(".json")
    if not side.is_file():
        return Sidecar()
    try:
        data = json.loads(side.read_text(encoding="utf-8"))
        if not isinstance(data, dict):
            raise ValueError("top level is not an object")
        light = checked_light(data["light"], "light") if "light" in data else None
        eyes = None
        if "eyes" in data:
            eyes = np.asarray(data["eyes"], np.float64)
            if eyes.shape != (2, 2) or not np.all(np.isfinite(eyes)):
                raise ValueError("eyes must be [[x1, y1], [x2, y2]]")
    except (ValueError, TypeError, UnicodeDecodeError) as exc:
        raise InputError(f"{side}: malformed sidecar ({exc})") from None
    return Sidecar(light=light, eyes=eyes)
