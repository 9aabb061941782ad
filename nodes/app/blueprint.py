"""How a run looks in the Rerun viewer: its default blueprint, and the run's Rerun sink with it.

Imports only the recording engine, the channel names and ``rerun``: a recording process (``ProcessSinks``) makes
the sink from here without loading the method.
"""
from __future__ import annotations

from pathlib import Path

from ...flow.recording.rerun_sink import RerunSink
from . import channels as ch


def rerun_sink(path: str | Path, recording_id: str | None = None, previous_paths: list[str] | None = None) -> RerunSink:
    """The run's Rerun sink: ``path`` with the default blueprint (a ``ProcessSinks`` factory;
    ``previous_paths``: see ``RerunSink``)."""
    return RerunSink(path, blueprint=default_blueprint(), recording_id=recording_id, previous_paths=previous_paths)


def default_blueprint():
    """Rerun layout: the frame's images and its surface above the fit's convergence (sigma, mean
    change, mean residual) and its coefficients as a bar chart, on the ``iteration`` timeline.
    Entities are ``/<node>/<name>/<input stem>``; each view gathers its channel from every frame
    (``/<node>/<name>/**``), and the image and surface views show the frame at the time cursor of
    the ``frame`` timeline (the plots: every frame's curve on the ``iteration`` timeline)."""
    import rerun.blueprint as rrb

    this_frame = [rrb.VisibleTimeRange("frame", start=rrb.TimeRangeBoundary.cursor_relative(),
                                       end=rrb.TimeRangeBoundary.cursor_relative())]
    images = [("input", ch.GRID_IMAGE), ("weights", ch.FIT_WEIGHTS), ("normals", ch.FIT_NORMALS),
              ("shadow", ch.CAST_SHADOW), ("albedo", ch.ALBEDO), ("relit", ch.RELIT)]
    plots = [(ch.CONVERGENCE_LABELS[k], f"{ch.CONVERGENCE}/{k}") for k in ch.CONVERGENCE_PLOTS]
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Grid(*[rrb.Spatial2DView(name=n, origin=f"/{p}", time_ranges=this_frame) for n, p in images]),
                rrb.Spatial3DView(name="surface", origin=f"/{ch.MESH}", time_ranges=this_frame),
                column_shares=[3, 2],
            ),
            rrb.Horizontal(
                *[rrb.TimeSeriesView(name=n, origin=f"/{p}") for n, p in plots],
                rrb.BarChartView(name="coefficients b", origin=f"/{ch.FIT_COEFFICIENTS}"),
            ),
            row_shares=[3, 2],
        ),
        collapse_panels=True,
    )
