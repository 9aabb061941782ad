"""Loader: images to float brightness in [0, 1], and where the light and eyes come from."""
from __future__ import annotations

import errno
import io
import json
import os
import re
import stat
import warnings
import zlib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from ..geometry.reflectance import light_from_angles
from .native_messages import decoder_messages_dropped
from .encoding import Decoded8, decode_samples, decoded_luminance, linear_luminance, resolve, swapped_rb

# what a folder is read for; a file named on the command line is read whatever its name
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".jfif", ".pgm", ".ppm", ".pnm", ".tif", ".tiff", ".bmp", ".webp", ".gif",
                  ".npy"}
_YALEB = re.compile(r"_P\d+A([+-]\d{3})E([+-]\d{2})")


class InputError(ValueError):
    """A problem with one input; the message names the file and the problem on one line."""


@dataclass(frozen=True)
class Sidecar:
    """Optional ``<stem>.json`` next to an input: ``light`` (3,) and ``eyes`` (2, 2)."""

    light: np.ndarray | None = None
    eyes: np.ndarray | None = None


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
MAX_SIDECAR_BYTES = 64 << 10  # a sidecar holds a light and two eyes: a few dozen bytes


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


# a PNM header's next number: whitespace and comments (to the end of their line) before it, taken possessively so that
# a header of megabytes of comments is scanned once, and no more digits than a 32-bit number has
_PNM_FIELD = re.compile(rb"(?:\s|#[^\r\n]*+)*+(\d{1,10}+)(?!\d)")


def _pnm_header(data: bytes) -> tuple[int, int, int, int] | None:
    """A PNM's (width, height, maxval, where its samples start) after its magic, its comments any length
    (a 14-bit PGM's 2,000-byte comment made the first 1,024 bytes a header without its numbers); None when
    it is malformed."""
    pos, values = 2, []
    for _ in range(3):
        m = _PNM_FIELD.match(data, pos)
        if m is None:
            return None
        values.append(int(m.group(1)))
        pos = m.end()
    if not data[pos:pos + 1].isspace():  # one whitespace character ends the header
        return None
    return values[0], values[1], values[2], pos + 1


def _read_binary_pnm(p: Path, data: bytes) -> tuple[np.ndarray, int]:
    """A binary PGM (P5) or PPM (P6) as ``(samples (H, W) or (H, W, 3) BGR as OpenCV gives them,
    uint8 or uint16, maxval)``, read by the format's own rules (samples over 255 are two bytes,
    big-endian, on the scale 0..maxval); ``InputError`` when the header or the data is malformed."""
    header = _pnm_header(data)
    if header is None:
        raise InputError(f"{p}: corrupt PNM header (its width, height and maxval)")
    width, height, maxval, start = header
    if not 0 < maxval < 65536:
        raise InputError(f"{p}: PNM maxval {maxval} is outside 1-65535")
    channels = 3 if data[:2] == b"P6" else 1
    dtype = np.dtype(">u2") if maxval > 255 else np.dtype(np.uint8)
    count = width * height * channels
    body = data[start:start + count * dtype.itemsize]
    if len(body) < count * dtype.itemsize:
        raise InputError(f"{p}: truncated PNM data ({len(body)} of the {count * dtype.itemsize} bytes its header "
                         "declares)")
    samples = np.frombuffer(body, dtype).reshape((height, width, channels) if channels == 3 else (height, width))
    samples = samples.astype(np.uint16 if maxval > 255 else np.uint8)
    return (swapped_rb(samples) if channels == 3 else samples), maxval


_PLAIN_BLOCK = 1 << 22  # bytes of a plain PNM's samples split into numbers at a time


def _plain_samples(data: bytes, start: int, count: int) -> np.ndarray | None:
    """The first ``count`` numbers of a plain PNM's samples from ``start``, split a block at a time (whatever
    follows them, megabytes of more numbers too, is never read); None when there are fewer, or one is not a
    number of at most five digits."""
    parts, got, pos, carry = [], 0, start, b""
    while got < count and (pos < len(data) or carry):
        block = data[pos:pos + _PLAIN_BLOCK]
        pos += len(block)
        tokens = (carry + block).split()
        carry = tokens.pop() if tokens and block and not block[-1:].isspace() else b""
        if len(carry) > 5:
            return None
        take = tokens[:count - got]
        if take:
            digits = np.array(take)
            if digits.dtype.itemsize > 5 or not all(t.isdigit() for t in take):
                return None
            parts.append(digits.astype(np.int64))
            got += len(take)
    return np.concatenate(parts) if got == count else None


def _read_ascii_pnm(data: bytes, width: int, height: int) -> tuple[np.ndarray, int] | None:
    """A plain (ASCII) PGM (P2) or PPM (P3), already checked to be ``width`` x ``height``, as
    ``_read_binary_pnm`` gives a binary one (its samples on the scale 0..maxval, whatever the maxval);
    None when it is malformed (too few samples, one over maxval)."""
    header = _pnm_header(data)
    if header is None or header[:2] != (width, height) or not 0 < header[2] < 65536:
        return None
    maxval = header[2]
    channels = 3 if data[:2] == b"P3" else 1
    samples = _plain_samples(data, header[3], width * height * channels)
    if samples is None or samples.max() > maxval:
        return None
    samples = samples.astype(np.uint16 if maxval > 255 else np.uint8)
    samples = samples.reshape((height, width, 3) if channels == 3 else (height, width))
    return (swapped_rb(samples) if channels == 3 else samples), maxval


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


