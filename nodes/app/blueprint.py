"""How a run looks in the Rerun viewer: its default blueprint, and the run's Rerun sink with it.

Imports only the recording engine and ``rerun``: a recording process (``ProcessSinks``) makes
the sink from here without loading the method.
"""
from __future__ import annotations

from pathlib import Path

from ...flow.recording.rerun_sink import RerunSink


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
    images = [("input", "load/grid_image"), ("weights", "robust_fit/weights"), ("normals", "robust_fit/normals"),
              ("shadow", "shadow/cast"), ("albedo", "albedo/albedo"), ("relit", "relight/relit")]
    plots = [("sigma (radians)", "robust_fit/convergence/sigma"),
             ("mean change (degrees)", "robust_fit/convergence/change_deg"),
             ("mean residual (radians)", "robust_fit/convergence/residual_mean")]
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Grid(*[rrb.Spatial2DView(name=n, origin=f"/{p}", time_ranges=this_frame) for n, p in images]),
                rrb.Spatial3DView(name="surface", origin="/integrate/mesh", time_ranges=this_frame),
                column_shares=[3, 2],
            ),
            rrb.Horizontal(
                *[rrb.TimeSeriesView(name=n, origin=f"/{p}") for n, p in plots],
                rrb.BarChartView(name="coefficients b", origin="/robust_fit/b"),
            ),
            row_shares=[3, 2],
        ),
        collapse_panels=True,
    )
