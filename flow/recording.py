"""Recordings of a run: every iteration's arrays and scalars, to MCAP and Rerun files.

Nodes hand ``Event``s to a ``Recorder``; one writer thread takes them from a bounded queue and
passes them to each ``Sink`` (``McapSink``, ``RerunSink``), so encoding and compression stay
off the compute threads and Rerun's per-thread time cursor lives on a single thread. Times
are explicit on every event: timeline ``frame`` (the frame's position in the stream) and
timeline ``iteration`` (absent for once-per-frame products). The on-disk formats are
documented in ``recordings/README.md``. Knows nothing about faces.
"""
from __future__ import annotations

import base64
import json
import queue
import struct
import threading
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

ARRAY_MAGIC = b"SFA1"
ARRAY_ENCODING = "shadowflow.ndarray"
ARRAY_SCHEMA = "shadowflow.NDArray"
ALLOWED_DTYPES = {"<f2", "<f4", "<f8", "|u1", "<u2", "<u4", "<i4", "<i8", "|b1"}
MAX_ARRAY_BYTES = 1 << 30  # a message claiming more than 1 GiB is refused when reading


@dataclass(frozen=True)
class Event:
    """One recorded item.

    frame: stream position; path: ``node/name``; iteration: None for per-frame products;
    kind: "array" | "image" ([0, 1] grey) | "depth" | "normals" ((H, W, 3) unit) | "mesh"
    (dict of vertices (V, 3), triangles (T, 3), colours (V, 3) uint8) | "scalars" (dict
    name -> float) | "frame" (dict: source, status, meta; closes the frame). An array value
    may be an ``OnMask``: the sinks put it on its grid on the recorder's thread.
    """

    frame: int
    path: str
    kind: str
    value: Any
    iteration: int | None = None


@dataclass(frozen=True)
class OnMask:
    """An array known only at the True pixels of a grid mask, e.g. values over a face.

    values: (N, ...) in the mask's row-major order; mask: (H, W) bool with N True pixels.
    Emitting one costs the producer an (N, ...) array instead of an (H, W, ...) grid; the
    recorder's thread scatters it (``grid``) with whatever fill each sink wants.
    """

    values: np.ndarray
    mask: np.ndarray

    def grid(self, fill: float = np.nan) -> np.ndarray:
        """(H, W, ...) of the values' dtype, ``fill`` off the mask."""
        rest = self.values.shape[1:]
        out = np.full((self.mask.size, *rest), fill, dtype=self.values.dtype)
        out[np.flatnonzero(self.mask)] = self.values  # integer rows: 3x faster than a boolean mask for (N, 3)
        return out.reshape(self.mask.shape + rest)


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


def decode_array(data: bytes) -> tuple[dict, np.ndarray]:
    """Inverse of ``encode_array`` (a masked message comes back as the full array); raises
    ``ValueError`` on anything malformed."""
    if len(data) < 8 or data[:4] != ARRAY_MAGIC:
        raise ValueError("not a shadowflow array message")
    (hlen,) = struct.unpack("<I", data[4:8])
    if hlen > 4096 or 8 + hlen > len(data):
        raise ValueError("array header length out of range")
    header = json.loads(data[8:8 + hlen])
    dtype, shape, masked = header.get("dtype"), header.get("shape"), header.get("masked", False)
    if dtype not in ALLOWED_DTYPES or not isinstance(shape, list) or len(shape) > 8 \
            or not all(isinstance(d, int) and 0 <= d for d in shape) or masked not in (True, False) \
            or (masked and len(shape) < 2):
        raise ValueError(f"bad array header {header!r}")
    itemsize = np.dtype(dtype).itemsize
    full = int(np.prod(shape, dtype=np.int64)) * itemsize
    if full > MAX_ARRAY_BYTES:
        raise ValueError(f"array payload is {len(data) - 8 - hlen} bytes, header says {full}, over the "
                         f"{MAX_ARRAY_BYTES}-byte limit")
    payload = memoryview(data)[8 + hlen:]
    if not masked:
        if full != len(payload):
            raise ValueError(f"array payload is {len(payload)} bytes, header says {full}")
        return header, np.frombuffer(payload, dtype=dtype).reshape(shape).copy()
    pixels = shape[0] * shape[1]
    nbits = (pixels + 7) // 8
    if len(payload) < nbits:
        raise ValueError(f"masked array payload is {len(payload)} bytes, its mask alone needs {nbits}")
    mask = np.unpackbits(np.frombuffer(payload[:nbits], np.uint8), count=pixels).astype(bool).reshape(shape[:2])
    per_pixel = int(np.prod(shape[2:], dtype=np.int64))
    n = int(mask.sum()) * per_pixel * itemsize
    if n != len(payload) - nbits:
        raise ValueError(f"masked array values are {len(payload) - nbits} bytes, its mask says {n}")
    values = np.frombuffer(payload[nbits:], dtype=dtype).reshape((-1, *shape[2:]))
    fill = np.nan if np.dtype(dtype).kind == "f" else 0
    return header, OnMask(values, mask).grid(fill)


