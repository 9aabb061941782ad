"""PNM files (PGM, PPM) read by the format's own rules, binary (P5, P6) or plain (ASCII: P2, P3), whatever
their maxval: OpenCV reads 10- and 12-bit ones with the bytes swapped."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .encoding import swapped_rb
from .input_error import InputError

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


def read_binary_pnm(p: Path, data: bytes) -> tuple[np.ndarray, int]:
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


def read_ascii_pnm(data: bytes, width: int, height: int) -> tuple[np.ndarray, int] | None:
    """A plain (ASCII) PGM (P2) or PPM (P3), already checked to be ``width`` x ``height``, as
    ``read_binary_pnm`` gives a binary one (its samples on the scale 0..maxval, whatever the maxval);
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
