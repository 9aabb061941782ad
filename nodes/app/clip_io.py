"""A clip's frames read and its relit frames written, with PyAV (FFmpeg's codecs in the wheel): ``ClipReader``
decodes one frame at a time, ``ClipEncoder`` encodes one relit clip (H.264 in MP4) and remuxes the input's audio
beside it, interleaved by time, into a temporary file renamed into place when it is complete."""
from __future__ import annotations

import os
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Iterator

import numpy as np

# what a run takes as a clip by its name (docs/usage.md, "Clips"); a ``.gif`` is a clip when it has more than
# one frame, else a still
VIDEO_SUFFIXES = frozenset({".mp4", ".mov", ".avi", ".mkv", ".webm", ".m4v"})
CLIP_SUFFIXES = VIDEO_SUFFIXES | {".gif"}


def is_clip(path: str | os.PathLike) -> bool:
    """Whether the input ``path`` is read as a clip: a video file by its suffix, or an animated GIF."""
    suffix = Path(path).suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        return True
    if suffix != ".gif":
        return False
    from PIL import Image

    try:
        with Image.open(path) as probe:
            return getattr(probe, "n_frames", 1) > 1
    except (OSError, ValueError, Image.DecompressionBombError):
        return False  # the still's loader says what is wrong with it


@dataclass(frozen=True)
class ClipInfo:
    """What the relit clips keep of the input: size (W, H), frame rate (a fraction), frames (the container's
    count, 0 when it does not say), time base, whether it has audio. ``as_meta`` / ``from_meta``: as JSON."""

    width: int
    height: int
    rate: Fraction
    frames: int
    time_base: Fraction
    audio: bool

    def as_meta(self) -> dict:
        return {"width": self.width, "height": self.height, "rate": str(self.rate), "frames": self.frames,
                "time_base": str(self.time_base), "audio": self.audio}

    @classmethod
    def from_meta(cls, m: dict) -> "ClipInfo":
        return cls(int(m["width"]), int(m["height"]), Fraction(m["rate"]), int(m["frames"]),
                   Fraction(m["time_base"]), bool(m["audio"]))


@dataclass
class ClipFrame:
    """One decoded frame: its index in the clip, its time (s), its pts (in the stream's time base), and its
    pixels ((H, W, 3) uint8 RGB), or the one-line reason it could not be decoded (``error``, pixels None)."""

    index: int
    time: float
    pts: int | None
    rgb: np.ndarray | None
    error: str | None = None


# a container's average frame rate more than this many times its codec's guessed rate is read off broken timestamps
# (every frame's at 0 read as 1000 frames a second): the guessed rate is the clip's
RATE_MISMATCH = 4.0


def clip_rate(average: Fraction | None, guessed: Fraction | None) -> Fraction:
    """A clip's frame rate from its stream's ``average`` rate (measured off its timestamps) and ``guessed`` rate (the
    codec's): the average, unless it is missing or ``RATE_MISMATCH`` times off the guessed one; else 25."""
    if average and guessed and not 1.0 / RATE_MISMATCH <= float(average) / float(guessed) <= RATE_MISMATCH:
        return Fraction(guessed)
    return Fraction(average or guessed or 25)


class _FrameTimes:
    """Each frame's ``(pts, time)`` as the clip gives them, or, where it gives none or one not after the last (a clip
    whose every frame says 0, as some tools write them), one frame period after the last: frames written at one time
    cannot be muxed (the relit clip failed with "Invalid argument"), and ``frames.jsonl`` would say they are."""

    def __init__(self, time_base: Fraction, rate: Fraction):
        self.tb = Fraction(time_base)
        self.step = max(1, round(1 / (Fraction(rate) * self.tb)))  # a frame period, in the time base's ticks
        self.last: int | None = None

    def next(self, pts: int | None) -> tuple[int, float]:
        if pts is None or (self.last is not None and pts <= self.last):
            pts = 0 if self.last is None else self.last + self.step
        self.last = pts
        return pts, float(pts * self.tb)


class ClipReader:
    """The clip at ``path`` opened (``av.FFmpegError`` / ``OSError`` when it cannot be, or has no video); iterate
    it for ``ClipFrame``s, one at a time (never the whole clip); ``close()`` after."""

    def __init__(self, path: str | os.PathLike):
        import av

        self.path = str(path)
        self.container = av.open(self.path)
        try:
            if not self.container.streams.video:
                raise ValueError("no video stream")
            self.stream = self.container.streams.video[0]
            self.stream.thread_type = "AUTO"
            ctx = self.stream.codec_context
            rate = clip_rate(self.stream.average_rate, self.stream.guessed_rate)
            self.info = ClipInfo(int(ctx.width), int(ctx.height), Fraction(rate), int(self.stream.frames or 0),
                                 Fraction(self.stream.time_base or Fraction(1, 90000)),
                                 bool(self.container.streams.audio))
            if self.info.width <= 0 or self.info.height <= 0:
                raise ValueError("the video stream has no size")
        except BaseException:
            self.container.close()
            raise

    def __iter__(self) -> Iterator[ClipFrame]:
        import av

        index, tb = 0, self.stream.time_base or Fraction(1, 90000)
        times = _FrameTimes(tb, self.info.rate)
        for packet in self.container.demux(self.stream):
            try:
                decoded = packet.decode()
            except av.FFmpegError as exc:  # a damaged packet: its frame is one line, the clip goes on
                if packet.size:
                    pts, time = times.next(packet.pts)
                    why = getattr(exc, "strerror", None) or str(exc)
                    yield ClipFrame(index, time, pts, None, " ".join(why.split()))
                    index += 1
                continue
            for frame in decoded:
                pts, time = times.next(frame.pts)
                yield ClipFrame(index, time, pts, frame.to_ndarray(format="rgb24"))
                index += 1

    def close(self) -> None:
        self.container.close()


