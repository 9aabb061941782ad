"""Two runs' recordings compared channel by channel and iteration by iteration."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable, Iterator

import numpy as np

from ..recording import FrameRecording, Recording


@dataclass
class Difference:
    frame: int | str  # the frame's key (its id, or the caller's name for it)
    iteration: int | None
    channel: str
    max_abs: float
    what: str = "values differ"


@dataclass
class DiffReport:
    """differences: in the order the runs split (see ``diff_streams``); frames:
    how many were compared; iterations: distinct iterations over the frames compared."""

    differences: list[Difference]
    frames: int
    iterations: int


def diff_streams(a: Iterable[FrameRecording], b: Iterable[FrameRecording], atol: float = 0.0, rtol: float = 0.0,
                 key: Callable[[FrameRecording], object] | None = None,
                 stage: Callable[[str], int] | None = None,
                 fallback: Callable[[FrameRecording], object] | None = None) -> DiffReport:
    """Channel-by-channel, iteration-by-iteration comparison of two streams of frames, holding only
    the frames one stream has reached and the other not yet (one each when both run in the same
    order). Frames pair up by ``key(frame)`` (default: the frame id); a frame, channel or
    iteration present on one side only is a difference. Arrays (and scalars) match when
    ``|a - b| <= atol + rtol |b|`` everywhere (NaN equals NaN). The differences come in the order
    the runs split: by frame, then by ``stage(channel)`` (the rank of the step that made the
    channel; default: all one stage), then iteration (per-frame products of a stage first), then
    channel. ``fallback``: a second key that pairs, in order, the frames ``key`` left alone once both
    streams have ended (e.g. inputs read from other folders, paired by file name). Tolerances must be
    finite and not negative (``ValueError``)."""
    if not (np.isfinite(atol) and np.isfinite(rtol) and atol >= 0 and rtol >= 0):
        raise ValueError(f"tolerances must be finite and not negative, not atol={atol!r} rtol={rtol!r}")
    diff = _Comparison(atol, rtol, stage or (lambda channel: 0))
    key = key or (lambda fr: fr.frame)
    pending = _pair_streams(iter(a), iter(b), key, diff)
    if fallback is not None:  # what the key left: paired by the fallback, in the order they came
        pending = _pair_left(pending, key, fallback, diff)
    for side, label in ((0, "A"), (1, "B")):
        for k, frs in pending[side].items():
            for fr in frs:
                diff.out.append(((fr.frame, -1, -2, ""), Difference(k, None, "*", float("inf"),
                                                                   f"frame only in {label}")))
    diff.out.sort(key=lambda od: od[0])
    return DiffReport([d for _, d in diff.out], diff.compared, diff.iterations)


class _Comparison:
    """The differences of the frame pairs compared so far, with their sort keys, and how many frames and
    iterations were compared."""

    def __init__(self, atol: float, rtol: float, stage: Callable[[str], int]):
        self.atol, self.rtol, self.stage = atol, rtol, stage
        self.out: list[tuple[tuple, Difference]] = []
        self.compared = self.iterations = 0

    def __call__(self, k, fa: FrameRecording, fb: FrameRecording) -> None:
        self.compared += 1
        self.iterations += len({i for kind in (fa.arrays, fa.scalars) for by_it in kind.values() for i in by_it
                                if i is not None})
        self.out += [((fa.frame, self.stage(d.channel)) + _order(d), d)
                     for d in _diff_frame(k, fa, fb, self.atol, self.rtol)]


def _pair_streams(a: Iterator[FrameRecording], b: Iterator[FrameRecording], key: Callable,
                  compare: _Comparison) -> tuple[dict, dict]:
    """Read both streams in step, comparing each frame with the other side's of its key as soon as both
    came; returns the frames left unpaired, per side, by key (two frames with one key pair up in order)."""
    pending: tuple[dict, dict] = ({}, {})
    streams: list[Iterator[FrameRecording] | None] = [a, b]
    while any(s is not None for s in streams):
        for side in (0, 1):
            stream = streams[side]
            fr = next(stream, None) if stream is not None else None
            if fr is None:
                streams[side] = None
                continue
            k = key(fr)
            waiting = pending[1 - side].get(k)
            if not waiting:
                pending[side].setdefault(k, []).append(fr)
                continue
            other = waiting.pop(0)
            compare(k, *((fr, other) if side == 0 else (other, fr)))
    return pending


def _pair_left(pending: tuple[dict, dict], key: Callable, fallback: Callable,
               compare: _Comparison) -> tuple[dict, dict]:
    """The frames ``key`` left unpaired, paired by ``fallback`` in the order they came; returns those still
    left."""
    left = [[fr for frs in pending[side].values() for fr in frs] for side in (0, 1)]
    still: tuple[dict, dict] = ({}, {})
    by_b: dict = {}
    for fr in left[1]:
        by_b.setdefault(fallback(fr), []).append(fr)
    for fa in left[0]:
        k = fallback(fa)
        if by_b.get(k):
            compare(k, fa, by_b[k].pop(0))
        else:
            still[0].setdefault(key(fa), []).append(fa)
    for frs in by_b.values():
        for fr in frs:
            still[1].setdefault(key(fr), []).append(fr)
    return still


def _order(d: Difference) -> tuple:
    return (-1 if d.iteration is None else d.iteration, d.channel)


def diff_recordings(a: Recording, b: Recording, atol: float = 0.0, rtol: float = 0.0,
                    key: Callable[[FrameRecording], object] | None = None,
                    stage: Callable[[str], int] | None = None) -> list[Difference]:
    """``diff_streams`` of two recordings read whole: the differences, the first divergence first."""
    return diff_streams(a, b, atol, rtol, key, stage).differences


def _diff_frame(fid, fa: FrameRecording, fb: FrameRecording, atol: float, rtol: float) -> list[Difference]:
    out: list[Difference] = []
    keys = set()
    for kind in ("arrays", "scalars"):
        for ch in set(getattr(fa, kind)) | set(getattr(fb, kind)):
            for it in set(getattr(fa, kind).get(ch, {})) | set(getattr(fb, kind).get(ch, {})):
                keys.add((-1 if it is None else it, ch, kind))
    for it, ch, kind in sorted(keys):
        itv = None if it == -1 else it
        va = getattr(fa, kind).get(ch, {}).get(itv)
        vb = getattr(fb, kind).get(ch, {}).get(itv)
        if va is None or vb is None:
            out.append(Difference(fid, itv, ch, float("inf"), f"only in {'B' if va is None else 'A'}"))
            continue
        pair = _comparable(va, vb, kind)
        if isinstance(pair, str):
            out.append(Difference(fid, itv, ch, float("inf"), pair))
            continue
        d = _max_violation(*pair, atol, rtol)
        if d is not None:
            out.append(Difference(fid, itv, ch, d))
    if (fa.record or {}).get("status") != (fb.record or {}).get("status"):
        out.append(Difference(fid, None, "frames", float("inf"), "status differs"))
    return out


def _comparable(va, vb, kind: str) -> tuple[np.ndarray, np.ndarray] | str:
    """Two recorded values as float64 arrays to compare, or why they cannot be (other scalar names, another
    shape or type)."""
    if kind == "scalars":
        if set(va) != set(vb):
            return "different scalar names"
        names = sorted(va)
        return (np.array([np.nan if va[n] is None else va[n] for n in names], float),
                np.array([np.nan if vb[n] is None else vb[n] for n in names], float))
    if va.shape != vb.shape or va.dtype != vb.dtype:
        return f"{va.dtype}{list(va.shape)} vs {vb.dtype}{list(vb.shape)}"
    return np.asarray(va, np.float64), np.asarray(vb, np.float64)


def _max_violation(a: np.ndarray, b: np.ndarray, atol: float, rtol: float) -> float | None:
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    if not np.array_equal(nan_a, nan_b):
        return float("inf")
    ok = ~nan_a
    diff = np.abs(a[ok] - b[ok])
    if diff.size == 0:
        return None
    bad = diff > atol + rtol * np.abs(b[ok])
    return float(diff.max()) if np.any(bad) else None
