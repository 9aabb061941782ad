"""The convergence table: one row a frame, its columns named by the caller (the engine knows no fit)."""
from __future__ import annotations

from dataclasses import dataclass

from ..recording import FrameRecording
from .text import one_line


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


def scalar_value(x) -> float | None:
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
        values=tuple(tuple(scalar_value(ends[a].get(c.key)) for a in c.at) for c in columns),
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