class Sink:
    """Writes events somewhere. ``write`` runs on the recorder's thread only."""

    def write(self, event: Event) -> None: ...

    def frame_done(self, frame: int) -> None: ...

    def close(self) -> None: ...


class McapSink(Sink):
    """MCAP file: exact arrays (``shadowflow.ndarray``), scalars and frame records as JSON,
    images also as ``foxglove.RawImage`` (mono8, JSON) so Foxglove shows them.

    Compressed chunks, lz4 by default: on float arrays it writes in about half the CPU time of
    mcap's zstd (level 3) for files about a quarter larger, and the recorder shares the machine
    with the fit. The chunk is closed and flushed after every frame, so a
    killed run leaves every finished frame readable.
    """

    def __init__(self, path: str | Path, compression: str = "lz4"):
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        self._file = open(self.path, "wb")
        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[compression]
        self._w = Writer(self._file, compression=comp, chunk_size=4 << 20)
        self._w.start(profile="", library="shadowflow")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._seq: dict[str, int] = {}

    def _schema(self, name: str) -> int:
        if name not in self._schemas:
            if name == ARRAY_SCHEMA:
                sid = self._w.register_schema(name, ARRAY_ENCODING, b"see recordings/README.md")
            else:
                sid = self._w.register_schema(name, "jsonschema", json.dumps(_JSON_SCHEMAS[name]).encode())
            self._schemas[name] = sid
        return self._schemas[name]

    def _channel(self, topic: str, schema: str, encoding: str) -> int:
        if topic not in self._channels:
            self._channels[topic] = self._w.register_channel(topic, encoding, self._schema(schema))
        return self._channels[topic]

    def _add(self, topic: str, schema: str, encoding: str, event: Event, data: bytes) -> None:
        ch = self._channel(topic, schema, encoding)
        seq = self._seq.get(topic, 0)
        self._seq[topic] = seq + 1
        t = log_time_ns(event.frame, event.iteration)
        self._w.add_message(ch, log_time=t, data=data, publish_time=t, sequence=seq)

    def write(self, event: Event) -> None:
        topic = "/" + event.path
        if event.kind in ("scalars", "frame"):
            body = {"frame": event.frame, "iteration": event.iteration, "values": event.value}
            schema = "shadowflow.Scalars" if event.kind == "scalars" else "shadowflow.Frame"
            self._add(topic, schema, "json", event, json.dumps(body, default=_jsonable).encode())
            return
        if event.kind == "mesh":
            for key, arr in event.value.items():
                self._add(f"{topic}/{key}", ARRAY_SCHEMA, ARRAY_ENCODING, event,
                          encode_array(event.frame, event.iteration, arr))
            return
        v = event.value
        if isinstance(v, OnMask):  # face pixels and a 2 KiB bit mask instead of a NaN-padded grid
            data = encode_array(event.frame, event.iteration, v.values, v.mask)
        else:
            data = encode_array(event.frame, event.iteration, np.asarray(v))
        self._add(topic, ARRAY_SCHEMA, ARRAY_ENCODING, event, data)
        if event.kind == "image":
            img8 = (_display(v).clip(0, 1) * 255 + 0.5).astype(np.uint8)
            t = log_time_ns(event.frame, event.iteration)
            msg = {"timestamp": {"sec": t // 1_000_000_000, "nsec": t % 1_000_000_000}, "frame_id": "camera",
                   "width": int(img8.shape[1]), "height": int(img8.shape[0]), "encoding": "mono8",
                   "step": int(img8.shape[1])}
            # base64 needs no JSON escaping: splice it in rather than have json scan 20 KB of it
            body = json.dumps(msg).encode()[:-1] + b', "data": "' + base64.b64encode(img8.tobytes()) + b'"}'
            self._add(topic + "/foxglove", "foxglove.RawImage", "json", event, body)

    def frame_done(self, frame: int) -> None:
        self._w.flush()

    def close(self) -> None:
        self._w.finish()
        self._file.close()


class RerunSink(Sink):
    """Rerun ``.rrd`` file with timelines ``frame`` and ``iteration``, entities
    ``frames/<frame>/<node>/<name>``, and a default blueprint (images side by side and the
    convergence plots), streamed to disk as it goes.

    Per-iteration images, vectors and scalars are held per entity until the frame ends (or
    ``batch`` iterations are waiting) and sent in one ``send_columns`` call: Rerun's cost is
    per call (about 0.3 ms to turn one array into Arrow, whatever its size), and a frame
    makes dozens of them. The file holds the same rows, times and values as one ``log`` per
    iteration would write; a frame's rows reach the file when the frame is flushed, as before.
    """

    def __init__(self, path: str | Path, blueprint=None, application_id: str = "shadowflow",
                 batch: int = 32):
        import rerun as rr

        self.rr = rr
        self.path = Path(path)
        self.batch = batch
        self.rec = rr.RecordingStream(application_id)
        self.rec.save(str(self.path), default_blueprint=blueprint)
        self._pending: dict[tuple[int, str], list[Event]] = {}

    def write(self, event: Event) -> None:
        if event.iteration is not None and self._columnar(event):
            rows = self._pending.setdefault((event.frame, event.path), [])
            rows.append(event)
            if len(rows) >= self.batch:
                self._send(event.frame, event.path)
            return
        self._log(event)

    @staticmethod
    def _columnar(event: Event) -> bool:
        """Per-iteration kinds that are batched: scalars, vectors and 2-D/3-D images."""
        if event.kind in ("scalars", "normals", "image"):
            return True
        return event.kind == "array" and _ndim(event.value) in (1, 2)

    def _log(self, event: Event) -> None:
        rr, rec = self.rr, self.rec
        rec.set_time("frame", sequence=event.frame)
        if event.iteration is None:
            rec.disable_timeline("iteration")
        else:
            rec.set_time("iteration", sequence=event.iteration)
        entity = _entity(event)
        v = event.value
        if event.kind == "scalars":
            for name, x in v.items():
                if _is_number(x):
                    rec.log(f"{entity}/{name}", rr.Scalars(float(x)))
        elif event.kind == "frame":
            rec.log(f"frames/{event.frame:05d}/status", rr.TextLog(json.dumps(v, default=_jsonable)))
        elif event.kind == "depth":
            rec.log(entity, rr.DepthImage(_display(v)))
        elif event.kind == "mesh":
            rec.log(entity, rr.Mesh3D(vertex_positions=v["vertices"], triangle_indices=v["triangles"],
                                      vertex_colors=v["colours"]))
        elif event.kind == "normals":
            rec.log(entity, rr.Image(_display(v, "normals")))
        else:
            a = _display(v)
            if a.ndim == 2:  # "image", and 2-D "array"s
                rec.log(entity, rr.Image(a))
            elif a.ndim == 1:  # a vector (the fit's coefficients): one plotted series per entry,
                rec.log(entity, rr.Scalars(a.astype(np.float64)))  # 40x cheaper to log than a Tensor
            else:
                rec.log(entity, rr.Tensor(a))

    def _send(self, frame: int, path: str) -> None:
        """One ``send_columns`` per entity for the held iterations of ``path`` in ``frame``."""
        rr, rows = self.rr, self._pending.pop((frame, path))
        entity = _entity(rows[0])

        def index(rs: list[Event]) -> list:
            return [rr.TimeColumn("frame", sequence=[frame] * len(rs)),
                    rr.TimeColumn("iteration", sequence=[e.iteration for e in rs])]

        if rows[0].kind == "scalars":
            names = dict.fromkeys(n for e in rows for n, x in e.value.items() if _is_number(x))
            for name in names:
                rs = [e for e in rows if _is_number(e.value.get(name))]
                self.rec.send_columns(f"{entity}/{name}", indexes=index(rs),
                                      columns=rr.Scalars.columns(scalars=[float(e.value[name]) for e in rs]))
            return
        if _ndim(rows[0].value) == 1:
            shown = [_display(e.value) for e in rows]
            if any(a.ndim != 1 for a in shown):
                raise ValueError(f"{entity}: iterations mix vectors and images")
            columns = rr.Scalars.columns(scalars=np.concatenate(shown).astype(np.float64))
            self.rec.send_columns(entity, indexes=index(rows), columns=columns.partition([a.size for a in shown]))
            return
        images = _display_stack(rows)
        n, h, w = images.shape[:3]
        fmt = rr.components.ImageFormat(width=w, height=h, color_model="RGB" if images.ndim == 4 else "L",
                                        channel_datatype="U8" if images.dtype == np.uint8 else "F32")
        self.rec.send_columns(entity, indexes=index(rows),
                              columns=rr.Image.columns(buffer=images.reshape(n, -1).view(np.uint8), format=[fmt] * n))

    def _send_frame(self, frame: int | None) -> None:
        for f, path in [k for k in self._pending if frame is None or k[0] == frame]:
            self._send(f, path)

    def frame_done(self, frame: int) -> None:
        self._send_frame(frame)
        self.rec.flush()

    def close(self) -> None:
        self._send_frame(None)
        self.rec.flush()
        self.rec.disconnect()


def _entity(event: Event) -> str:
    return f"frames/{event.frame:05d}/{event.path}"


def _ndim(value: Any) -> int:
    if isinstance(value, OnMask):
        return value.mask.ndim + value.values.ndim - 1
    return np.ndim(value)


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.floating, np.integer)) and not isinstance(x, bool)


