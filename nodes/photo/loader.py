"""Loader: images to float brightness in [0, 1], and where the light and eyes come from."""
from __future__ import annotations

import errno
import io
import json
import os
import re
import stat
import warnings
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from ..geometry.reflectance import light_from_angles

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".pgm", ".ppm", ".pnm", ".tif", ".tiff", ".bmp", ".npy"}
_YALEB = re.compile(r"_P\d+A([+-]\d{3})E([+-]\d{2})")


class InputError(ValueError):
    """A problem with one input; the message names the file and the problem on one line."""


@dataclass(frozen=True)
class Sidecar:
    """Optional ``<stem>.json`` next to an input: ``light`` (3,) and ``eyes`` (2, 2)."""

    light: np.ndarray | None = None
    eyes: np.ndarray | None = None


MIN_SIDE = 32  # pixels: the smallest image side that can hold a face to align
MAX_PIXELS = 40_000_000  # larger images are refused before decoding (about 0.5 GB to decode)
MAX_FILE_BYTES = 512 << 20


def _read_file(p: Path) -> bytes:
    """The bytes of a regular file, or ``InputError`` saying why not (one line)."""
    try:
        st = p.stat()
    except FileNotFoundError:
        raise InputError(f"{p}: no such file" + (" (a dangling symlink)" if p.is_symlink() else "")) from None
    except OSError as exc:
        why = "a symlink loop" if exc.errno == errno.ELOOP else (exc.strerror or str(exc))
        raise InputError(f"{p}: cannot be read ({why})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{p}: is a directory, not an image")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{p}: not a regular file (a pipe, socket or device)")
    if st.st_size == 0:
        raise InputError(f"{p}: is empty (0 bytes)")
    if st.st_size > MAX_FILE_BYTES:
        raise InputError(f"{p}: file of {st.st_size >> 20} MiB exceeds the {MAX_FILE_BYTES >> 20} MiB input limit")
    try:
        return p.read_bytes()
    except OSError as exc:
        raise InputError(f"{p}: cannot be read ({exc.strerror or exc})") from None


def _read_binary_pnm(data: bytes) -> tuple[np.ndarray, int] | None:
    """A binary PGM (P5) or PPM (P6) as ``(samples (H, W) or (H, W, 3) BGR as OpenCV gives them,
    uint8 or uint16, maxval)``, read by the format's own rules (samples over 255 are two bytes,
    big-endian, on the scale 0..maxval); None when the header or the data is malformed."""
    m = re.match(rb"(P[56])(?:\s+(?:#[^\n]*\n\s*)*)(\d+)(?:\s+(?:#[^\n]*\n\s*)*)(\d+)(?:\s+(?:#[^\n]*\n\s*)*)(\d+)\s",
                  data[:1024])
    if m is None:
        return None
    width, height, maxval = int(m.group(2)), int(m.group(3)), int(m.group(4))
    if not 0 < maxval < 65536:
        return None
    channels = 3 if m.group(1) == b"P6" else 1
    dtype = np.dtype(">u2") if maxval > 255 else np.dtype(np.uint8)
    count = width * height * channels
    body = data[m.end():m.end() + count * dtype.itemsize]
    if len(body) < count * dtype.itemsize:
        return None
    samples = np.frombuffer(body, dtype).reshape((height, width, channels) if channels == 3 else (height, width))
    samples = samples.astype(np.uint16 if maxval > 255 else np.uint8)
    return (samples[..., ::-1].copy() if channels == 3 else samples), maxval


def _check_size(p: Path, width: int, height: int) -> None:
    if width * height > MAX_PIXELS:
        raise InputError(f"{p}: {width}x{height} pixels exceeds the {MAX_PIXELS // 1_000_000}-megapixel limit; "
                         "downscale it first")
    if min(width, height) < MIN_SIDE:
        raise InputError(f"{p}: {width}x{height} pixels is too small for a face (each side needs >= {MIN_SIDE})")


def _load_npy(p: Path, data: bytes) -> np.ndarray:
    fh = io.BytesIO(data)
    try:
        version = np.lib.format.read_magic(fh)
        read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read_header(fh)
    except (ValueError, EOFError) as exc:
        raise InputError(f"{p}: not a readable .npy array ({exc})") from None
    if len(shape) != 2 or dtype.hasobject or not np.issubdtype(dtype, np.number):
        raise InputError(f"{p}: .npy input must be a 2-D numeric array, got {dtype} {shape}")
    _check_size(p, shape[1], shape[0])
    try:
        fh.seek(0)
        arr = np.load(fh, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"{p}: not a readable .npy array ({exc})") from None
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{p}: .npy input holds NaN or infinite values")
    return np.clip(arr, 0.0, 1.0).astype(np.float32)


