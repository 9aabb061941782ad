"""TIFF files: their header read before anything is decoded, the types OpenCV cannot decode read through
tifffile, and segments that would inflate past their geometry (decompression bombs) refused."""
from __future__ import annotations

import io
import zlib
from pathlib import Path

import numpy as np

from .input_error import InputError

TIFF_MAGIC = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")

# what one tile or strip of a TIFF may hold: a tile larger than its image is decoded whole before it is cropped (a
# 64 x 64 image declaring one 16384^2 float64 tile took 4.3 GB); encoders tile at 256-1024 pixels a side
MAX_TILE_PIXELS = 4_000_000
# TIFF compressions tifffile decodes without a bound on what they inflate to (zlib, Adobe deflate, LZMA, zstd): each
# segment is inflated first, no further than its geometry allows
_INFLATING = {8: "zlib", 32946: "zlib", 34925: "lzma", 50000: "zstd"}


def tiff_header(data: bytes) -> tuple[int, int, np.dtype, bool]:
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


def read_tiff(p: Path, data: bytes) -> np.ndarray | None:
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