class ClipEncoder:
    """One relit clip written to ``path`` (through ``path``'s temporary ``.<name>.tmp``, renamed at ``finish``):
    H.264 at the input's size and frame rate, each frame at its input time; the input's audio (``info.audio``)
    remuxed from ``source`` as the video reaches it (or made AAC when the container cannot take its codec)."""

    def __init__(self, path: Path, info: ClipInfo, source: str):
        import av

        self.path, self.info = path, info
        self.tmp = path.with_name(f".{path.name}.tmp")
        self.out = av.open(str(self.tmp), mode="w", format="mp4")
        self.video = self.out.add_stream("libx264", rate=info.rate)
        self.video.width, self.video.height = info.width, info.height
        # 4:2:0 halves the colour's resolution and needs even sides; an odd-sided clip keeps it whole
        even = info.width % 2 == 0 and info.height % 2 == 0
        self.video.pix_fmt = "yuv420p" if even else "yuv444p"
        self.video.time_base = info.time_base
        self.video.codec_context.time_base = info.time_base
        # no B-frames: with them a clip of uneven frame times (a phone's: its first two frames 11 ms apart, then 40)
        # got packets whose decode times ran backwards, which MP4 refuses ("Invalid argument"); files 17 % larger
        self.video.options = {"crf": "18", "preset": "veryfast", "bf": "0"}
        self.audio = _AudioFeed(source, self.out) if info.audio else None
        self._last_pts = -1

    def write(self, rgb: np.ndarray, pts: int | None, time: float) -> None:
        """One frame ((H, W, 3) uint8 RGB) at ``pts`` (the input's, in its time base) or, without one, after the
        last; the audio up to ``time`` (s) muxed first."""
        import av

        if self.audio is not None:
            self.audio.until(time)
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")
        pts = pts if pts is not None and pts > self._last_pts else self._last_pts + 1
        frame.pts, frame.time_base, self._last_pts = pts, self.info.time_base, pts
        self.out.mux(self.video.encode(frame))

    def finish(self) -> None:
        """The encoder flushed, the rest of the audio muxed, the file closed and renamed into place."""
        self.out.mux(self.video.encode(None))
        if self.audio is not None:
            self.audio.until(None)
        self.out.close()
        os.replace(self.tmp, self.path)

    def abort(self) -> None:
        """Closed and its temporary file removed (a stopped run: the clip is redone by ``--resume``)."""
        try:
            self.out.close()
        except Exception:  # noqa: BLE001 - a half-written file is removed either way
            pass
        if self.audio is not None:
            self.audio.close()
        self.tmp.unlink(missing_ok=True)


# the audio codecs an MP4 file holds as they are (copied); any other (PCM, Vorbis, ...) is made AAC
MP4_AUDIO = frozenset({"aac", "mp3", "ac3", "eac3", "alac", "opus", "flac"})


class _AudioFeed:
    """The input's first audio stream, read from a container of its own, muxed into ``out``: copied as it is
    (remuxed) when ``out``'s format takes its codec, else decoded and encoded as AAC."""

    def __init__(self, source: str, out):
        import av

        self.input = av.open(source)
        self.stream = self.input.streams.audio[0]
        self.out = out
        self.copy = self.stream.codec_context.name in MP4_AUDIO
        if self.copy:
            self.target = out.add_stream_from_template(self.stream)
        else:
            self.target = out.add_stream("aac", rate=self.stream.codec_context.sample_rate or 48000)
        self.packets = self.input.demux(self.stream)
        self.held = None  # a packet read past the time asked for

    def until(self, time: float | None) -> None:
        """The audio up to ``time`` (s; None: all of it) muxed."""
        while True:
            packet = self.held or next(self.packets, None)
            self.held = None
            if packet is None:
                if time is None:
                    self._flush()
                return
            if packet.dts is None and packet.size == 0:
                continue  # the demuxer's empty last packet
            at = float(packet.pts * packet.time_base) if packet.pts is not None else 0.0
            if time is not None and at > time:
                self.held = packet
                return
            self._mux(packet)

    def _mux(self, packet) -> None:
        if self.copy:
            packet.stream = self.target
            self.out.mux(packet)
            return
        for frame in packet.decode():
            frame.pts = None
            self.out.mux(self.target.encode(frame))

    def _flush(self) -> None:
        if not self.copy:
            self.out.mux(self.target.encode(None))
        self.close()

    def close(self) -> None:
        self.input.close()
