"""Replay and diff of recordings: convergence tables and plots, re-logging, comparison.

Face-agnostic: a "convergence" channel is any scalars channel with per-iteration values; the
caller names it (and how re-logged arrays are shown), e.g. ``nodes/app/record.py``.
"""
from __future__ import annotations

import heapq
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Collection, Iterable, Iterator, Mapping

import numpy as np

from .manifest import recording_parts
from .recording import Event, FrameRecording, FrameStream, Kind, Recording, RecordingError, RerunSink


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
            stream = FrameStream(part, arrays=False)
            for fr in stream:
                if fr.finished or fr.frame not in owner or not owner[fr.frame][1]:
                    owner[fr.frame] = (k, fr.finished)
            if stream.truncated:
                cut.add(k)
        self.truncated = any(k in cut and not done for k, done in owner.values())

        def part_frames(k: int) -> Iterator[tuple[int, int, int, FrameRecording]]:
            for n, fr in enumerate(FrameStream(self.parts[k], self.arrays)):
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


@dataclass(frozen=True)
class Column:
    """A column of the convergence table: its ``label``, and the scalar ``key`` of the channel at the
    frame's first and/or last iteration (``at``), shown ``first -> last`` when both."""

    label: str
    key: str
    at: tuple[str, ...] = ("last",)


@dataclass
class ConvergenceRow:
    """One frame of the convergence table: ``values`` per column (its ``at`` values, None when unknown)."""

    frame: int
    source: str
    status: str
    iterations: int
    values: tuple[tuple[float | None, ...], ...]
    converged: bool | None


def _number(x) -> float | None:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) else None


def convergence_row(fr: FrameRecording, channel: str, columns: tuple[Column, ...]) -> ConvergenceRow:
    """A frame's iterations and the ``columns``' scalars from the per-iteration scalars of ``channel``
    and its record (anything of the wrong type in them reads as unknown)."""
    series = fr.scalars.get(channel, {})
    its = sorted(i for i in series if i is not None)
    ends = {"first": series[its[0]] if its else {}, "last": series[its[-1]] if its else {}}
    record = fr.record or {}
    iterations = record.get("iterations")
    return ConvergenceRow(
        frame=fr.frame, source=str(record.get("source", "?")), status=str(record.get("status", "unfinished")),
        iterations=iterations if isinstance(iterations, int) and not isinstance(iterations, bool) else len(its),
        values=tuple(tuple(_number(ends[a].get(c.key)) for a in c.at) for c in columns),
        converged=record.get("converged") if isinstance(record.get("converged"), bool) else None)


def format_table(rows: list[ConvergenceRow], columns: tuple[Column, ...]) -> str:
    """The rows as a table, one line a frame: id, iterations, the columns, converged, then the source
    (a failed frame's status, a doubtful one's flags with its file), each on one line of a terminal."""
    def f(x):
        return "-" if x is None else f"{x:.4g}"

    widths = [max(9, len(c.label)) for c in columns]
    head = " ".join(f"{c.label:>{w}}" for c, w in zip(columns, widths))
    lines = [f"{'frame':>5} {'iters':>5} {head} {'converged':>9}  status / source"]
    for r in rows:
        cells = " ".join(f"{' -> '.join(f(v) for v in vals):>{w}}" for vals, w in zip(r.values, widths))
        conv = "-" if r.converged is None else ("yes" if r.converged else "no")
        # a doubtful frame's flags with its file (a failed one's status already names it)
        what = one_line(r.source if r.status == "ok" else f"{r.status}: {r.source}" if r.status.startswith("doubtful")
                        else r.status)
        lines.append(f"{r.frame:>5} {r.iterations:>5} {cells} {conv:>9}  {what}")
    return "\n".join(lines)


def plot_convergence(series: Iterable[tuple[object, Mapping]], path: str | Path, keys: tuple[str, ...],
                     labels: Mapping[str, str] | None = None, legend_max: int = 12, highlight: Collection = ()) -> Path:
    """``convergence_figure`` written as a PNG at ``path``; returns the path."""
    path = Path(path)
    convergence_figure(series, keys, labels, legend_max, highlight).savefig(path)
    return path


def printable(text: str) -> str:
    """``text`` as a font can draw it: bytes of a file name that were not UTF-8 (lone surrogates)
    become U+FFFD."""
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def one_line(text: str) -> str:
    """``text`` on one line of a terminal: control characters (tab, newline, escape) and bytes
    that were not UTF-8 written as Python escapes, so a file name cannot break a table's rows."""
    return "".join(c if c.isprintable() or c == " " else c.encode("unicode_escape", "backslashreplace").decode("ascii")
                   for c in text)


def plot_label(text: str) -> str:
    """``text`` as matplotlib draws it literally: ``printable``, one line, and ``$`` escaped (two of
    them would start mathtext, and a lone one fails the drawing)."""
    return one_line(printable(text)).replace("$", r"\$")


