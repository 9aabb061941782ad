"""``RerunSink``: recordings as Rerun ``.rrd`` files, and how each event kind is displayed."""
from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..jsonsafe import jsonable
from .events import Event, Kind, OnMask, Sink, value_nbytes


class RerunSink(Sink):
    """Rerun ``.rrd`` file with timelines ``frame`` and ``iteration``, entities
    ``<node>/<name>/<frame>`` (``<frame>`` the frame's name as ``name_frame`` gave it, e.g. the
    input's stem; else its id as ``00042``; a frame's record is ``status/<frame>``): the channel
    first, so one view gathers a channel of every frame with ``/<node>/<name>/**`` (a viewer's
    path filters take a wildcard at the end only), and a default blueprint (images side by side and the
    convergence plots), streamed to disk as it goes; after every ``segment_frames`` frames it goes
    on in a new file of the same recording (``run.s2.rrd``, ... see ``_next_segment``), opened when
    the next frame's first event comes. ``previous_paths``: the files an earlier sink of this
    recording wrote (``recording_id`` the same; e.g. in a process since renewed, see
    ``ProcessSinks``): this one goes on in the next segment after them. Per-iteration images, vectors
    and scalars are held (``HeldRows``: ``batch``, ``max_held_bytes``) and sent a batch at a time.
    """

    def __init__(self, path: str | Path, blueprint=None, application_id: str = "shadowflow",
                 batch: int = 32, segment_frames: int | None = 100, recording_id: str | None = None,
                 previous_paths: list[str] | None = None, max_held_bytes: int = 24 << 20):
        import uuid

        import rerun as rr

        self.rr = rr
        self.path = Path(path)
        self.blueprint, self.application_id = blueprint, application_id
        self.recording_id = recording_id or str(uuid.uuid4())  # files of one id: one recording in the viewer
        self.segment_frames = segment_frames
        self.paths: list[Path] = [Path(p) for p in previous_paths or []]  # the files written: path, then its segments
        self._frames_in_segment = 0
        self._held = HeldRows(batch, max_held_bytes)
        self._names: dict[int, str] = {}  # frame id -> its entity path part, until the frame is done
        self.rec = None
        if not self.paths:  # else the next segment opens with the first event, as after a full one
            self._open(self.path)

    def _open(self, path: Path) -> None:
        if path.is_symlink():
            raise OSError(f"{path}: is a symbolic link; refusing to write through it")
        self.rec = self.rr.RecordingStream(self.application_id, recording_id=self.recording_id)
        self.rec.save(str(path), default_blueprint=self.blueprint)
        self.paths.append(path)

    def _next_segment(self) -> None:
        """Close this file and go on in ``<stem>.s<k><suffix>``, one recording (same id) across files.

        A stream saving to a file keeps an index entry for every chunk it has written (the .rrd
        footer's manifest, written when the file closes): a few kB a chunk, 25 chunks or more a
        frame here, so about 75-130 kB a frame (290 -> 460 MiB over 2,000 frames in one file). A
        new file every ``segment_frames`` frames bounds that: RSS then saws by about 10 MiB at 100
        frames a file instead of climbing (``benchmarks/bench_soak.py``). The viewer merges the
        files of one recording id: ``rerun OUT/run*.rrd``."""
        if self.rec is not None:
            self._drop_stream()
        k = len(self.paths) + 1
        self._open(self.path.with_name(f"{self.path.stem}.s{k}{self.path.suffix}"))
        self._frames_in_segment = 0

    def name_frame(self, frame: int, name: str) -> None:
        self._names[frame] = self.rr.escape_entity_path_part(name)

    def _entity(self, path: str, frame: int) -> str:
        """The entity of channel ``path`` in ``frame``."""
        return f"{path}/{self._names.get(frame) or f'{frame:05d}'}"

    @property
    def held_bytes(self) -> int:
        """Bytes of the rows held, over all frames."""
        return self._held.nbytes

    def write(self, event: Event) -> None:
        if self.rec is None:  # the last segment is full
            self._next_segment()
        if event.iteration is not None and _columnar(event):
            if self._held.hold(event):
                self._send(event.frame, event.path)
            while (largest := self._held.over_bound()) is not None:
                self._send(*largest)
            return
        self._log(event)

    def _log(self, event: Event) -> None:
        rr, rec = self.rr, self.rec
        rec.set_time("frame", sequence=event.frame)
        if event.iteration is None:
            rec.disable_timeline("iteration")
        else:
            rec.set_time("iteration", sequence=event.iteration)
        entity = self._entity(event.path, event.frame)
        v = event.value
        if event.kind is Kind.SCALARS:
            for name, x in v.items():
                if _is_number(x):
                    rec.log(self._entity(f"{event.path}/{name}", event.frame), rr.Scalars(float(x)))
        elif event.kind is Kind.FRAME:
            if event.frame not in self._names and isinstance(v, dict) and isinstance(v.get("stem"), str):
                self.name_frame(event.frame, v["stem"])  # a frame that failed before recording anything
            rec.log(self._entity("status", event.frame), rr.TextLog(json.dumps(v, default=jsonable)))
        else:
            rec.log(entity, _archetype(rr, event.kind, v))

    def _send(self, frame: int, path: str) -> None:
        """One ``send_columns`` per entity for the held iterations of ``path`` in ``frame``."""
        rr, rows = self.rr, self._held.take(frame, path)
        entity = self._entity(path, frame)
        if rows[0].kind is Kind.SCALARS:
            for name, rs in _scalar_series(rows):
                self.rec.send_columns(self._entity(f"{path}/{name}", frame), indexes=_iteration_index(rr, frame, rs),
                                      columns=rr.Scalars.columns(scalars=[float(e.value[name]) for e in rs]))
            return
        if _ndim(rows[0].value) == 1:  # a vector per iteration: the bar chart of the latest one held
            # (normally the frame's last). The SDK sends no batch of tensors in one call, and one log
            # call per iteration made a 128x128 recorded run 2.55x the unrecorded one instead of 1.77x;
            # every iteration's vector stays in the MCAP (``replay``, ``diff``)
            iteration, a = _latest_vector(rows, entity)
            self.rec.set_time("frame", sequence=frame)
            self.rec.set_time("iteration", sequence=iteration)
            self.rec.log(entity, rr.BarChart(a))
            return
        self.rec.send_columns(entity, indexes=_iteration_index(rr, frame, rows), columns=_image_columns(rr, rows))

    def _send_frame(self, frame: int | None) -> None:
        for f, path in self._held.batches(frame):
            self._send(f, path)

    def frame_done(self, frame: int) -> None:
        if self.rec is None:  # a frame that recorded nothing, after a full segment
            self._next_segment()
        self._send_frame(frame)
        self._names.pop(frame, None)
        self.rec.flush()
        self._frames_in_segment += 1
        if self.segment_frames and self._frames_in_segment >= self.segment_frames:
            self._drop_stream()  # the next segment opens with the next frame's first event

    def close(self) -> None:
        if self.rec is not None:
            self._send_frame(None)
            self._drop_stream()

    def _drop_stream(self) -> None:
        """Flush and close the file, and let the stream's threads end: a dropped stream is kept
        "orphaned" (with its batcher and writer threads, about 0.5 MB) until the SDK is told to
        clean those up, which ``rr.init`` does and a ``RecordingStream`` alone never does."""
        self.rec.flush()
        self.rec.disconnect()
        self.rec = None
        cleanup = getattr(self.rr.bindings, "flush_and_cleanup_orphaned_recordings", None)
        if cleanup is not None:
            cleanup()


