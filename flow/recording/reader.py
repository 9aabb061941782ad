"""Reading MCAP recordings back without trusting them."""
from __future__ import annotations

import io
import json
import os
import stat
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

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

    def __iter__(self) -> Iterator[FrameRecording]:
        return iter([f for _, f in sorted(self.frames.items())])

    def finished_frames(self) -> list[FrameRecording]:
        return [f for _, f in sorted(self.frames.items()) if f.finished]


class RecordingError(ValueError):
    """The file is not a readable shadowflow recording (the message says why, on one line)."""


MAX_OPEN_BYTES = 2 << 30  # arrays held for frames not yet closed; a file needing more is refused
# scalar messages held for frames not yet closed: a frame records one a fit iteration and channel (hundreds; thousands
# for a photo of many faces), and each costs some hundred bytes of Python objects held
MAX_OPEN_SCALARS = 500_000
# a chunk is decompressed whole: one declaring more is refused before any of it is (the writer's chunks hold a
# frame, 4 MiB typically; a message holds one array of at most MAX_ARRAY_BYTES)
MAX_CHUNK_BYTES = MAX_ARRAY_BYTES + (1 << 20)
# what the chunks of a file may declare in all: this many times the bytes read so far, plus an allowance (twice the
# writer's 4 MiB chunk). The writer's chunks decompress to 1.3-2.4 times their size (lz4 on the
# fit's arrays); a chunk of a few kB that declares hundreds of MiB of tiny messages is a bomb, each message costing
# some microseconds to read (docs/faults.md)
MAX_INFLATION = 16
INFLATION_ALLOWANCE = 8 << 20
MAGIC = b"\x89MCAP0\r\n"


class ChunkError(ValueError):
    """A chunk that cannot be read within its bounds (the file is bad, not cut short)."""


def _chunk_data(chunk) -> bytes:
    """The chunk's records, decompressed no further than the size it declares (itself at most
    ``MAX_CHUNK_BYTES``), whatever its compressed stream holds, and checked against its CRC when it
    has one (the writer's always do)."""
    declared = chunk.uncompressed_size
    if declared > MAX_CHUNK_BYTES:
        raise ChunkError(f"a chunk declares {declared} bytes, over the {MAX_CHUNK_BYTES >> 30} GiB limit")
    if chunk.compression == "zstd":
        import zstandard

        reader = zstandard.ZstdDecompressor().stream_reader(io.BytesIO(chunk.data), read_across_frames=True)
        parts, got = [], 0
        while got <= declared and (part := reader.read(min(declared + 1 - got, 1 << 20) or 1)):
            parts.append(part)
            got += len(part)
        data = b"".join(parts)
    elif chunk.compression == "lz4":
        import lz4.frame

        data = lz4.frame.LZ4FrameDecompressor().decompress(chunk.data, max_length=declared + 1)
    elif chunk.compression == "":
        data = chunk.data
    else:
        raise ChunkError(f"a chunk is compressed with {chunk.compression!r} (zstd, lz4 or none are read)")
    if len(data) > declared:
        raise ChunkError(f"a chunk decompresses to more than the {declared} bytes it declares")
    if len(data) < declared:
        raise ChunkError(f"a chunk decompresses to {len(data)} bytes, not the {declared} it declares")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise ChunkError("a chunk's records fail its CRC check: the file is corrupt")
    return data


_MESSAGE = struct.Struct("<HIQQ")  # a message record's channel, sequence, log and publish times


def _chunk_records(data: bytes) -> Iterator[object]:
    """The schema, channel and message records of a chunk's decompressed ``data``, one at a time (a chunk
    of a million tiny messages is never a list of them); a record running past the chunk's end is a
    ``ChunkError``."""
    from mcap.data_stream import ReadDataStream
    from mcap.opcode import Opcode
    from mcap.records import Channel, Message, Schema

    pos, n = 0, len(data)
    while pos < n:
        if n - pos < 9:
            raise ChunkError("a chunk ends inside a record's header: the file is corrupt")
        opcode, length = data[pos], int.from_bytes(data[pos + 1:pos + 9], "little")
        pos += 9
        end = pos + length
        if end > n:
            raise ChunkError("a record runs past the end of its chunk: the file is corrupt")
        if opcode == Opcode.MESSAGE:
            if length < _MESSAGE.size:
                raise ChunkError("a message record shorter than its header: the file is corrupt")
            channel, sequence, log_time, publish_time = _MESSAGE.unpack_from(data, pos)
            yield Message(channel_id=channel, sequence=sequence, log_time=log_time, publish_time=publish_time,
                          data=data[pos + _MESSAGE.size:end])
        elif opcode in (Opcode.CHANNEL, Opcode.SCHEMA):
            kind = Channel if opcode == Opcode.CHANNEL else Schema
            yield kind.read(ReadDataStream(io.BytesIO(data[pos:end])))
        pos = end


