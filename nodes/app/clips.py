"""Clips in a run: a clip's frames made one at a time as the run's frames (``clip_frames``: decoded as the engine
takes them, never the whole clip), each through the photo's chain; their relit frames made on the engine's threads
(``ClipNode``); and, in input order on the run's thread, encoded into ``OUT/<stem>/relit.mp4`` (and one
``relit_A<az>E<el>.mp4`` per ``--relight`` light), each frame's line written to ``frames.jsonl`` and the clip's
one record kept when its last frame is done (``ClipSink``). A frame without a face, or one that failed, is written
as the input has it: the relit clip keeps the input's frame count."""
from __future__ import annotations

import json
import os
from collections import Counter
from pathlib import Path
from typing import Callable, Iterator

import cv2
import numpy as np

from ...flow.frame import Frame
from ...flow.jsonsafe import json_safe
from ..relight.products import relit_lights, relit_photo_8bit
from .clip_io import ClipEncoder, ClipInfo, ClipReader, ClipFrame
from .counts import status_lines
from .outputs import CLIP_FILES, face_record, face_status, relit_name
from .storage import cannot_write


def clip_relit_name(light) -> str:
    """The clip relit by a ``--relight`` light: ``relit_A<az>E<el>.mp4``, as the stills' ``relit_<tag>.png``."""
    return relit_name(light, ".mp4")


def clip_complete(folder: Path, extra_lights) -> bool:
    """Whether a clip's folder holds its relit clips and ``frames.jsonl`` (each renamed into place when whole)."""
    names = (*CLIP_FILES, *(clip_relit_name(light) for light in extra_lights))
    return all((folder / n).is_file() for n in names)


def clip_frames(head: Frame, next_id: Callable[[], int], files: bool) -> Iterator[Frame]:
    """The frames of the clip whose input frame is ``head`` (its stem, key and identity named by the run's intake):
    ``head`` failed with one line when it cannot be opened; else one frame per decoded frame (ids from ``next_id``,
    ``head.id`` first), then a skipped end frame that closes the clip (``ClipSink``). ``files``: ``--frames``, each
    frame's files written too, in ``OUT/<stem>/frames/<index>/``."""
    try:
        reader = ClipReader(head.source)
    except Exception as exc:  # noqa: BLE001 - av.FFmpegError and kin, a missing file: the clip fails alone
        why = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        head.fail("load", f"{head.source}: cannot read as a clip ({why})")
        yield head
        return
    stem, fid = head.meta["stem"], head.id
    try:
        for cf in reader:
            yield _frame(head, cf, reader.info, fid, files)
            fid = next_id()
    finally:
        reader.close()
    end = Frame(fid, head.source, meta={**head.meta, "clip_end": True}, skipped=True)
    end.meta["clip"] = {"stem": stem, "info": reader.info.as_meta(), "source": head.source, "end": True}
    yield end


def _frame(head: Frame, cf: ClipFrame, info: ClipInfo, fid: int, files: bool) -> Frame:
    stem = head.meta["stem"]
    frame = Frame(fid, f"{head.source} frame {cf.index}")
    frame.meta["stem"] = f"{stem}/frames/{cf.index:06d}" if files else stem
    frame.meta["clip"] = {"stem": stem, "index": cf.index, "time": round(cf.time, 6), "pts": cf.pts,
                          "info": info.as_meta(), "source": head.source, "files": files}
    if cf.rgb is None:
        frame.fail("load", f"{frame.source}: unreadable frame ({cf.error})")
    else:
        frame.data["samples"] = cf.rgb
        frame.data["clip_rgb"] = cf.rgb
    return frame


class ClipNode:
    """A clip's frame relit by each light of the run (``relit_photo_8bit``), as the relit clips take them:
    ``data["clip_relit"]``, (H, W, 3) uint8 RGB each. Photos pass untouched."""

    name = "clip"
    thread_safe = True

    def __call__(self, frame: Frame) -> Frame:
        if frame.meta.get("clip"):
            frame.data["clip_relit"] = [_rgb(relit_photo_8bit(frame, i)) for i in range(len(relit_lights(frame)))]
        return frame


def _rgb(image: np.ndarray) -> np.ndarray:
    return np.repeat(image.reshape(*image.shape[:2], 1), 3, axis=2) if image.ndim == 2 or image.shape[2] == 1 \
        else image