class HeldRows:
    """Per-iteration rows held per entity (frame, channel) until the frame ends (or ``batch`` iterations are
    waiting), for ``RerunSink`` to send in one ``send_columns`` call: Rerun's cost is per call (about 0.3 ms
    to turn one array into Arrow, whatever its size), and a frame makes dozens of them. The file holds the
    same rows, times and values as one ``log`` per iteration would write; a frame's rows reach the file
    when the frame is flushed, as before. ``max_bytes``: the rows held, over all frames, are at most about
    this many bytes; past it the largest held batch is sent at once. A run's pipeline has several frames in
    its fit at a time, each with per-iteration images held here until it ends: without the bound the held
    rows ranged from 1 to 100 MiB with how many frames the pipeline's timing kept in flight (the recording
    process's RSS 130-300 MiB in a soak, ``benchmarks/bench_soak.py``)."""

    def __init__(self, batch: int, max_bytes: int):
        self.batch, self.max_bytes = batch, max_bytes
        self._rows: dict[tuple[int, str], list[Event]] = {}
        self._bytes: dict[tuple[int, str], int] = {}  # of each held batch's values
        self.nbytes = 0  # of all of them

    def hold(self, event: Event) -> bool:
        """Hold ``event``'s row; True when its batch is full (to be sent now)."""
        rows = self._rows.setdefault((event.frame, event.path), [])
        rows.append(event)
        key, size = (event.frame, event.path), value_nbytes(event.value)
        self._bytes[key] = self._bytes.get(key, 0) + size
        self.nbytes += size
        return len(rows) >= self.batch

    def over_bound(self) -> tuple[int, str] | None:
        """(frame, path) of the largest held batch while the rows held are over ``max_bytes``; else None."""
        return max(self._bytes, key=self._bytes.__getitem__) if self.nbytes > self.max_bytes else None

    def take(self, frame: int, path: str) -> list[Event]:
        """The held rows of ``path`` in ``frame``, no longer held."""
        rows = self._rows.pop((frame, path))
        self.nbytes -= self._bytes.pop((frame, path))
        return rows

    def batches(self, frame: int | None) -> list[tuple[int, str]]:
        """(frame, path) of every batch held for ``frame`` (None: for every frame)."""
        return [k for k in self._rows if frame is None or k[0] == frame]


