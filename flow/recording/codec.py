"""The array message of MCAP recordings (``shadowflow.ndarray``, see ``recordings/README.md``),
deterministic log times, and the JSON schemas of the other messages."""
from __future__ import annotations

import json
import struct

import numpy as np


from .events import OnMask

ARRAY_MAGIC = b"SFA1"
ARRAY_ENCODING = "shadowflow.ndarray"
ARRAY_SCHEMA = "shadowflow.NDArray"
ARRAY_SCHEMA_TEXT = (  # the schema record's data: how a reader decodes the message, without this code
    "shadowflow.ndarray: b'SFA1', uint32 little-endian n, n bytes of UTF-8 JSON header "
    '{"frame": int, "iteration": int|null, "dtype": numpy dtype string (little-endian: "<f4", "|u1", ...), '
    '"shape": [int, ...], "masked": true (optional)}, then the payload: the array\'s C-order bytes; when '
    "masked, shape is (H, W, ...) and the payload is numpy.packbits of the (H, W) bool mask (row-major, "
    "big bit order, padded to a byte) followed by the values at the mask's True pixels in row-major order, "
    "(N, ...); off the mask a float array is NaN, others 0.")
ALLOWED_DTYPES = {"<f2", "<f4", "<f8", "|u1", "<u2", "<u4", "<i4", "<i8", "|b1"}
MAX_ARRAY_BYTES = 1 << 30  # a message claiming more than 1 GiB is refused when reading


def log_time_ns(frame: int, iteration: int | None) -> int:
    """Deterministic MCAP time: 1 s per frame, 1 ms per iteration (no wall clock)."""
    return int(frame) * 1_000_000_000 + (0 if iteration is None else int(iteration) + 1) * 1_000_000


def encode_array(frame: int, iteration: int | None, arr: np.ndarray, mask: np.ndarray | None = None) -> bytes:
    """``SFA1`` + uint32 LE header length + JSON header + payload.

    Dense (``mask`` None): the payload is ``arr``'s raw C-order little-endian bytes. Masked:
    ``arr`` holds the values (N, ...) at the N True pixels of the bool grid ``mask`` (H, W);
    the header says ``"masked": true`` with the full shape (H, W, ...), and the payload is
    ``np.packbits(mask)`` followed by the values' bytes. Readers rebuild the full array with
    NaN (floats) or 0 off the mask.
    """
    a = np.ascontiguousarray(arr)
    if a.dtype.byteorder == ">":
        a = a.astype(a.dtype.newbyteorder("<"))
    shape = list(a.shape) if mask is None else list(mask.shape) + list(a.shape[1:])
    head = {"frame": int(frame), "iteration": iteration, "dtype": a.dtype.str, "shape": shape}
    if mask is not None:
        head["masked"] = True
    header = json.dumps(head, separators=(",", ":")).encode()
    bits = b"" if mask is None else np.packbits(mask).tobytes()
    return ARRAY_MAGIC + struct.pack("<I", len(header)) + header + bits + a.tobytes()


def decode_array(data: bytes, check_only: bool = False) -> tuple[dict, np.ndarray | None]:
    """Inverse of ``encode_array`` (a masked message comes back as the full array); raises
    ``ValueError`` on anything malformed. ``check_only``: validate the whole message the same
    way, but build no array (None)."""
    header, hlen = _array_header(data)
    dtype, shape = header["dtype"], header["shape"]
    itemsize = np.dtype(dtype).itemsize
    full = int(np.prod(shape, dtype=np.int64)) * itemsize
    if full > MAX_ARRAY_BYTES:
        raise ValueError(f"array payload is {len(data) - 8 - hlen} bytes, header says {full}, over the "
                         f"{MAX_ARRAY_BYTES}-byte limit")
    payload = memoryview(data)[8 + hlen:]
    if not header.get("masked", False):
        if full != len(payload):
            raise ValueError(f"array payload is {len(payload)} bytes, header says {full}")
        return header, None if check_only else np.frombuffer(payload, dtype=dtype).reshape(shape).copy()
    return header, _masked_array(payload, dtype, shape, check_only)


def _array_header(data: bytes) -> tuple[dict, int]:
    """An array message's JSON header, checked (an allowed dtype, a shape of at most 8 sizes, a masked
    flag), and its length in bytes."""
    if len(data) < 8 or data[:4] != ARRAY_MAGIC:
        raise ValueError("not a shadowflow array message")
    (hlen,) = struct.unpack("<I", data[4:8])
    if hlen > 4096 or 8 + hlen > len(data):
        raise ValueError("array header length out of range")
    header = json.loads(data[8:8 + hlen])
    if not isinstance(header, dict):
        raise ValueError(f"bad array header {header!r}")
    dtype, shape, masked = header.get("dtype"), header.get("shape"), header.get("masked", False)
    if dtype not in ALLOWED_DTYPES or not isinstance(shape, list) or len(shape) > 8 \
            or not all(isinstance(d, int) and 0 <= d for d in shape) or masked not in (True, False) \
            or (masked and len(shape) < 2):
        raise ValueError(f"bad array header {header!r}")
    return header, hlen


def _masked_array(payload: memoryview, dtype: str, shape: list[int], check_only: bool) -> np.ndarray | None:
    """A masked message's full array (NaN or 0 off its mask), from its packed mask and its values."""
    pixels = shape[0] * shape[1]
    nbits = (pixels + 7) // 8
    if len(payload) < nbits:
        raise ValueError(f"masked array payload is {len(payload)} bytes, its mask alone needs {nbits}")
    mask = np.unpackbits(np.frombuffer(payload[:nbits], np.uint8), count=pixels).astype(bool).reshape(shape[:2])
    per_pixel = int(np.prod(shape[2:], dtype=np.int64))
    n = int(mask.sum()) * per_pixel * np.dtype(dtype).itemsize
    if n != len(payload) - nbits:
        raise ValueError(f"masked array values are {len(payload) - nbits} bytes, its mask says {n}")
    if check_only:
        return None
    values = np.frombuffer(payload[nbits:], dtype=dtype).reshape((-1, *shape[2:]))
    fill = np.nan if np.dtype(dtype).kind == "f" else 0
    return OnMask(values, mask).grid(fill)


JSON_SCHEMAS: dict[str, dict] = {
    "shadowflow.Scalars": {"type": "object", "properties": {
        "frame": {"type": "integer"}, "iteration": {"type": ["integer", "null"]},
        "values": {"type": "object", "additionalProperties": {"type": "number"}}}},
    "shadowflow.Frame": {"type": "object", "properties": {
        "frame": {"type": "integer"}, "values": {"type": "object"}}},
}
