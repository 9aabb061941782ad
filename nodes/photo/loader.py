"""Loader: images to float brightness in [0, 1]. Each format's own reader is beside it (``pnm``, ``tiff``); the
light and eyes given with a photo are read by ``lights`` and ``sidecar``."""
from __future__ import annotations

import errno
import io
import os
import stat
import warnings
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from .native_messages import decoder_messages_dropped
from .encoding import Decoded8, decode_samples, decoded_luminance, linear_luminance, resolve, swapped_rb
from .input_error import InputError
from .pnm import read_ascii_pnm, read_binary_pnm
from .tiff import TIFF_MAGIC, TiffBomb, read_tiff, tiff_header

# what a folder is read for; a file named on the command line is read whatever its name
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".jfif", ".pgm", ".ppm", ".pnm", ".tif", ".tiff", ".bmp", ".webp", ".gif",
                  ".npy"}

MIN_SIDE = 32  # pixels: the smallest image side that can hold a face to align
MAX_PIXELS = 40_000_000  # larger images are refused before decoding
MAX_SIDE = 32_000  # OpenCV's warps stop at 32767 pixels a side
MAX_ASPECT = 16  # a face photo is not a strip
MAX_WORK_PIXELS = 4_000_000  # photos are processed at most this size (``read_photo``'s max_pixels)
MAX_FILE_BYTES = 512 << 20
MAX_PLAIN_PNM_PIXELS = 4_000_000  # a plain (ASCII) PNM is parsed token by token: a test file, not a camera's
# a plain PNM is read no further than this: 4 megapixels of 16-bit colour written as numbers take 72 MB, and what
# follows its samples is not part of the image
MAX_PLAIN_PNM_BYTES = 96 << 20


def _read_file(p: Path) -> bytes:
    """The bytes of a regular file (of a plain PNM, its first ``MAX_PLAIN_PNM_BYTES``), or ``InputError``
    saying why not (one line)."""
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
        with p.open("rb") as fh:
            plain = fh.read(2) in (b"P2", b"P3")
            fh.seek(0)
            return fh.read(MAX_PLAIN_PNM_BYTES if plain else -1)
    except OSError as exc:
        raise InputError(f"{p}: cannot be read ({exc.strerror or exc})") from None


# a progressive JPEG is decoded scan by scan, each a pass over the whole image: encoders write 6 (grey) to 10 (colour)
# scans, a hostile file thousands of tiny ones (minutes of CPU, docs/faults.md). libjpeg-turbo's tools offer such a limit
# (djpeg -maxscans) that OpenCV does not expose, so the scans are counted before decoding
MAX_JPEG_SCANS = 100


def jpeg_scans(data: bytes) -> int:
    """How many scans (SOS markers) a JPEG's bytes hold: the segments before the first are walked by their
    lengths (an EXIF thumbnail's scan is not counted), then its markers counted (in entropy-coded data a
    0xFF byte is always followed by 0x00 or a restart marker, so ``FF DA`` is a scan)."""
    i, n = 2, len(data)
    while i + 4 <= n and data[i] == 0xFF:
        marker = data[i + 1]
        if marker == 0xDA:
            break
        if marker == 0xFF:  # fill byte
            i += 1
        elif 0xD0 <= marker <= 0xD8 or marker == 0x01:  # markers without a length
            i += 2
        else:
            i += 2 + int.from_bytes(data[i + 2:i + 4], "big")
    return data.count(b"\xff\xda", i)


def check_size(p: Path, width: int, height: int) -> None:
    if width * height > MAX_PIXELS:
        raise InputError(f"{p}: {width}x{height} pixels exceeds the {MAX_PIXELS // 1_000_000}-megapixel limit; "
                         "downscale it first")
    if min(width, height) < MIN_SIDE:
        raise InputError(f"{p}: {width}x{height} pixels is too small for a face (each side needs >= {MIN_SIDE})")
    if max(width, height) > MAX_SIDE:
        raise InputError(f"{p}: {width}x{height} pixels: a side over {MAX_SIDE} pixels; downscale it first")
    if max(width, height) > MAX_ASPECT * min(width, height):
        raise InputError(f"{p}: {width}x{height} pixels is too long and thin for a photo of a face "
                         f"(sides over {MAX_ASPECT}:1)")


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
    check_size(p, shape[1], shape[0])
    try:
        fh.seek(0)
        arr = np.load(fh, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"{p}: not a readable .npy array ({exc})") from None
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{p}: .npy input holds NaN or infinite values")
    if arr.dtype.kind == "c" or (arr.size and float(arr.min()) < 0.0):
        raise InputError(f"{p}: .npy input holds negative or complex values (give brightness, 0 = black)")
    # on its real scale, as an image file's samples are: floats as [0, 1], 8-bit as 0-255, and so on
    return np.clip(arr.astype(np.float64) / sample_range(arr), 0.0, 1.0).astype(np.float32)


