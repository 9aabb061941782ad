"""A recording re-logged into a Rerun ``.rrd`` file, to look at in the viewer."""
from __future__ import annotations

from pathlib import Path
from typing import Collection, Iterable, Mapping

from ..recording import Event, FrameRecording, Kind, RerunSink


def relog_to_rerun(frames: Iterable[FrameRecording], rrd_path: str | Path, kinds: Mapping[str, Kind] | None = None,
                   blueprint=None, left_out: Collection[str] = ()) -> Path:
    """Write frames and their iterations (a ``Recording`` or a stream) into a Rerun ``.rrd`` file,
    one frame at a time. kinds: how to show an array by the last part of its path (e.g.
    ``{"depth": Kind.DEPTH}``); others are images when 2-D, arrays otherwise. left_out: path parts
    whose arrays are not re-logged (the pieces of something only the recording shows whole)."""
    kinds = kinds or {}
    left = {f"/{part}/" for part in left_out}
    sink = RerunSink(rrd_path, blueprint=blueprint)
    for fr in frames:
        _relog_frame(sink, fr, kinds, left)
    sink.close()
    return Path(rrd_path)


def _by_iteration(by_it: Mapping) -> list:
    """``{iteration: value}`` in iteration order, the frame's own value (iteration None) first."""
    return sorted(by_it.items(), key=lambda kv: -1 if kv[0] is None else kv[0])


def _relog_frame(sink: RerunSink, fr: FrameRecording, kinds: Mapping[str, Kind], left: set[str]) -> None:
    fid = fr.frame
    stem = (fr.record or {}).get("stem")
    if isinstance(stem, str) and stem:
        sink.name_frame(fid, stem)
    for path, by_it in fr.arrays.items():
        if any(part in f"/{path}" for part in left):
            continue
        name = path.rsplit("/", 1)[-1]
        for it, arr in _by_iteration(by_it):
            sink.write(Event(fid, path, kinds.get(name, Kind.IMAGE if arr.ndim == 2 else Kind.ARRAY), arr, it))
    for path, by_it in fr.scalars.items():
        for it, vals in _by_iteration(by_it):
            sink.write(Event(fid, path, Kind.SCALARS, vals, it))
    if fr.record is not None:
        sink.write(Event(fid, "frames", Kind.FRAME, fr.record))
    sink.frame_done(fid)
