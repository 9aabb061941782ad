"""Replay and diff of recordings: convergence tables and plots, re-logging, comparison.

Face-agnostic: a "convergence" channel is any scalars channel with per-iteration values; the
caller names it (and how re-logged arrays are shown), e.g. ``nodes/app/record.py``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import cv2
import numpy as np

from .recording import Event, FrameRecording, Kind, Recording, RecordingError, RerunSink, read_mcap


def _part_number(path: Path) -> int:
    m = re.search(r"\.part(\d+)$", path.stem)
    return int(m.group(1)) if m else 1


def merge_recordings(parts: list[Recording], path: Path) -> Recording:
    """One recording from the parts of an interrupted and resumed job, in order.

    A frame finished in a later part replaces any earlier copy (a frame cut short by a kill is
    redone by the resumed run); an unfinished frame is kept only if no part finished it.
    """
    frames: dict[int, FrameRecording] = {}
    for rec in parts:
        for fid, fr in rec.frames.items():
            if fr.finished or fid not in frames or not frames[fid].finished:
                frames[fid] = fr
    return Recording(path, dict(sorted(frames.items())), bool(parts) and parts[-1].truncated)


def open_recording(path: str | Path) -> Recording:
    """Open an MCAP recording (``.mcap``) for walking frame -> iteration -> arrays.

    A folder opens the recordings of one job in it, ``run.mcap`` then ``run.part2.mcap``,
    ``run.part3.mcap``... (written by ``--resume``), merged by ``merge_recordings``.
    ``.rrd`` files hold display forms (images, plots), not the exact arrays: replay them in
    the Rerun viewer, and use the MCAP twin written beside them for tables and diffs.
    """
    path = Path(path)
    if path.is_dir():
        files = sorted(path.glob("*.mcap"), key=lambda p: (_part_number(p), p.name))
        if not files:
            raise RecordingError(f"{path}: no .mcap recording in this folder")
        return merge_recordings([read_mcap(f) for f in files], path)
    if path.suffix.lower() == ".rrd":
        raise RecordingError(f"{path}: tables and diffs read the exact MCAP recording (run.mcap beside it)")
    return read_mcap(path)


@dataclass
class ConvergenceRow:
    frame: int
    source: str
    status: str
    iterations: int
    final_sigma: float | None
    residual_first: float | None
    residual_last: float | None
    converged: bool | None


def convergence_table(rec: Recording, channel: str) -> list[ConvergenceRow]:
    """One row per recorded frame: iterations, final ``sigma``, ``residual_mean`` first -> last, from
    the per-iteration scalars of ``channel``."""
    rows = []
    for fid, fr in sorted(rec.frames.items()):
        series = fr.scalars.get(channel, {})
        its = sorted(i for i in series if i is not None)
        first = series[its[0]] if its else {}
        last = series[its[-1]] if its else {}
        record = fr.record or {}
        rows.append(ConvergenceRow(
            frame=fid, source=str(record.get("source", "?")),
            status=str(record.get("status", "unfinished")), iterations=int(record.get("iterations") or len(its)),
            final_sigma=last.get("sigma"), residual_first=first.get("residual_mean"),
            residual_last=last.get("residual_mean"), converged=record.get("converged")))
    return rows


def format_table(rows: list[ConvergenceRow]) -> str:
    def f(x):
        return "-" if x is None else f"{x:.4g}"

    lines = [f"{'frame':>5} {'iters':>5} {'sigma':>9} {'residual first -> last':>24} {'converged':>9}  status / source"]
    for r in rows:
        trend = f"{f(r.residual_first)} -> {f(r.residual_last)}"
        conv = "-" if r.converged is None else ("yes" if r.converged else "no")
        what = r.source if r.status == "ok" else r.status
        lines.append(f"{r.frame:>5} {r.iterations:>5} {f(r.final_sigma):>9} {trend:>24} {conv:>9}  {what}")
    return "\n".join(lines)


def plot_convergence(rec: Recording, path: str | Path, channel: str, keys: tuple[str, ...],
                     size=(900, 300)) -> Path:
    """PNG with one panel per scalar ``keys`` of ``channel`` (log scale), one line per frame, against
    iteration."""
    w, h = size
    panels = []
    colours = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75)]
    for key in keys:
        img = np.full((h, w // len(keys), 3), 255, np.uint8)
        pw, ph = img.shape[1], img.shape[0]
        series = []
        for fid, fr in sorted(rec.frames.items()):
            s = fr.scalars.get(channel, {})
            pts = [(i, s[i][key]) for i in sorted(k for k in s if k is not None) if s[i].get(key, 0) > 0]
            if pts:
                series.append((fid, np.array(pts, float)))
        cv2.putText(img, key, (40, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        if series:
            xmax = max(s[:, 0].max() for _, s in series)
            ys = np.log10(np.concatenate([s[:, 1] for _, s in series]))
            lo, hi = float(ys.min()), float(ys.max()) + 1e-9
            cv2.putText(img, f"1e{lo:.1f}", (2, ph - 28), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (90, 90, 90), 1)
            cv2.putText(img, f"1e{hi:.1f}", (2, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (90, 90, 90), 1)
            cv2.putText(img, f"iteration 1..{int(xmax)}", (pw // 2 - 40, ph - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.35,
                        (90, 90, 90), 1)
            for k, (_, s) in enumerate(series):
                x = 40 + (s[:, 0] - 1) / max(xmax - 1, 1) * (pw - 50)
                y = (ph - 24) - (np.log10(s[:, 1]) - lo) / (hi - lo) * (ph - 50)
                pts = np.column_stack([x, y]).astype(np.int32).reshape(-1, 1, 2)
                cv2.polylines(img, [pts], False, colours[k % len(colours)], 1, cv2.LINE_AA)
        panels.append(img)
    path = Path(path)
    cv2.imwrite(str(path), np.hstack(panels))
    return path


def relog_to_rerun(rec: Recording, rrd_path: str | Path, kinds: Mapping[str, Kind] | None = None,
                   blueprint=None) -> Path:
    """Write a recording's frames and iterations into a Rerun ``.rrd`` file. kinds: how to show an
    array by the last part of its path (e.g. ``{"depth": Kind.DEPTH}``); others are images when
    2-D, arrays otherwise."""
    kinds = kinds or {}
    sink = RerunSink(rrd_path, blueprint=blueprint)
    for fid, fr in sorted(rec.frames.items()):
        for path, by_it in fr.arrays.items():
            name = path.rsplit("/", 1)[-1]
            if "/mesh/" in f"/{path}":
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
    frame: int
    iteration: int | None
    channel: str
    max_abs: float
    what: str = "values differ"


def diff_recordings(a: Recording, b: Recording, atol: float = 0.0, rtol: float = 0.0) -> list[Difference]:
    """Channel-by-channel, iteration-by-iteration comparison of two recordings.

    Arrays (and scalars) match when ``|a - b| <= atol + rtol |b|`` everywhere (NaN equals
    NaN); a channel, iteration or frame present in one and not the other is a difference.
    Returned in (frame, iteration, channel) order: the first is the first divergence.
    """
    out: list[Difference] = []
    for fid in sorted(set(a.frames) | set(b.frames)):
        fa, fb = a.frames.get(fid), b.frames.get(fid)
        if fa is None or fb is None:
            out.append(Difference(fid, None, "*", float("inf"), f"frame only in {'B' if fa is None else 'A'}"))
            continue
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
            if kind == "scalars":
                names = sorted(set(va) | set(vb))
                if set(va) != set(vb):
                    out.append(Difference(fid, itv, ch, float("inf"), "different scalar names"))
                    continue
                xa = np.array([va[n] for n in names], float)
                xb = np.array([vb[n] for n in names], float)
            else:
                xa, xb = va, vb
                if xa.shape != xb.shape or xa.dtype != xb.dtype:
                    out.append(Difference(fid, itv, ch, float("inf"), f"{xa.dtype}{list(xa.shape)} vs {xb.dtype}{list(xb.shape)}"))
                    continue
            d = _max_violation(np.asarray(xa, np.float64), np.asarray(xb, np.float64), atol, rtol)
            if d is not None:
                out.append(Difference(fid, itv, ch, d))
        if (fa.record or {}).get("status") != (fb.record or {}).get("status"):
            out.append(Difference(fid, None, "frames", float("inf"), "status differs"))
    return out


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