LUMA = np.array([0.299, 0.587, 0.114], np.float32)  # ITU-R BT.601 weights of R, G, B (OpenCV's BGR2GRAY)


def load_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image as (H, W) float32 brightness in [0, 1] (``load_photo`` without its colour)."""
    return load_photo(path)[0]


def load_photo(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """``read_photo`` at full size: ``(grey, colour)``."""
    photo = read_photo(path)
    return photo.grey, photo.colour


@dataclass
class Photo:
    """grey: (H, W) float32 brightness in [0, 1]; colour: (H, W, 3) float32 RGB in [0, 1] (for 8-bit sRGB a
    ``Decoded8`` of ``rgb8``, decoded where it is indexed), or None for a grey image; scale: its pixels per
    pixel of the file (1, or less when it was reduced to ``max_pixels``); size: the file's (width, height), upright (its EXIF orientation applied); encoding: "linear" (the values are the file's)
    or "srgb" (the file's values decoded to linear light, ``photo.encoding``); rgb8: (H, W, 3) uint8
    RGB, the file's own (encoded) values at 8 bits, when it was decoded from sRGB."""

    grey: np.ndarray
    colour: np.ndarray | None
    scale: float
    size: tuple[int, int]
    encoding: str = "linear"
    rgb8: np.ndarray | None = None


def read_photo(path: str | os.PathLike, max_pixels: int | None = None, encoding: str = "linear") -> Photo:
    """Read an image (``Photo``), reduced to at most ``max_pixels`` pixels (area-averaged; a JPEG is
    decoded at 1/2, 1/4 or 1/8 scale first, so a large one never exists at full size in memory).

    PNG / JPEG / PNM / TIFF / BMP, 8 or 16 bit, float or other integer types, grey, colour or
    palette (to luminance, ITU-R BT.601 weights as OpenCV's ``BGR2GRAY``), an alpha channel
    ignored, EXIF orientation applied; or a ``.npy`` (H, W) array of finite floats in [0, 1]
    (read without pickles). Samples are scaled by their real range: a PNM by its maxval, 8- and
    16-bit by 255 and 65535, floats as [0, 1] unless they exceed 1, and those and other integer
    types by the smallest of 2^8-1, 2^10-1, 2^12-1, 2^14-1 or 2^16-1 that holds them, else by their
    largest sample. The header is checked before decoding: each side >= ``MIN_SIDE`` and <=
    ``MAX_SIDE``, at most ``MAX_PIXELS`` pixels, a face's proportions, so a hostile file cannot
    exhaust memory. Images without contrast are refused. Raises ``InputError`` (one line naming the file and the problem).
    """
    p = Path(path)
    data = _read_file(p)
    if p.suffix.lower() == ".npy":
        img = _load_npy(p, data)
        small = shrunk(img, max_pixels)
        return Photo(small, None, small.shape[1] / img.shape[1], (img.shape[1], img.shape[0]))
    header = _header(p, data)
    raw = _decoded(p, data, header, max_pixels)
    del data
    grey, colour = _samples(p, raw)
    return _photo(p, grey, colour, header, max_pixels, encoding)


def photo_from_samples(source: str, samples: np.ndarray, max_pixels: int | None = None,
                       encoding: str = "linear") -> Photo:
    """The ``Photo`` of samples already decoded (an array given to the API, named ``source`` in errors):
    (H, W) grey or (H, W, 3) RGB (an alpha channel ignored), of any numeric type or bool, checked, scaled,
    reduced and encoded exactly as the same samples read from a file are (``read_photo``)."""
    p = Path(source)
    a = np.asarray(samples)
    if a.dtype == bool:
        a = a.astype(np.uint8) * 255
    if a.ndim == 3 and a.shape[2] in (3, 4):
        a = np.ascontiguousarray(a[..., 2::-1])  # RGB(A) -> BGR, as decoders give it
    elif a.ndim != 2:
        raise InputError(f"{source}: shape {a.shape} is not (H, W) or (H, W, 3)")
    check_size(p, a.shape[1], a.shape[0])
    if a.dtype.kind not in "uif":
        raise InputError(f"{source}: unsupported pixel type {a.dtype}")
    grey, colour = _samples(p, a)
    return _photo(p, grey, colour, _Header(a.shape[1], a.shape[0], "array"), max_pixels, encoding)


@dataclass(frozen=True)
class _Header:
    """What an image file's header says: its size (as stored), its format, and for a TIFF its sample type
    and whether its channels are planes."""

    width: int
    height: int
    kind: str
    tiff_dtype: np.dtype | None = None
    tiff_planar: bool = False


def _header(p: Path, data: bytes) -> _Header:
    """The file's header, checked (size, proportions, a JPEG's scans) before anything is decoded."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # bomb warnings (our limit is lower), odd EXIF: not ours to say
            if data[:4] in TIFF_MAGIC:
                width, height, dtype, planar = tiff_header(data)
                header = _Header(width, height, "TIFF", dtype, planar)
            else:
                with Image.open(io.BytesIO(data)) as probe:  # reads the header only
                    # a JPEG by its bytes, whatever Pillow calls it: one with an MPF segment is an "MPO"
                    kind = "JPEG" if data[:3] == b"\xff\xd8\xff" else probe.format or "image"
                    header = _Header(*probe.size, kind)
    except Image.DecompressionBombError:
        raise InputError(f"{p}: far more than the {MAX_PIXELS // 1_000_000}-megapixel limit; "
                         "downscale it first") from None
    except TiffBomb as exc:
        raise InputError(f"{p}: {exc}") from None
    except (OSError, ValueError, SyntaxError, IndexError, KeyError):
        raise InputError(f"{p}: not a recognised image (PNG, JPEG, PNM, TIFF, BMP, WebP or GIF)") from None
    check_size(p, header.width, header.height)
    if header.kind == "JPEG" and (scans := jpeg_scans(data)) > MAX_JPEG_SCANS:
        raise InputError(f"{p}: a progressive JPEG of {scans} scans, over the {MAX_JPEG_SCANS}-scan limit "
                         "(encoders write at most about 10; each costs a pass over the whole photo)")
    return header


def _decoded(p: Path, data: bytes, header: _Header, max_pixels: int | None) -> np.ndarray:
    """The file's samples as decoded: (H, W) or (H, W, C) BGR(A), any type; a PNM by its own maxval (a
    float in [0, 1] when it is neither 255 nor 65535), a large JPEG already reduced by libjpeg."""
    pnm = _pnm(p, data, header) if data[:2] in (b"P2", b"P3", b"P5", b"P6") else None
    if pnm is not None:  # by its own maxval: OpenCV reads 10- and 12-bit PNM with the bytes swapped
        raw, maxval = pnm
        return raw if maxval in (255, 65535) else (raw.astype(np.float32) / maxval).astype(np.float32)
    flags = cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR
    if header.kind == "JPEG" and max_pixels:  # libjpeg decodes straight to 1/2, 1/4, 1/8 of the size
        reduce = 1
        while reduce < 8 and header.width * header.height / (2 * reduce) ** 2 >= max_pixels:
            reduce *= 2
        flags = {1: flags, 2: cv2.IMREAD_REDUCED_COLOR_2, 4: cv2.IMREAD_REDUCED_COLOR_4,
                 8: cv2.IMREAD_REDUCED_COLOR_8}[reduce]
    # OpenCV reads only these TIFF types, and planar 16-bit RGB with its planes mixed up
    if header.kind == "TIFF" and (header.tiff_planar or header.tiff_dtype not in (np.uint8, np.uint16, np.float32)):
        raw = read_tiff(p, data)
    else:
        with decoder_messages_dropped():  # libpng's and libjpeg's own lines: the frame's error says it
            raw = cv2.imdecode(np.frombuffer(data, np.uint8), flags)
    if raw is None:
        raise InputError(f"{p}: corrupt or truncated {header.kind} data")
    return raw


def _pnm(p: Path, data: bytes, header: _Header) -> tuple[np.ndarray, int] | None:
    """A binary or plain (ASCII) PNM's samples and maxval, read here whatever its maxval (OpenCV swaps the
    bytes of 10- and 12-bit ones); ``InputError`` saying what is wrong with a malformed one."""
    if data[:2] in (b"P5", b"P6"):
        return read_binary_pnm(p, data)
    if header.width * header.height > MAX_PLAIN_PNM_PIXELS:
        raise InputError(f"{p}: a plain (ASCII) PNM of {header.width}x{header.height} pixels; over "
                         f"{MAX_PLAIN_PNM_PIXELS // 1_000_000} megapixels, save it as a binary one")
    pnm = read_ascii_pnm(data, header.width, header.height)
    if pnm is None:
        raise InputError(f"{p}: corrupt or truncated plain PNM data")
    return pnm


def _samples(p: Path, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """(grey (H, W), colour (H, W, 3) RGB or None) of decoded samples: alpha dropped, a grey image stored
    as RGB kept grey; NaN, infinities and non-numeric types refused."""
    colour = None
    if raw.ndim == 3:
        if raw.shape[2] == 4:
            raw = raw[..., :3]
        if raw.shape[2] == 3 and not (np.array_equal(raw[..., 0], raw[..., 1])
                                      and np.array_equal(raw[..., 1], raw[..., 2])):
            colour = swapped_rb(raw)  # BGR -> RGB
        raw = raw[..., 0] if colour is None else _grey(raw)
    if raw.dtype.kind == "f" and not np.all(np.isfinite(raw)):
        raise InputError(f"{p}: image holds NaN or infinite values")
    if raw.dtype.kind not in "uif":
        raise InputError(f"{p}: unsupported pixel type {raw.dtype}")
    return raw, colour


def _photo(p: Path, raw: np.ndarray, colour_raw: np.ndarray | None, header: _Header, max_pixels: int | None,
           encoding: str) -> Photo:
    """The ``Photo`` of the samples: on their real range, reduced to ``max_pixels``, in the encoding asked."""
    full = sample_range(raw if colour_raw is None else colour_raw)
    # a JPEG is sRGB-encoded whatever its channels (a black-and-white photo too); other grey files (Yale B's PGMs,
    # the project's renders) are taken as linear
    srgb = resolve(encoding, 3 if colour_raw is not None or header.kind == "JPEG" else 1) == "srgb"
    if not (srgb and colour_raw is not None):  # an sRGB colour photo's grey is its decoded colour's luminance
        raw = shrunk(raw, max_pixels)
    colour_raw = None if colour_raw is None else shrunk(colour_raw, max_pixels)
    lo, hi = float(raw.min()) / full, float(raw.max()) / full
    if hi - lo < 1.0 / 255.0:
        raise InputError(f"{p}: has no contrast (every pixel is {lo:.3f}): nothing to fit")
    kept = raw if colour_raw is None else colour_raw
    width, height = header.width, header.height
    scale = max(kept.shape[:2]) / max(width, height)  # EXIF may turn it
    if width != height and (kept.shape[1] > kept.shape[0]) != (width > height):
        width, height = height, width  # turned a quarter by its EXIF orientation: the size as it stands
    if srgb:
        del raw, colour_raw
        return _srgb_photo(kept, full, scale, (width, height))
    img = np.clip(raw.astype(np.float32) / np.float32(full), 0.0, 1.0)
    colour = None if colour_raw is None else np.clip(colour_raw.astype(np.float32) / np.float32(full), 0.0, 1.0)
    return Photo(img, colour, scale, (width, height))


def _srgb_photo(encoded: np.ndarray, full: float, scale: float, size: tuple[int, int]) -> Photo:
    """The ``Photo`` of sRGB-encoded samples (H, W) or (H, W, 3) RGB on the scale 0..``full``: linear light, and
    the file's values at 8 bits. 8-bit colour is decoded where it is read (``Decoded8``)."""
    rgb8 = encoded if encoded.dtype == np.uint8 and full == 255.0 else \
        (np.clip(encoded.astype(np.float32) / np.float32(full), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    if encoded is rgb8 and rgb8.ndim == 3:
        rgb8 = np.ascontiguousarray(rgb8)
        del encoded
        return Photo(decoded_luminance(rgb8), Decoded8(rgb8), scale, size, "srgb", rgb8)
    linear = decode_samples(encoded, full)
    del encoded
    if linear.ndim == 2:
        return Photo(linear, None, scale, size, "srgb", np.repeat(rgb8[..., None], 3, axis=-1))
    return Photo(linear_luminance(linear), linear, scale, size, "srgb", np.ascontiguousarray(rgb8))


def _grey(bgr: np.ndarray) -> np.ndarray:
    """Luminance of a BGR image of any numeric type (as float32 when not 8/16-bit or float32)."""
    if bgr.dtype in (np.uint8, np.uint16, np.float32):
        return cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    return bgr.astype(np.float32) @ LUMA[::-1]


def sample_range(raw: np.ndarray) -> float:
    """What full brightness is in these samples (see ``read_photo``)."""
    if raw.dtype == np.uint8:
        return 255.0
    if raw.dtype == np.uint16:
        return 65535.0
    top = float(raw.max()) if raw.size else 0.0
    if raw.dtype.kind == "f" and top <= 1.0:
        return 1.0
    for bits in (8, 10, 12, 14, 16):
        if top <= 2**bits - 1:
            return float(2**bits - 1)
    return top  # beyond 16 bits no depth is standard: the brightest sample is full brightness


def shrunk(samples: np.ndarray, max_pixels: int | None) -> np.ndarray:
    """(H, W) or (H, W, C) samples area-averaged to at most ``max_pixels`` pixels, in their own type
    when OpenCV can (8/16-bit, float), so a large photo is never held as floats at full size."""
    h, w = samples.shape[:2]
    if not max_pixels or h * w <= max_pixels:
        return samples
    f = (max_pixels / (h * w)) ** 0.5
    size = (max(MIN_SIDE, int(w * f)), max(MIN_SIDE, int(h * f)))
    if samples.dtype not in (np.uint8, np.uint16, np.float32, np.float64):
        samples = samples.astype(np.float32)
    return cv2.resize(np.ascontiguousarray(samples), size, interpolation=cv2.INTER_AREA)