TIFF_MAGIC = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")


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
                width, height, dtype, planar = _tiff_header(data)
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
        raw = _read_tiff(p, data)
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
        return _read_binary_pnm(p, data)
    if header.width * header.height > MAX_PLAIN_PNM_PIXELS:
        raise InputError(f"{p}: a plain (ASCII) PNM of {header.width}x{header.height} pixels; over "
                         f"{MAX_PLAIN_PNM_PIXELS // 1_000_000} megapixels, save it as a binary one")
    pnm = _read_ascii_pnm(data, header.width, header.height)
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


# what one tile or strip of a TIFF may hold: a tile larger than its image is decoded whole before it is cropped (a
# 64 x 64 image declaring one 16384^2 float64 tile took 4.3 GB); encoders tile at 256-1024 pixels a side
MAX_TILE_PIXELS = 4_000_000
# TIFF compressions tifffile decodes without a bound on what they inflate to (zlib, Adobe deflate, LZMA, zstd): each
# segment is inflated first, no further than its geometry allows
_INFLATING = {8: "zlib", 32946: "zlib", 34925: "lzma", 50000: "zstd"}


def _tiff_header(data: bytes) -> tuple[int, int, np.dtype, bool]:
    """(width, height, sample type, planar: one plane a channel) of a TIFF's first image, from its header only;
    ``ValueError`` for a tile (or strip) over ``MAX_TILE_PIXELS`` and larger than the image."""
    import tifffile

    try:
        with tifffile.TiffFile(io.BytesIO(data)) as tif:
            page = tif.pages[0]
            planar = page.planarconfig == tifffile.PLANARCONFIG.SEPARATE and page.samplesperpixel > 1
            width, height = int(page.imagewidth), int(page.imagelength)
            tile = (int(page.tilewidth) * int(page.tilelength) * max(1, int(page.tiledepth)) if page.is_tiled
                    else width * min(int(page.rowsperstrip) or height, height))
            dtype = np.dtype(page.dtype)
    except MemoryError:
        raise
    except Exception as exc:  # noqa: BLE001 - struct, index, type errors...: a damaged header, whatever the kind
        raise ValueError(f"damaged TIFF header ({type(exc).__name__})") from None
    if tile > max(MAX_TILE_PIXELS, width * height):
        raise TiffBomb(f"one TIFF tile of {tile} pixels for an image of {width}x{height}; over the "
                       f"{MAX_TILE_PIXELS // 1_000_000}-megapixel limit of a tile larger than its image")
    return width, height, dtype, planar


class TiffBomb(InputError):
    """A TIFF whose tiles or strips would decode to far more than its image (the message says how)."""


def _inflation_checked(p: Path, data: bytes, page) -> None:
    """``InputError`` when a segment (tile or strip) of ``page`` inflates past what its geometry holds: each is
    inflated in pieces and let go, before tifffile inflates them whole."""
    kind = _INFLATING.get(int(page.compression))
    if kind is None:
        return
    size = int(np.prod(page.chunks)) * max(1, page.dtype.itemsize)
    for offset, count in zip(page.dataoffsets, page.databytecounts):
        segment = data[offset:offset + count]
        if kind == "zlib":
            inflate = zlib.decompressobj()
        elif kind == "lzma":
            import lzma

            inflate = lzma.LZMADecompressor()
        else:
            import zstandard

            inflate = zstandard.ZstdDecompressor().decompressobj()
        got = _inflated_size(inflate, segment, size)
        if got > size:
            raise InputError(f"{p}: a TIFF strip or tile inflates past the {size} bytes its geometry holds "
                             "(a decompression bomb)")


def _inflated_size(inflate, segment: bytes, size: int) -> int:
    """How many bytes ``inflate`` (a zlib, LZMA or zstd decompressor) makes of ``segment``, counted no further
    than ``size`` + 1, a megabyte at a time."""
    got, step = 0, 1 << 20
    try:
        if hasattr(inflate, "unconsumed_tail"):  # zlib: max_length, then its unconsumed tail
            out = inflate.decompress(segment, step)
            while out and got <= size:
                got += len(out)
                out = inflate.decompress(inflate.unconsumed_tail, step) if inflate.unconsumed_tail else b""
        elif hasattr(inflate, "needs_input"):  # lzma
            out = inflate.decompress(segment, step)
            while out and got <= size:
                got += len(out)
                out = inflate.decompress(b"", step)
        else:  # zstd's decompressobj has no output bound: read from a stream instead
            import zstandard

            reader = zstandard.ZstdDecompressor().stream_reader(io.BytesIO(segment))
            while got <= size and (out := reader.read(step)):
                got += len(out)
    except Exception:  # noqa: BLE001 - a damaged stream: tifffile's decoding says so
        return 0
    return got


def _read_tiff(p: Path, data: bytes) -> np.ndarray | None:
    """A TIFF OpenCV cannot decode (32-bit integers, 64-bit floats, signed...) through tifffile, as
    (H, W) or (H, W, C) in BGR order; None when it is damaged."""
    import tifffile

    try:
        with tifffile.TiffFile(io.BytesIO(data)) as tif:
            page = tif.pages[0]
            _inflation_checked(p, data, page)
            arr = page.asarray()
            planar = page.planarconfig == tifffile.PLANARCONFIG.SEPARATE
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - tifffile raises many kinds for damaged files
        if isinstance(exc, MemoryError):
            raise
        return None
    if planar and arr.ndim == 3:  # one plane a channel, (S, H, W): as interleaved
        arr = np.moveaxis(arr, 0, -1)
    if arr.ndim == 3 and arr.shape[2] in (3, 4):
        return arr[..., [2, 1, 0]] if arr.shape[2] == 3 else arr[..., [2, 1, 0, 3]]
    if arr.ndim != 2:
        raise InputError(f"{p}: TIFF of shape {arr.shape} is not one grey or colour image")
    return arr


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