def _finite32(a: Any) -> np.ndarray:
    """A float32 copy with NaN and inf set to 0 (one pass; ``nan_to_num`` makes four)."""
    out = np.array(a, np.float32)
    bad = ~np.isfinite(out)
    if bad.any():
        out[bad] = 0
    return out


def _display_rule(kind: str):
    """How Rerun shows an event kind: (conversion of values, fill off the mask). Normals as RGB
    uint8 ``(n + 1) * 127.5`` with 127 off the face; everything else float32 with 0 there
    (Rerun shows NaN as garbage)."""
    return (_normals_rgb, 127) if kind == "normals" else (_finite32, 0)


def _display(value: Any, kind: str = "image") -> np.ndarray:
    """One event value as Rerun shows it (see ``_display_rule``)."""
    convert, fill = _display_rule(kind)
    if isinstance(value, OnMask):
        return OnMask(convert(value.values), value.mask).grid(fill)
    return convert(value)


def _display_stack(rows: list[Event]) -> np.ndarray:
    """(n, H, W) float32 or (n, H, W, 3) uint8: the rows' display images, stacked. Rows on one
    mask are converted and scattered in one pass (one indexed assignment for the whole batch)."""
    first, kind = rows[0].value, rows[0].kind
    if isinstance(first, OnMask) and all(isinstance(e.value, OnMask) and e.kind == kind
                                         and e.value.mask is first.mask for e in rows):
        convert, fill = _display_rule(kind)
        shown = convert(np.stack([e.value.values for e in rows]))
        out = np.full((len(rows), first.mask.size, *shown.shape[2:]), fill, shown.dtype)
        out[:, np.flatnonzero(first.mask)] = shown
        return out.reshape((len(rows), *first.mask.shape, *shown.shape[2:]))
    shown = [_display(e.value, e.kind) for e in rows]
    if any(a.shape != shown[0].shape or a.dtype != shown[0].dtype for a in shown):
        raise ValueError(f"{_entity(rows[0])}: iterations of different image sizes")
    return np.stack(shown)