def convergence_figure(series: Iterable[tuple[object, Mapping]], keys: tuple[str, ...],
                       labels: Mapping[str, str] | None = None, legend_max: int = 12, highlight: Collection = ()):
    """A matplotlib ``Figure`` with one panel per scalar of ``keys``, one line per frame against
    the iteration, on a log scale where a panel's values are all positive. series: (frame label,
    {iteration: {name: value}}) per frame, e.g. ``(name, fr.scalars[channel])``; values that are
    missing or not finite numbers are left out. labels: a panel's title (with its unit) by key.
    Up to ``legend_max`` frames get a legend, a colour each; more are drawn thin and grey with their
    median per iteration in black, and those named in ``highlight`` (up to ``legend_max``) in colour
    with a legend: a run's odd frames stand out of the crowd."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    series = list(series)
    labels = labels or {}
    many = len(series) > legend_max
    marked = [k for k, (label, _) in enumerate(series) if many and label in set(highlight)][:legend_max]
    # fixed margins: a constrained layout measured every tick label again and took half the drawing time
    side = 2.6 if not many or marked else 0.3  # inches right of the panels: the legend
    width = 4.4 * len(keys) + side
    fig = Figure(figsize=(width, 3.6), dpi=110)
    fig.subplots_adjust(left=0.85 / width, right=1 - side / width, bottom=0.14, top=0.9, wspace=0.4)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(keys), squeeze=False)[0]
    cmap = colormaps["tab10"]
    handles: dict = {}  # frame -> its first line: the legend's entries, given explicitly (a label starting
    # with "_" would otherwise be left out of it)
    for ax, key in zip(axes, keys):
        _panel(ax, key, series, many, marked, cmap, handles)
        ax.set_title(labels.get(key, key), fontsize=10)
    _legend(axes[-1], handles, many, marked)
    return fig


def _points(s: Mapping, key: str) -> np.ndarray:
    """(n, 2) iteration and value of ``key`` in one frame's ``{iteration: scalars}``, finite numbers only."""
    pts = [(i, _number(s[i].get(key))) for i in sorted(i for i in s if i is not None)]
    return np.array([(i, v) for i, v in pts if v is not None and np.isfinite(v)], float).reshape(-1, 2)


def _panel(ax, key: str, series: list, many: bool, marked: list[int], cmap, handles: dict) -> None:
    """One scalar's panel of ``convergence_figure``: a line per frame (the crowd grey, with its median)."""
    from matplotlib.ticker import MaxNLocator

    plotted = []
    for k, (label, s) in enumerate(series):
        pts = _points(s, key)
        if not len(pts):
            continue
        plotted.append(pts)
        if many and k not in marked:
            ax.plot(pts[:, 0], pts[:, 1], color="0.7", lw=0.5, alpha=0.6, zorder=1)
            continue
        colour = cmap((marked.index(k) if many else k) % 10)
        line, = ax.plot(pts[:, 0], pts[:, 1], color=colour, lw=1.3, marker="." if len(pts) < 3 else None, zorder=3)
        handles.setdefault(k, (line, plot_label(str(label))))
    if many and plotted:  # the crowd's median per iteration
        handles.setdefault(-1, (_median_line(ax, plotted), f"median of {len(series)}"))
    if plotted and all((p[:, 1] > 0).all() for p in plotted):
        ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.grid(True, alpha=0.3)  # major lines only: minor ones on a log axis were most of the drawing time
    if not plotted:
        ax.text(0.5, 0.5, "no values", ha="center", va="center", transform=ax.transAxes, color="grey")


def _median_line(ax, plotted: list[np.ndarray]):
    """The median of the frames' values at each iteration, drawn black over the crowd; its line."""
    iters = np.unique(np.concatenate([p[:, 0] for p in plotted]))
    med = [np.median([p[p[:, 0] == i, 1][0] for p in plotted if (p[:, 0] == i).any()]) for i in iters]
    line, = ax.plot(iters, med, color="k", lw=1.6, zorder=2)
    return line


def _legend(ax, handles: dict, many: bool, marked: list[int]) -> None:
    """The frames' legend right of the last panel (the median last); a crowd without marked frames: the
    median's alone."""
    if handles and (not many or marked):
        entries = [handles[k] for k in sorted(handles, key=lambda k: (k < 0, k))]
        ax.legend([h for h, _ in entries], [t for _, t in entries], loc="upper left", bbox_to_anchor=(1.02, 1),
                  fontsize=8, title="frame", frameon=False)
    elif handles:
        ax.legend([handles[-1][0]], [handles[-1][1]], loc="upper right", fontsize=8, frameon=False)


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
        fid = fr.frame
        stem = (fr.record or {}).get("stem")
        if isinstance(stem, str) and stem:
            sink.name_frame(fid, stem)
        for path, by_it in fr.arrays.items():
            name = path.rsplit("/", 1)[-1]
            if any(part in f"/{path}" for part in left):
                continue
            for it, arr in sorted(by_it.items(), key=lambda kv: -1 if kv[0] is None else kv[0]):
                kind = kinds.get(name, Kind.IMAGE if arr.ndim == 2 else Kind.ARRAY)
                sink.write(Event(fid, path, kind, arr, it))
        for path, by_it in fr.scalars.items():
            for it, vals in sorted(by_it.items(), key=lambda kv: -1 if kv[0] is None else kv[0]):
                sink.write(Event(fid, path, Kind.SCALARS, vals, it))
        if fr.record is not None:
            sink.write(Event(fid, "frames", Kind.FRAME, fr.record))
        sink.frame_done(fid)
    sink.close()
    return Path(rrd_path)


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
