"""Replay and diff of recordings, one module a job: a job's recordings read back (``jobs``), the
convergence table (``table``) and plot (``plot``), re-logging into Rerun (``relog``), and the
comparison of two runs (``diff``).

Face-agnostic: a "convergence" channel is any scalars channel with per-iteration values; the
caller names it, its table's columns and how re-logged arrays are shown (``nodes/app/record.py``).
"""
from .diff import Difference, DiffReport, diff_recordings, diff_streams
from .jobs import JobStream, open_frames, open_recording
from .plot import convergence_figure, plot_convergence
from .relog import relog_to_rerun
from .table import Column, ConvergenceRow, convergence_row, format_table
from .text import one_line, plot_label, printable

__all__ = ["Column", "ConvergenceRow", "DiffReport", "Difference", "JobStream", "convergence_figure",
           "convergence_row", "diff_recordings", "diff_streams", "format_table", "one_line", "open_frames",
           "open_recording", "plot_convergence", "plot_label", "printable", "relog_to_rerun"]