LUMA = np.array([0.299, 0.587, 0.114], np.float32)  # ITU-R BT.601 weights of R, G, B (OpenCV's BGR2GRAY)


def luminance(image: np.ndarray) -> np.ndarray:
    """(H, W) brightness of an RGB image (H, W, 3); a grey (H, W) image is returned as it is."""
    a = np.asarray(image)
    return a @ LUMA if a.ndim == 3 else a


def load_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image as (H, W) float32 brightness in [0, 1] (``load_photo`` without its colour)."""
    return load_photo(path)[0]


def load_photo(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """Read an image as ``(grey (H, W) float32 brightness in [0, 1], colour (H, W, 3) float32 RGB in
    [0, 1] or None for a grey image)``.

    PNG / JPEG / PGM / TIFF / BMP, 8 or 16 bit or float, grey, colour or palette (to luminance,
    ITU-R BT.601 weights as OpenCV's ``BGR2GRAY``), an alpha channel ignored, EXIF orientation
    applied; or a ``.npy`` (H, W) array of finite floats in [0, 1] (read without pickles).
    The header is checked before decoding: each side >= ``MIN_SIDE`` and at most ``MAX_PIXELS``
    pixels, so a hostile file cannot exhaust memory. Images without contrast are refused.
    Raises ``InputError`` (one line naming the file and the problem).
    """
    p = Path(path)
    data = _read_file(p)
    colour = None
    if p.suffix.lower() == ".npy":
        img = _load_npy(p, data)
    else:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # bomb warnings (our limit is lower), odd EXIF: not ours to say
                with Image.open(io.BytesIO(data)) as probe:  # reads the header only
                    width, height = probe.size
                    kind = probe.format or "image"
        except Image.DecompressionBombError:
            raise InputError(f"{p}: far more than the {MAX_PIXELS // 1_000_000}-megapixel limit; "
                             "downscale it first") from None
        except (OSError, ValueError, SyntaxError):
            raise InputError(f"{p}: not a recognised image (PNG, JPEG, PNM, TIFF or BMP)") from None
        _check_size(p, width, height)
        pnm = _read_binary_pnm(data) if data[:2] in (b"P5", b"P6") else None
        if pnm is not None:  # by its own maxval: OpenCV reads 10- and 12-bit PNM with the bytes swapped
            raw, maxval = pnm
            if maxval not in (255, 65535):
                raw = (raw.astype(np.float32) / maxval).astype(np.float32)
        else:
            raw = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR)
        if raw is None:
            raise InputError(f"{p}: corrupt or truncated {kind} data")
        colour_raw = None
        if raw.ndim == 3:
            if raw.shape[2] == 4:
                raw = raw[..., :3]
            if not (np.array_equal(raw[..., 0], raw[..., 1]) and np.array_equal(raw[..., 1], raw[..., 2])):
                colour_raw = raw[..., ::-1]  # BGR -> RGB; a grey image stored as RGB stays grey
            raw = cv2.cvtColor(raw, cv2.COLOR_BGR2GRAY)
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
        img = np.clip(img, 0.0, 1.0)
        if colour_raw is not None:
            scale = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}.get(colour_raw.dtype, 1.0)
            colour = np.clip(np.nan_to_num(colour_raw.astype(np.float32) / scale), 0.0, 1.0)
    lo, hi = float(img.min()), float(img.max())
    if hi - lo < 1.0 / 255.0:
        raise InputError(f"{p}: has no contrast (every pixel is {lo:.3f}): nothing to fit")
    return img, colour


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
    try:
        if not side.is_file():
            return Sidecar()
    except OSError as exc:
        if exc.errno == errno.ENAMETOOLONG:  # a 255-byte image name: its sidecar's name cannot exist
            return Sidecar()
        raise InputError(f"{p}: cannot look for its sidecar {side.name} ({exc.strerror or exc})") from None
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
        raise InputError(f"{p}: malformed sidecar {side.name} ({exc})") from None
    return Sidecar(light=light, eyes=eyes)