class _Exact:
    """A file read as the MCAP reader reads it, but a read that gets fewer bytes than it asks for is the
    end of the file (``EndOfFile``): a record cut short by a kill is never handed on half-read."""

    def __init__(self, fh):
        self.fh = fh

    def read(self, n: int = -1) -> bytes:
        data = self.fh.read(n)
        if n > 0 and len(data) < n:
            from mcap.exceptions import EndOfFile

            raise EndOfFile()
        return data

    def tell(self) -> int:
        return self.fh.tell()


class McapMessages:
    """``(channel, message)`` of an MCAP stream in file order (a ``NonSeekingReader`` with its chunks
    bounded, ``_chunk_data``, and all of them together declaring at most ``MAX_INFLATION`` times the
    bytes read, ``INFLATION_ALLOWANCE`` more). Raises ``ChunkError`` for a chunk out of bounds, the reader's
    errors (``mcap.exceptions.EndOfFile`` for a file cut short) for the rest. ``started``: its header was
    read (a file cut after it is a recording cut short, not a file of another kind)."""

    def __init__(self, fh, record_size_limit: int):
        self.fh, self.record_size_limit, self.started = fh, record_size_limit, False

    def __iter__(self) -> Iterator[tuple[object, object]]:
        from mcap.exceptions import McapError
        from mcap.records import Channel, Chunk, Header, Message
        from mcap.stream_reader import StreamReader

        channels: dict[int, Channel] = {}
        declared = 0
        reader = _Exact(self.fh)
        for record in StreamReader(reader, emit_chunks=True, record_size_limit=self.record_size_limit).records:
            if isinstance(record, Header):
                self.started = True
            if isinstance(record, Chunk):
                declared += record.uncompressed_size
                allowed = MAX_INFLATION * reader.tell() + INFLATION_ALLOWANCE
                if declared > allowed and record.uncompressed_size <= MAX_CHUNK_BYTES:
                    raise ChunkError(f"its chunks declare {declared} bytes in its first {reader.tell()}, over "
                                     f"{MAX_INFLATION} times as many (a recording's inflate about 2 times)")
                inner = _chunk_records(_chunk_data(record))
            else:
                inner = (record,)
            for r in inner:
                if isinstance(r, Channel):
                    channels[r.id] = r
                elif isinstance(r, Message):
                    channel = channels.get(r.channel_id)
                    if channel is None:
                        raise McapError(f"a message on channel {r.channel_id}, which was never declared")
                    yield channel, r