def _normals_rgb(n: Any) -> np.ndarray:
    rgb = _finite32(n)
    rgb += 1
    rgb *= 127.5
    return rgb.clip(0, 255, out=rgb).astype(np.uint8)


@dataclass
class RecordOptions:
    """every: keep iterations 1, 1 + every, ... and the last; float16: store float arrays as
    float16 (half the bytes, about 3 significant digits)."""

    every: int = 1
    float16: bool = False


class Recorder:
    """Collects events from any thread and writes them on its own thread.

    ``emit`` blocks when ``max_pending`` events are waiting (backpressure instead of
    unbounded memory). Errors in a sink are kept and raised by ``close``.
    """

    def __init__(self, sinks: list[Sink], options: RecordOptions | None = None, max_pending: int = 256):
        self.sinks = sinks
        self.options = options or RecordOptions()
        self._q: queue.Queue = queue.Queue(maxsize=max_pending)
        self._error: BaseException | None = None
        self._closed_frames = 0  # frames flushed by every sink (or dropped after an error)
        self._asked = 0  # frames handed to frame_done
        self._flushed = threading.Condition()
        self._thread = threading.Thread(target=self._loop, name="flow-recorder", daemon=True)
        self._thread.start()

    @property
    def error(self) -> BaseException | None:
        """The first error a sink raised (recording stopped there), or None."""
        return self._error

    def keep_iteration(self, iteration: int, last: bool = False) -> bool:
        return last or self.options.every <= 1 or (iteration - 1) % self.options.every == 0

    def emit(self, event: Event) -> None:
        if self.options.float16 and event.kind in ("array", "image", "depth", "normals"):
            v = event.value
            a = v.values if isinstance(v, OnMask) else np.asarray(v)
            if a.dtype.kind == "f":
                half = a.astype(np.float16)
                event = replace(event, value=OnMask(half, v.mask) if isinstance(v, OnMask) else half)
        self._q.put(("event", event))

    def frame_done(self, frame: int, record: dict, wait: bool = False) -> None:
        """Close a frame: its status record, then every sink flushes it to disk. ``wait``:
        return only once that is done (so a caller can then mark the frame finished)."""
        self._q.put(("event", Event(frame, "frames", "frame", record)))
        self._q.put(("done", frame))
        self._asked += 1
        if wait:
            target = self._asked
            with self._flushed:
                self._flushed.wait_for(lambda: self._closed_frames >= target or not self._thread.is_alive())

    def _loop(self) -> None:
        while True:
            kind, item = self._q.get()
            if kind == "stop":
                return
            if self._error is None:  # after an error nothing more is written; close() reports it
                try:
                    for s in self.sinks:
                        s.write(item) if kind == "event" else s.frame_done(item)
                except BaseException as exc:  # noqa: BLE001 - reported by close()
                    self._error = exc
            if kind == "done":
                with self._flushed:
                    self._closed_frames += 1
                    self._flushed.notify_all()

    def close(self) -> None:
        self._q.put(("stop", None))
        self._thread.join()
        for s in self.sinks:
            try:
                s.close()
            except BaseException as exc:  # noqa: BLE001
                self._error = self._error or exc
        if self._error is not None:
            raise RuntimeError(f"recording failed: {self._error}") from self._error


def _jsonable(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


_JSON_SCHEMAS: dict[str, dict] = {
    "shadowflow.Scalars": {"type": "object", "properties": {
        "frame": {"type": "integer"}, "iteration": {"type": ["integer", "null"]},
        "values": {"type": "object", "additionalProperties": {"type": "number"}}}},
    "shadowflow.Frame": {"type": "object", "properties": {
        "frame": {"type": "integer"}, "values": {"type": "object"}}},
    "foxglove.RawImage": {"type": "object", "properties": {
        "timestamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
        "frame_id": {"type": "string"}, "width": {"type": "integer"}, "height": {"type": "integer"},
        "encoding": {"type": "string"}, "step": {"type": "integer"},
        "data": {"type": "string", "contentEncoding": "base64"}}},
}


# ---------------------------------------------------------------------------------------------
# Reading


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
