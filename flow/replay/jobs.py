"""A job's recordings read back: one file, or the parts of a resumed or distributed job, as one stream of
frames in id order (``open_frames``), or whole in memory (``open_recording``)."""
from __future__ import annotations

import heapq
import re
from pathlib import Path
from typing import Iterator

from ..manifest import recording_parts
from ..recording import FrameRecording, FrameStream, Recording, RecordingError


def _part_number(path: Path) -> int:
    m = re.search(r"\.part(\d+)$", path.stem)
    return int(m.group(1)) if m else 1


class JobStream:
    """The frames of one job's recording, streamed (``FrameStream``), in frame id order: one file,
    or several parts, those of an interrupted and resumed job (``run.part2.mcap``...) and those
    the workers of a distributed run wrote side by side (``run.<worker>.mcap``). A frame finished
    in a later part replaces any earlier copy (a frame cut short by a kill, or redone because its
    input or the options changed, is recorded again by the resumed run); an unfinished frame is
    kept only if no part finished it. With several parts a first pass reads only their records
    to decide this, and the second merges the parts by frame id, so memory holds one frame per
    part. ``truncated`` (after iterating): the last part ended early, or, with several parts, a
    frame was left unfinished in all of them by a part that ended early."""

    def __init__(self, path: Path, parts: list[Path], arrays: bool = True):
        self.path, self.parts, self.arrays, self.truncated = path, parts, arrays, False

    def __iter__(self) -> Iterator[FrameRecording]:
        if len(self.parts) == 1:
            stream = FrameStream(self.parts[0], self.arrays)
            yield from stream
            self.truncated = stream.truncated
            return
        owner: dict[int, tuple[int, bool]] = {}  # frame id -> (part, finished there)
        cut: set[int] = set()  # parts that ended early
        for k, part in enumerate(self.parts):
            stream = FrameStream(part, arrays=False, part=True)
            for fr in stream:
                if fr.finished or fr.frame not in owner or not owner[fr.frame][1]:
                    owner[fr.frame] = (k, fr.finished)
            if stream.truncated:
                cut.add(k)
        self.truncated = any(k in cut and not done for k, done in owner.values())

        def part_frames(k: int) -> Iterator[tuple[int, int, int, FrameRecording]]:
            for n, fr in enumerate(FrameStream(self.parts[k], self.arrays, part=True)):
                if owner.get(fr.frame, (k,))[0] == k:
                    yield fr.frame, k, n, fr

        for *_, fr in heapq.merge(*(part_frames(k) for k in range(len(self.parts)))):
            yield fr


def open_frames(path: str | Path, arrays: bool = True) -> JobStream:
    """The frames of an MCAP recording (``.mcap``) as a stream, for walking frame -> iteration ->
    arrays; ``arrays=False`` skips the arrays (tables, plots).

    A folder opens the recordings of the job in it, in order (``run.mcap``, then the
    ``run.part2.mcap``... a resumed run adds): the parts its ``manifest.json`` names, so a stray
    or older ``.mcap`` beside them is never merged in (every ``*.mcap`` of the folder when it
    has no manifest). ``.rrd`` files hold display forms (images, plots), not the exact arrays:
    ``run.rrd`` opens the MCAP twin written beside it.
    """
    path = Path(path)
    if path.is_dir():
        files = recording_parts(path, "mcap")
        if files is None:
            files = sorted(path.glob("*.mcap"), key=lambda p: (_part_number(p), p.name))
        if not files:
            raise RecordingError(f"{path}: no .mcap recording in this folder")
        return JobStream(path, files, arrays)
    if path.suffix.lower() == ".rrd":
        twin = path.with_suffix(".mcap")
        if not twin.is_file():
            raise RecordingError(f"{path}: tables and diffs read the exact MCAP recording, and there is no "
                                 f"{twin.name} beside it (record with --record mcap)")
        path = twin
    return JobStream(path, [path], arrays)


def open_recording(path: str | Path) -> Recording:
    """The whole of ``open_frames(path)`` in memory, by frame id."""
    stream = open_frames(path)
    frames = {fr.frame: fr for fr in stream}
    return Recording(Path(path), dict(sorted(frames.items())), stream.truncated)
