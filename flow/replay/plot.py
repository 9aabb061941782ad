"""The convergence plot: one panel a scalar, one line a frame, against the iteration."""
from __future__ import annotations

from pathlib import Path
from typing import Collection, Iterable, Mapping

import numpy as np

from .table import scalar_value
from .text import plot_label


def plot_convergence(series: Iterable[tuple[object, Mapping]], path: str | Path, keys: tuple[str, ...],
                     labels: Mapping[str, str] | None = None, legend_max: int = 12, highlight: Collection = (),
                     marks: Mapping[str, str] | None = None) -> Path:
    """``convergence_figure`` written as a PNG at ``path``; returns the path."""
    path = Path(path)
    convergence_figure(series, keys, labels, legend_max, highlight, marks).savefig(path)
    return path



def convergence_figure(series: Iterable[tuple[object, Mapping]], keys: tuple[str, ...],
                       labels: Mapping[str, str] | None = None, legend_max: int = 12, highlight: Collection = (),
                       marks: Mapping[str, str] | None = None):
    """A matplotlib ``Figure`` with one panel per scalar of ``keys``, one line per frame against
    the iteration, on a log scale where a panel's values are all positive. series: (frame label,
    {iteration: {name: value}}) per frame, e.g. ``(name, fr.scalars[channel])``; values that are
    missing or not finite numbers are left out. labels: a panel's title (with its unit) by key.
    Up to ``legend_max`` frames get a legend, a colour each; more are drawn thin and grey with their
    median per iteration in black, and those named in ``highlight`` (up to ``legend_max``) in colour
    with a legend: a run's odd frames stand out of the crowd. marks: scalars that flag an iteration (non-zero
    where it happened) with their legend's text: each line gets an open circle there, on every panel (an event
    that explains a jump, e.g. the fit's albedo measured again)."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    series = list(series)
    labels = labels or {}
    many = len(series) > legend_max
    marked = [k for k, (label, _) in enumerate(series) if many and label in set(highlight)][:legend_max]
    # fixed margins: a constrained layout measures every tick label again, which made drawing slow
    side = 2.6 if not many or marked else 0.3  # inches right of the panels: the legend
    width = 4.4 * len(keys) + side
    fig = Figure(figsize=(width, 3.6), dpi=110)
    fig.subplots_adjust(left=0.85 / width, right=1 - side / width, bottom=0.14, top=0.9, wspace=0.4)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(keys), squeeze=False)[0]
    cmap = colormaps["tab10"]
    handles: dict = {}  # frame -> its first line: the legend's entries, given explicitly (a label starting
    # with "_" would otherwise be left out of it)
    events = [(text, [_flagged(s, flag) for _, s in series]) for flag, text in (marks or {}).items()]
    for ax, key in zip(axes, keys):
        _panel(ax, key, series, many, marked, cmap, handles)
        ax.set_title(labels.get(key, key), fontsize=10)
        for k, (text, flagged) in enumerate(events):
            if _mark(ax, key, series, flagged, many, marked):
                handles.setdefault(-2 - k, (_mark_handle(), text))
    _legend(axes[-1], handles, many, marked)
    return fig


def _flagged(s: Mapping, flag: str) -> set:
    """The iterations of one frame's ``{iteration: scalars}`` whose ``flag`` is a non-zero number."""
    return {i for i in s if i is not None and (scalar_value(s[i].get(flag)) or 0.0) != 0.0}


def _mark(ax, key: str, series: list, flagged: list[set], many: bool, marked: list[int]) -> bool:
    """Open circles on each frame's line of ``key`` at its ``flagged`` iterations (small and grey on the crowd's);
    whether any was drawn."""
    drawn = False
    for k, ((_, s), iters) in enumerate(zip(series, flagged)):
        pts = _points(s, key)
        pts = pts[np.isin(pts[:, 0], sorted(iters))] if iters and len(pts) else pts[:0]
        if not len(pts):
            continue
        crowd = many and k not in marked
        ax.plot(pts[:, 0], pts[:, 1], ls="", marker="o", ms=3.5 if crowd else 6, mfc="white",
                mec="0.6" if crowd else "k", mew=0.8, zorder=2 if crowd else 4)
        drawn = True
    return drawn


def _mark_handle():
    """The legend's sample of a mark: an open circle alone."""
    from matplotlib.lines import Line2D

    return Line2D([], [], ls="", marker="o", ms=6, mfc="white", mec="k", mew=0.8)


def _points(s: Mapping, key: str) -> np.ndarray:
    """(n, 2) iteration and value of ``key`` in one frame's ``{iteration: scalars}``, finite numbers only."""
    pts = [(i, scalar_value(s[i].get(key))) for i in sorted(i for i in s if i is not None)]
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
    """The frames' legend right of the last panel (the median, then the marks, last); a crowd without marked frames:
    the median's and the marks' alone."""
    if handles and (not many or marked):
        entries = [handles[k] for k in sorted(handles, key=lambda k: (k < 0, abs(k)))]
        ax.legend([h for h, _ in entries], [t for _, t in entries], loc="upper left", bbox_to_anchor=(1.02, 1),
                  fontsize=8, title="frame", frameon=False)
    elif handles:
        entries = [handles[k] for k in sorted(k for k in handles if k < 0)[::-1]]
        ax.legend([h for h, _ in entries], [t for _, t in entries], loc="upper right", fontsize=8, frameon=False)