def _columnar(event: Event) -> bool:
    """Per-iteration kinds that are batched: scalars, vectors and 2-D/3-D images."""
    if event.kind in (Kind.SCALARS, Kind.NORMALS, Kind.IMAGE):
        return True
    return event.kind is Kind.ARRAY and _ndim(event.value) in (1, 2)


def _archetype(rr, kind: Kind, v: Any):
    """The Rerun archetype of a value logged alone (a depth map, a mesh, normals, an image or array)."""
    if kind is Kind.DEPTH:
        return rr.DepthImage(display(v, Kind.DEPTH))
    if kind is Kind.MESH:
        return rr.Mesh3D(vertex_positions=v["vertices"], triangle_indices=v["triangles"], vertex_colors=v["colours"])
    if kind is Kind.NORMALS:
        return rr.Image(display(v, Kind.NORMALS))
    return _shown(rr, display(v, kind), kind)


def _shown(rr, a: np.ndarray, kind: Kind):
    """The Rerun archetype of an image or array: an image (grey, RGB, and 2-D arrays), a bar chart
    (a vector, the fit's coefficients) or a tensor."""
    if a.ndim == 2 or (kind is Kind.IMAGE and a.ndim == 3 and a.shape[2] == 3):
        return rr.Image(a)
    return rr.BarChart(a) if a.ndim == 1 else rr.Tensor(a)


def _iteration_index(rr, frame: int, rs: list[Event]) -> list:
    """The time columns of rows of ``frame``: its number and each row's iteration."""
    return [rr.TimeColumn("frame", sequence=[frame] * len(rs)),
            rr.TimeColumn("iteration", sequence=[e.iteration for e in rs])]


def _scalar_series(rows: list[Event]) -> Iterator[tuple[str, list[Event]]]:
    """(name, the rows where it is a number) of every scalar the rows of one channel hold, in their order."""
    names = dict.fromkeys(n for e in rows for n, x in e.value.items() if _is_number(x))
    for name in names:
        yield name, [e for e in rows if _is_number(e.value.get(name))]


def _latest_vector(rows: list[Event], entity: str) -> tuple[int, np.ndarray]:
    """(iteration, vector as displayed) of the last of rows of vectors; ``ValueError`` when it is no vector."""
    e = rows[-1]
    a = display(e.value, e.kind)
    if a.ndim != 1:
        raise ValueError(f"{entity}: iterations mix vectors and images")
    return e.iteration, a


def _image_columns(rr, rows: list[Event]):
    """The ``rr.Image`` columns of rows of images of one size: their display images in one buffer."""
    images = display_stack(rows)
    n, h, w = images.shape[:3]
    fmt = rr.components.ImageFormat(width=w, height=h, color_model="RGB" if images.ndim == 4 else "L",
                                    channel_datatype="U8" if images.dtype == np.uint8 else "F32")
    return rr.Image.columns(buffer=images.reshape(n, -1).view(np.uint8), format=[fmt] * n)


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


def _display_rule(kind: Kind):
    """How Rerun shows an event kind: (conversion of values, fill off the mask). Normals as RGB
    uint8 ``(n + 1) * 127.5`` with 127 off the mask; images float32 clipped to their [0, 1] range
    (one bright outlier, e.g. an albedo over a specular spot, would otherwise set the viewer's
    range and show the face black); everything else float32; 0 off the mask (Rerun shows NaN as
    garbage)."""
    if kind is Kind.NORMALS:
        return _normals_rgb, 127
    return (_unit32 if kind is Kind.IMAGE else _finite32), 0


def display(value: Any, kind: Kind = Kind.IMAGE) -> np.ndarray:
    """One event value as Rerun shows it (see ``_display_rule``)."""
    convert, fill = _display_rule(kind)
    if isinstance(value, OnMask):
        return OnMask(convert(value.values), value.mask).grid(fill)
    return convert(value)


def display_stack(rows: list[Event]) -> np.ndarray:
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
    shown = [display(e.value, e.kind) for e in rows]
    if any(a.shape != shown[0].shape or a.dtype != shown[0].dtype for a in shown):
        raise ValueError(f"{rows[0].path} of frame {rows[0].frame}: iterations of different image sizes")
    return np.stack(shown)


def _normals_rgb(n: Any) -> np.ndarray:
    rgb = _finite32(n)
    rgb += 1
    rgb *= 127.5
    return rgb.clip(0, 255, out=rgb).astype(np.uint8)


def _unit32(a: Any) -> np.ndarray:
    """``_finite32`` clipped to [0, 1]: an image as a viewer shows it."""
    return np.clip(_finite32(a), 0.0, 1.0)
