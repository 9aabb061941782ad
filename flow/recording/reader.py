"""Reading MCAP recordings back without trusting them."""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .codec import ARRAY_ENCODING, MAX_ARRAY_BYTES, decode_array


@dataclass
class FrameRecording:
    """Everything recorded for one frame.

    arrays: path -> {iteration (None for per-frame) -> array}; scalars: path -> {iteration ->
    {name: value}}; record: the frame's closing record (source, status, ...), if it finished.
    """

    frame: int
    arrays: dict[str, dict[int | None, np.ndarray]] = field(default_factory=dict)
    scalars: dict[str, dict[int | None, dict]] = field(default_factory=dict)
    record: dict | None = None

    @property
    def finished(self) -> bool:
        return self.record is not None

    def iterations(self, path: str) -> list[int]:
        src = self.arrays.get(path) or self.scalars.get(path) or {}
        return sorted(i for i in src if i is not None)


@dataclass
class Recording:
    """A recording read back: ``frames`` by stream position, and ``truncated`` when the file
    ended early (a killed run); everything before the cut is kept."""

    path: Path
    frames: dict[int, FrameRecording]
    truncated: bool = False

    def finished_frames(self) -> list[FrameRecording]:
        return [f for _, f in sorted(self.frames.items()) if f.finished]


class RecordingError(ValueError):
    """The file is not a readable shadowflow recording (the message says why, on one line)."""


def read_mcap(path: str | Path) -> Recording:
    """Read a shadowflow MCAP recording without trusting it.

    No pickle, no code: arrays are decoded only from the documented binary layout with a
    whitelist of dtypes and a size check; a record claiming more than 1 GiB is refused. A
    file cut short (killed run) yields what came before the cut, ``truncated=True``.
    """
    from mcap.reader import NonSeekingReader

    path = Path(path)
    frames: dict[int, FrameRecording] = {}
    truncated = False
    try:
        fh = open(path, "rb")
    except OSError as exc:
        raise RecordingError(f"{path}: cannot open ({exc.strerror or exc})") from None
    with fh:
        head = fh.read(8)
        if head != b"\x89MCAP0\r\n":
            raise RecordingError(f"{path}: not an MCAP file")
        fh.seek(0)
        reader = NonSeekingReader(fh, record_size_limit=MAX_ARRAY_BYTES + (1 << 20))
        it = reader.iter_messages(log_time_order=False)  # file order: stream, never buffer the file
        while True:
            try:
                schema, channel, message = next(it)
            except StopIteration:
                break
            except Exception as exc:  # noqa: BLE001 - McapError, zstd/lz4 errors, EOF...: all mean a bad file
                if not frames:
                    raise RecordingError(f"{path}: unreadable MCAP ({type(exc).__name__}: {exc})") from None
                truncated = True
                break
            try:
                _take(frames, channel.topic, channel.message_encoding, message.data)
            except (ValueError, KeyError, TypeError) as exc:
                raise RecordingError(f"{path}: bad message on {channel.topic} ({exc})") from None
    return Recording(path, frames, truncated)


def _take(frames: dict[int, FrameRecording], topic: str, encoding: str, data: bytes) -> None:
    if topic.endswith("/foxglove"):
        return  # a display copy of an array recorded exactly beside it
    path = topic.lstrip("/")
    if encoding == ARRAY_ENCODING:
        header, arr = decode_array(data)
        fr = frames.setdefault(int(header["frame"]), FrameRecording(int(header["frame"])))
        fr.arrays.setdefault(path, {})[header["iteration"]] = arr
    elif encoding == "json":
        body = json.loads(data)
        frame = int(body["frame"])
        fr = frames.setdefault(frame, FrameRecording(frame))
        if path == "frames":
            fr.record = dict(body["values"])
        else:
            fr.scalars.setdefault(path, {})[body.get("iteration")] = dict(body["values"])
    else:
        raise ValueError(f"unknown message encoding {encoding!r}")