class FrameStream:
    """The frames of one MCAP recording, read as a stream: iterating yields each frame's
    ``FrameRecording`` once its closing record has come and a message of another frame follows
    (then forgets it; a frame's messages may come in any order, as in a file sorted by log
    time), and at the end the frames never closed (a killed run), in id order. Only the frames still open are held
    (one at a time when frames were recorded one after another).

    arrays: False skips array messages (a table or a plot needs only scalars and records).
    After iterating, ``truncated`` says whether the file ended early. Malformed content raises
    ``RecordingError`` naming the file; running out of memory is never taken for truncation.
    part: the file is one part of a job's recording (``flow.replay.JobStream``), which a kill may have cut
    before it held a whole header (even at 0 bytes): then it holds no frame and is ``truncated``.
    """

    def __init__(self, path: str | Path, arrays: bool = True, part: bool = False):
        self.path, self.arrays, self.truncated, self.part = Path(path), arrays, False, part

    def __iter__(self) -> Iterator[FrameRecording]:
        if self.part and self._cut_in_header():
            self.truncated = True
            return
        open_frames: dict[int, FrameRecording] = {}
        held = {"bytes": 0, "entries": 0}
        closing: set[int] = set()  # frames whose closing record has come
        with self._opened() as fh:
            for channel, message in self._messages(fh):
                current, closed = self._take(open_frames, held, channel, message)
                for fid in [f for f in closing if current is not None and f != current]:  # its record came, and then another frame
                    closing.discard(fid)
                    fr = open_frames.pop(fid)
                    held["bytes"] -= _nbytes(fr)
                    held["entries"] -= _entries(fr)
                    yield fr
                if closed:
                    closing.add(current)
        for fid in sorted(closing):
            yield open_frames.pop(fid)
        for fid in sorted(open_frames):
            yield open_frames.pop(fid)

    def _opened(self):
        """The file, open at its start, once it is known to be an MCAP file (a pipe or device is never read:
        it could hang the reader)."""
        try:
            fd = os.open(self.path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot open ({exc.strerror or exc})") from None
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            os.close(fd)
            raise RecordingError(f"{self.path}: not a regular file (a pipe, socket or device)")
        fh = os.fdopen(fd, "rb")
        if fh.read(8) != MAGIC:
            fh.close()
            raise RecordingError(f"{self.path}: " + ("is empty (0 bytes)" if st.st_size == 0 else "not an MCAP file"))
        fh.seek(0)
        return fh

    def _cut_in_header(self) -> bool:
        """Whether the file ends within the magic and header record a recording begins with (a part created
        and listed, then killed before its header reached the disk)."""
        try:
            st = os.stat(self.path)
            if not stat.S_ISREG(st.st_mode):
                return False
            with open(self.path, "rb") as fh:
                head = fh.read(len(MAGIC) + 9)
        except OSError:
            return False
        if head[:len(MAGIC)] != MAGIC[:len(head)]:
            return False
        return len(head) < len(MAGIC) + 9 or st.st_size < len(head) + int.from_bytes(head[-8:], "little")

    def _complete(self, fh) -> bool:
        """Whether the file ends as a finished recording does (its closing magic): an error reading it is
        damage, not a cut."""
        try:
            size = os.fstat(fh.fileno()).st_size
            return size >= 16 and os.pread(fh.fileno(), 8, size - 8) == MAGIC
        except OSError:
            return False

    def _messages(self, fh) -> Iterator[tuple[object, object]]:
        """``(channel, message)`` in file order (a stream: the file is never buffered); a file cut short
        ends them (``truncated``) once anything was read; a bad one raises ``RecordingError``, a damaged
        one naming where (bytes that make no record, a chunk failing its CRC, a finished file whose records
        run past its end)."""
        from mcap.exceptions import EndOfFile

        path, seen_any = self.path, False
        messages = McapMessages(fh, MAX_CHUNK_BYTES)
        it = iter(messages)
        while True:
            try:
                item = next(it)
            except StopIteration:
                return
            except MemoryError:
                raise RecordingError(f"{path}: out of memory while reading it (not a truncated file)") from None
            except ChunkError as exc:
                raise RecordingError(f"{path}: {exc}") from None
            except EndOfFile as exc:  # cut short (a kill, a full disk): what came before it stands
                if not (seen_any or messages.started):
                    raise RecordingError(f"{path}: unreadable MCAP (EndOfFile: {exc})") from None
                if self._complete(fh):
                    raise RecordingError(f"{path}: corrupt: a record runs past the end of a finished recording "
                                         f"(at byte {fh.tell()})") from None
                self.truncated = True
                return
            except Exception as exc:  # noqa: BLE001 - McapError, zstd/lz4 errors...: all mean a bad file
                if not (seen_any or messages.started):
                    raise RecordingError(f"{path}: unreadable MCAP ({type(exc).__name__}: {exc})") from None
                raise RecordingError(f"{path}: corrupt at byte {fh.tell()} ({type(exc).__name__}: "
                                     f"{' '.join(str(exc).split())}); not a cut file") from None
            seen_any = True
            yield item

    def _take(self, open_frames: dict[int, FrameRecording], held: dict, channel, message) -> tuple[int | None, bool]:
        """One message into its frame (``_take``), its errors as ``RecordingError``; the frames still open
        may hold at most ``MAX_OPEN_BYTES`` of arrays and ``MAX_OPEN_SCALARS`` entries."""
        path = self.path
        try:
            taken = _take(open_frames, held, channel.topic, channel.message_encoding, message.data, self.arrays)
        except MemoryError:
            raise RecordingError(f"{path}: out of memory while reading it (not a truncated file)") from None
        except (ValueError, KeyError, TypeError, OverflowError) as exc:
            raise RecordingError(f"{path}: bad message on {channel.topic} ({exc})") from None
        if held["bytes"] > MAX_OPEN_BYTES:
            raise RecordingError(f"{path}: frames still open hold over {MAX_OPEN_BYTES >> 30} GiB of "
                                 "arrays; refusing to read further")
        if held["entries"] > MAX_OPEN_SCALARS:
            raise RecordingError(f"{path}: frames still open hold over {MAX_OPEN_SCALARS} messages; refusing to "
                                 "read further")
        return taken


def read_mcap(path: str | Path) -> Recording:
    """Read a whole shadowflow MCAP recording into memory (``FrameStream`` reads one frame at a
    time). No pickle, no code: arrays are decoded only from the documented binary layout with a
    whitelist of dtypes and a size check; a record claiming more than 1 GiB is refused. A file
    cut short (killed run) yields what came before the cut, ``truncated=True``.
    """
    stream = FrameStream(path)
    frames: dict[int, FrameRecording] = {}
    for fr in stream:  # a frame id seen twice (a file redone in one run): the later one
        frames[fr.frame] = fr
    return Recording(Path(path), dict(sorted(frames.items())), stream.truncated)


def _nbytes(fr: FrameRecording) -> int:
    return sum(a.nbytes for by_it in fr.arrays.values() for a in by_it.values())


def _entries(fr: FrameRecording) -> int:
    """What a frame holds, counted as ``_take`` counts it: itself and each array and scalar entry."""
    return 1 + sum(len(by_it) for by_it in fr.arrays.values()) + sum(len(by_it) for by_it in fr.scalars.values())


def _put(held: dict, entries: dict, key, value) -> None:
    """``entries[key] = value``, counted in ``held["entries"]`` when the key is new."""
    held["entries"] += key not in entries
    entries[key] = value


def _opened_frame(frames: dict[int, FrameRecording], held: dict, fid: int) -> FrameRecording:
    if fid not in frames:
        frames[fid] = FrameRecording(fid)
        held["entries"] += 1
    return frames[fid]


def _frame_id(x) -> int:
    if not isinstance(x, int) or isinstance(x, bool) or not 0 <= x < 1 << 53:
        raise ValueError(f"frame must be a whole number >= 0, not {x!r}")
    return x


def _iteration(x) -> int | None:
    try:
        return None if x is None else _frame_id(x)
    except ValueError:
        raise ValueError(f"iteration must be a whole number >= 0 or null, not {x!r}") from None


def _scalars(x) -> dict:
    if not isinstance(x, dict):
        raise ValueError("values must be an object")
    for k, v in x.items():
        if v is not None and (not isinstance(v, (int, float)) or isinstance(v, bool)):
            raise ValueError(f"scalar {k!r} must be a number or null, not {v!r}")
    return dict(x)


def _take(frames: dict[int, FrameRecording], held: dict, topic: str, encoding: str, data: bytes,
          arrays: bool) -> tuple[int | None, bool]:
    """File one message under its frame; returns (its frame id, whether it is the frame's closing record)."""
    if topic.endswith("/foxglove"):
        return None, False  # a display copy of an array recorded exactly beside it
    path = topic.lstrip("/")
    if encoding == ARRAY_ENCODING:
        header, arr = decode_array(data, check_only=not arrays)
        fid, it = _frame_id(header.get("frame")), _iteration(header.get("iteration"))
        fr = _opened_frame(frames, held, fid)
        if arr is None:
            return fid, False
        _put(held, fr.arrays.setdefault(path, {}), it, arr)
        held["bytes"] += arr.nbytes
    elif encoding == "json":
        body = json.loads(data)
        if not isinstance(body, dict):
            raise ValueError("message is not a JSON object")
        fid = _frame_id(body.get("frame"))
        fr = _opened_frame(frames, held, fid)
        if path == "frames":
            if not isinstance(body.get("values"), dict):
                raise ValueError("a frame record's values must be an object")
            fr.record = dict(body["values"])
            return fid, True
        _put(held, fr.scalars.setdefault(path, {}), _iteration(body.get("iteration")), _scalars(body.get("values")))
    else:
        raise ValueError(f"unknown message encoding {encoding!r}")
    return fid, False
