"""``shadowflow replay`` and ``shadowflow diff``: a recording's convergence table, plot and re-logging; two recordings compared."""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from ....flow.replay.text import one_line
from ....flow.replay import (
    convergence_row,
    diff_streams,
    format_table,
    open_frames,
    plot_convergence,
    relog_to_rerun,
)
from ..blueprint import default_blueprint
from ..channels import CONVERGENCE, CONVERGENCE_LABELS, CONVERGENCE_MARKS, CONVERGENCE_PLOTS
from ..outputs import real_path
from ..record import (
    CONVERGENCE_TABLE,
    DISPLAY_KINDS,
    RELOG_LEFT_OUT,
    frame_name,
    frame_source,
    stage_rank,
)


def _same_file(a: Path, b: Path) -> bool:
    """Whether two paths name one file: one inode, whatever the names (a symbolic or a hard link)."""
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def _refuse_overwriting_the_recording(target: Path, recording: Path, flag: str) -> None:
    """``ValueError`` when ``replay --rrd`` or ``--plot`` (``flag``) would write over the recording it reads:
    the file given, its MCAP twin, or in a run's folder any file of it, by any name that reaches it (a hard
    link too); or into something that is not a file (a pipe would never let the write end)."""
    sources = [recording, recording.with_suffix(".mcap")]
    if recording.is_dir():
        sources += [p for p in recording.iterdir()]
    if real_path(target) in {real_path(s) for s in sources} or any(_same_file(target, s) for s in sources):
        raise ValueError(f"{flag} {target}: is the recording being read (or a file of its run); write it elsewhere")
    if target.exists() and not target.is_file():
        raise ValueError(f"{flag} {target}: is not a regular file; name a file to write")


def cmd_replay(args: argparse.Namespace) -> int:

    for flag, target in (("--rrd", args.rrd), ("--plot", args.plot)):
        if target:
            _refuse_overwriting_the_recording(Path(target), Path(args.recording), flag)
    stream = open_frames(args.recording, arrays=bool(args.rrd))  # one frame in memory at a time
    rows, series = [], []

    def tap(frames):
        for fr in frames:
            rows.append(convergence_row(fr, CONVERGENCE, CONVERGENCE_TABLE))
            if args.plot:  # a plot needs every frame's curves; a table only its row
                series.append((frame_name(fr), fr.scalars.get(CONVERGENCE, {})))
            yield fr

    if args.rrd:
        relog_to_rerun(tap(stream), args.rrd, DISPLAY_KINDS, default_blueprint(), RELOG_LEFT_OUT)
    else:
        for _ in tap(stream):
            pass
    print(format_table(sorted(rows, key=lambda r: r.frame), CONVERGENCE_TABLE))
    if stream.truncated:
        print(one_line(f"note: {args.recording} ends early (a killed run?); shown: everything before the cut"))
    if args.plot:
        plot = plot_convergence(series, args.plot, CONVERGENCE_PLOTS, CONVERGENCE_LABELS, marks=CONVERGENCE_MARKS)
        print(one_line(f"plot: {plot}"))
    if args.rrd:
        print(one_line(f"rerun: {args.rrd}"))
    return 0


def cmd_diff(args: argparse.Namespace) -> int:

    # frames pair by their input's path (two inputs may share a file name), then by its file name (a run over
    # copies of the inputs elsewhere)
    report = diff_streams(open_frames(args.a), open_frames(args.b), args.atol, args.rtol, key=frame_source,
                          stage=stage_rank, fallback=frame_name)
    if not report.differences:
        print(f"same: {report.frames} frames, {report.iterations} iterations within atol={args.atol:g} "
              f"rtol={args.rtol:g}")
        return 0
    diffs = report.differences
    first = diffs[0]
    it = "-" if first.iteration is None else first.iteration
    print(one_line(f"first divergence: frame {first.frame}, iteration {it}, channel {first.channel}: "
                   f"{first.what}, max |difference| {first.max_abs:.6g}"))
    frames = {str(d.frame) for d in diffs}
    channels = sorted({d.channel for d in diffs})
    print(one_line(f"{len(diffs)} differing items in {len(frames)} frame(s) over channel(s): {', '.join(channels)}"))
    return 1


def add_parsers(sub) -> None:
    """``shadowflow replay``'s and ``shadowflow diff``'s arguments."""
    rp = sub.add_parser("replay", help="convergence table / plot / re-log to Rerun of a recording")
    rp.add_argument("recording", help="run.mcap, or a run's --out folder (its parts merged)")
    rp.add_argument("--plot", metavar="PNG", help="write a convergence plot")
    rp.add_argument("--rrd", metavar="RRD", help="re-log the recording into a Rerun file")
    rp.set_defaults(func=cmd_replay)

    d = sub.add_parser("diff", help="compare two recordings; exit 0 same, 1 different, 2 unreadable")
    d.add_argument("a", help="run.mcap, or a run's --out folder (a resumed run's parts merged)")
    d.add_argument("b", help="the recording to compare A with (a file or a folder, as A)")
    d.add_argument("--atol", type=float, default=0.0, help="absolute tolerance: equal when |a - b| <= atol + rtol |b|")
    d.add_argument("--rtol", type=float, default=0.0, help="relative tolerance (see --atol)")
    d.set_defaults(func=cmd_diff)