def frame_line(frame: Frame) -> dict:
    """A clip frame's line of ``frames.jsonl``: index, time (s), status, and its faces as ``summary.json`` lists a
    photo's (``face_record``: box, eyes, pose, status, light), each with the light estimated on that frame alone
    (``light_raw``) when the clip's running light replaced it, how its yaw was read (``yaw_read``: by the fit on
    this frame, or carried from the last frame that read it), ``light_changed`` true on a frame whose photo
    showed its light changed (``relight.temporal.light_shown_changed``: relit as alone, its light taken at once), and
    ``light_alone`` true on a frame relit alone under its own estimate, which left the running light as the frame
    before's did (``app.steady.LightSmoother``)."""
    clip = frame.meta["clip"]
    faces = []
    for part in frame.parts:
        rec = face_record(frame, part, None)
        for key in ("light_raw", "yaw_read"):
            if key in part.meta:
                rec[key] = part.meta[key]
        for key in ("light_changed", "light_alone"):
            if part.meta.get(key):
                rec[key] = True
        faces.append(rec)
    first = next((p for p in frame.parts if p.ok), None)
    status = face_status(first) if frame.ok and first is not None else frame.status
    return json_safe({"index": clip["index"], "time": clip["time"], "status": status, "faces": faces})


class _ClipOut:
    """One clip being written: its encoders (one per light), ``frames.jsonl`` (a temporary file until the end) and
    what its record counts."""

    def __init__(self, folder: Path, info: ClipInfo, source: str, extra_lights):
        self.made = not folder.exists()  # (a folder made for the clip is taken away with it when it fails)
        folder.mkdir(parents=True, exist_ok=True)
        self.folder, self.info, self.source = folder, info, source
        names = ("relit.mp4", *(clip_relit_name(light) for light in extra_lights))
        self.encoders = []
        try:
            for name in names:
                self.encoders.append(ClipEncoder(folder / name, info, source))
        except BaseException:
            self.abort()
            raise
        self.lines_tmp = folder / ".frames.jsonl.tmp"
        self.lines = open(self.lines_tmp, "w", encoding="utf-8")
        self.frames, self.seconds = 0, 0.0
        self.status, self.faces = Counter(), Counter()
        self.last: list[np.ndarray] | None = None

    def write(self, frame: Frame, line: dict) -> None:
        """The frame's relit images (or the input's own, or the last written when it could not be read) encoded,
        its line written."""
        images = frame.data.get("clip_relit") if frame.ok else None
        if images is None:
            rgb = frame.data.get("clip_rgb")
            images = [rgb] * len(self.encoders) if rgb is not None else self.last
        if images is None:  # the first frame unreadable: black
            images = [np.zeros((self.info.height, self.info.width, 3), np.uint8)] * len(self.encoders)
        images = [self._sized(im) for im in images]
        clip = frame.meta["clip"]
        for encoder, image in zip(self.encoders, images):
            encoder.write(image, clip.get("pts"), float(clip["time"]))
        self.last = images
        self.lines.write(json.dumps(line) + "\n")
        self.frames += 1
        self.seconds += float(sum(frame.meta.get("timings", {}).values()))
        self.status[_reason(line["status"], frame.source)] += 1
        self.faces[len(line["faces"])] += 1

    def _sized(self, image: np.ndarray) -> np.ndarray:
        """At the clip's size (a frame read reduced by --max-megapixels is brought back up)."""
        h, w = self.info.height, self.info.width
        return image if image.shape[:2] == (h, w) else cv2.resize(image, (w, h), interpolation=cv2.INTER_LINEAR)

    def finish(self) -> None:
        for encoder in self.encoders:
            encoder.finish()
        self.lines.close()
        os.replace(self.lines_tmp, self.folder / "frames.jsonl")

    def abort(self) -> None:
        for encoder in self.encoders:
            encoder.abort()
        if hasattr(self, "lines"):
            self.lines.close()
            self.lines_tmp.unlink(missing_ok=True)
        if self.made:
            try:
                self.folder.rmdir()
            except OSError:
                pass  # not empty (a frame's own files, --frames): they stay

    def record(self, end: Frame) -> dict:
        """The clip's ``summary.json`` record: ok when any frame had a face that came through."""
        ok = sum(n for s, n in self.status.items() if s == "ok" or s.startswith("doubtful"))
        return clip_record(end, self.info, "ok" if ok else f"{end.source}: no face in any of its {self.frames} frames",
                           self.frames, self.status, self.faces, self.seconds)


def clip_record(end: Frame, info: ClipInfo, status: str, frames: int, frame_status: Counter | None = None,
                faces: Counter | None = None, seconds: float = 0.0) -> dict:
    """A clip's ``summary.json`` record, made at its ``end`` frame: its ``status``, its size, rate and audio
    (``info``), how many ``frames`` it had, how many had each status and each number of ``faces``, and the seconds
    they took."""
    return json_safe({
        "source": end.source, "stem": end.meta["stem"], "status": status,
        "clip": {"frames": frames, "width": info.width, "height": info.height, "fps": round(float(info.rate), 6),
                 "audio": info.audio, "frame_status": dict(frame_status or {}),
                 "faces_per_frame": {str(k): n for k, n in sorted((faces or {}).items())}},
        "seconds": round(seconds, 4), "faces": []})


def _reason(status: str, source: str) -> str:
    """A frame's status without its source's name (``frames.jsonl`` counted by reason)."""
    return status[len(source) + 2:] if status.startswith(source + ": ") else status


