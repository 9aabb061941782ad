"""Messages between a run and its recording process: a JSON header and raw array bytes, no pickle.

A message is ``uint32 little-endian n``, ``n`` bytes of UTF-8 JSON (the header, space-padded so
the payload starts 8-byte aligned), then the payload: the C-order bytes of the header's
``"buffers"`` one after the other, each padded with zeros to a multiple of 8 bytes. In the header's
``"value"`` tree an array is ``{"$a": i}`` (buffer ``i``), an ``OnMask`` is ``{"$m": i, "mask":
key}`` (its values in buffer ``i``, its mask sent before as a ``mask`` message under ``key``);
dicts, lists, strings, numbers (NaN included), booleans and null are themselves; NumPy scalars
become numbers and anything else its ``str`` (as the recordings' JSON would show it anyway).
Both ends are this package; the format keeps a recording process from ever unpickling anything.
"""
from __future__ import annotations

import json
import struct
from typing import Any

import numpy as np

from .events import OnMask

ARRAY, MASKED = "$a", "$m"


def encode(header: dict, value: Any = None, mask_key=None) -> bytes:
    """One message: ``header`` (a JSON object) with ``value`` as its ``"value"``. ``mask_key``:
    ``OnMask`` -> the key its mask was sent under (see ``ProcessSinks``)."""
    buffers: list[np.ndarray] = []

    def tree(x: Any) -> Any:
        if isinstance(x, dict):
            return {str(k): tree(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [tree(v) for v in x]
        if isinstance(x, OnMask):
            buffers.append(np.ascontiguousarray(x.values))
            return {MASKED: len(buffers) - 1, "mask": mask_key(x)}
        if isinstance(x, np.ndarray):
            buffers.append(np.ascontiguousarray(x))
            return {ARRAY: len(buffers) - 1}
        if isinstance(x, np.generic):
            return x.item()
        if x is None or isinstance(x, (str, int, float, bool)):
            return x
        return str(x)

    head = dict(header)
    if value is not None:
        head["value"] = tree(value)
    head["buffers"] = [[a.dtype.str, list(a.shape)] for a in buffers]
    text = json.dumps(head, separators=(",", ":")).encode()
    text += b" " * (-(4 + len(text)) % 8)
    parts = [struct.pack("<I", len(text)), text]
    for a in buffers:
        parts += [a.data, bytes(-a.nbytes % 8)]  # the array's own buffer: joined with one copy
    return b"".join(parts)


def decode(data: bytes, masks: dict) -> dict:
    """Inverse of ``encode``: the header with its ``"value"`` rebuilt (arrays are read-only views
    of ``data``); ``masks``: key -> the (H, W) bool masks received so far."""
    (n,) = struct.unpack_from("<I", data)
    head = json.loads(data[4:4 + n])
    arrays, at = [], 4 + n
    for dtype, shape in head.pop("buffers"):
        count = int(np.prod(shape, dtype=np.int64))
        arrays.append(np.frombuffer(data, np.dtype(dtype), count, at).reshape(shape))
        nbytes = count * np.dtype(dtype).itemsize
        at += nbytes + (-nbytes % 8)
    if at != len(data):
        raise ValueError(f"message is {len(data)} bytes, its header accounts for {at}")

    def tree(x: Any) -> Any:
        if isinstance(x, dict):
            if ARRAY in x:
                return arrays[x[ARRAY]]
            if MASKED in x:
                return OnMask(arrays[x[MASKED]], masks[x["mask"]])
            return {k: tree(v) for k, v in x.items()}
        if isinstance(x, list):
            return [tree(v) for v in x]
        return x

    if "value" in head:
        head["value"] = tree(head["value"])
    return head