class ClipSink:
    """A run's clips written as their frames are done, in input order (``done``, on the run's thread): the frame's
    recording closed, its images encoded, its line written, the progress line moved; at the clip's end frame its
    files put in place and its record kept in the run's books (``ledger``: record, journal, summary). A storage
    failure stops the run as a photo's does; a clip that cannot be encoded fails alone (its files removed).
    ``extra_lights``: ``--relight``; ``recording``: the run's (``RunRecording``); ``progress``: its line."""

    def __init__(self, out: Path, extra_lights, ledger, recording, progress):
        self.out, self.extra_lights = out, tuple(extra_lights)
        self.ledger, self.recording, self.progress = ledger, recording, progress
        self.open: dict[str, _ClipOut] = {}
        self.failed: dict[str, str] = {}  # clips that could not be written, and why: their other frames pass

    def done(self, frame: Frame) -> None:
        clip = frame.meta["clip"]
        try:
            self._done(frame, clip["stem"], clip)
        finally:
            frame.drop_data()

    def _done(self, frame: Frame, stem: str, clip: dict, again: bool = False) -> None:
        try:
            if stem in self.failed:
                self._passed(frame, stem)
            elif clip.get("end"):
                self._end(frame, stem, clip)
            else:
                self._frame(frame, stem, clip)
        except OSError as exc:
            self.abort_clip(stem)
            self.ledger.out_of_storage(cannot_write(exc.filename or self.out / stem, exc))
        except Exception as exc:  # noqa: BLE001 - an encoder's refusal: the clip fails alone
            self.abort_clip(stem)
            self.failed[stem] = f"{clip['source']}: cannot write its relit clip ({' '.join(str(exc).split())})"
            self.progress.write(f"error: {self.failed[stem]}")
            if clip.get("end") and not again:  # its last frame: its record kept now, as a frame after it would
                self._done(frame, stem, clip, again=True)

    def _frame(self, frame: Frame, stem: str, clip: dict) -> None:
        line = frame_line(frame)
        # the recording's frame record: the line, and which clip's frame it is (replay's table names it)
        record = {**line, "source": frame.source, "stem": clip["stem"]}
        failed = self.recording.frame_recorded(frame, record, self.ledger.save_manifest)
        if failed is not None:
            raise OSError(f"{self.out}: {failed}")
        clip_out = self.open.get(stem)
        if clip_out is None:
            clip_out = self.open[stem] = _ClipOut(self.out / stem, ClipInfo.from_meta(clip["info"]), clip["source"],
                                                  self.extra_lights)
            self.progress.grow(clip_out.info.frames - 1)  # (the clip was counted as one input)
        clip_out.write(frame, line)
        self.progress.update(frame.ok)
        if frame.data.get("clip_rgb") is None and not frame.ok:  # undecodable: said at once (no face: at the end)
            self.progress.write(f"error: {frame.status}")

    def _end(self, frame: Frame, stem: str, clip: dict) -> None:
        clip_out = self.open.pop(stem, None)
        if clip_out is None:  # a clip without a frame
            clip_out = _ClipOut(self.out / stem, ClipInfo.from_meta(clip["info"]), clip["source"], self.extra_lights)
        try:
            clip_out.finish()
        except BaseException:  # (no longer open: its temporary files removed here, or they stayed)
            clip_out.abort()
            raise
        self._keep(frame, clip_out.record(frame))

    def _passed(self, frame: Frame, stem: str) -> None:
        """A frame of a clip that could not be written, passed by; at its end, the clip's record kept as failed (said
        once already: its files were removed), so summary.json, the report and the terminal's count name it."""
        clip = frame.meta["clip"]
        if clip.get("end"):
            info = ClipInfo.from_meta(clip["info"])
            self._keep(frame, clip_record(frame, info, self.failed.pop(stem), info.frames), said=True)

    def _keep(self, frame: Frame, rec: dict, said: bool = False) -> None:
        """``rec`` kept in the run's books; its status lines said unless they were (``said``)."""
        ledger = self.ledger
        if not ledger.stored(frame.meta["stem"], rec):
            return
        ledger.journal_entry(frame, rec)
        ledger.save_summary()
        for line in [] if said else status_lines(rec):
            self.progress.write(line)
        counts = rec["clip"]["frame_status"]
        others = sum(n for why, n in counts.items() if why != "ok" and not why.startswith("doubtful"))
        if others and rec["status"] == "ok":
            self.progress.write(f"note: {rec['source']}: {others} of {rec['clip']['frames']} frames without a face that "
                                "came through, written as they are (frames.jsonl says why)")

    def abort_clip(self, stem: str) -> None:
        clip_out = self.open.pop(stem, None)
        if clip_out is not None:
            clip_out.abort()

    def abort(self) -> None:
        """Every clip not finished: its temporary files removed (``--resume`` redoes it whole)."""
        for stem in list(self.open):
            self.abort_clip(stem)
