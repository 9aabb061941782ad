"""Recordings read as a stream (issue 18 #11, #12): one frame held at a time, well-formed but
hostile content refused with one line naming the file, and no out-of-memory taken for a cut file."""
import json
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest
from mcap.writer import Writer
from shadowflow.flow.recording import Event, FrameStream, McapSink, RecordingError, read_mcap
from shadowflow.flow.recording import reader as reader_module
from shadowflow.flow.replay import diff_streams, open_frames

CLI = [sys.executable, "-m", "shadowflow.nodes.app.cli"]


def _recording(path, frames: int, side: int = 512, iterations: int = 3, seed: int = 0):
    """``frames`` frames of ``iterations`` (side, side) float32 arrays each, closed by their record."""
    rng = np.random.default_rng(seed)
    sink = McapSink(path)
    for f in range(frames):
        for it in range(1, iterations + 1):
            sink.write(Event(f, "fit/w", "array", rng.random((side, side), dtype=np.float32), it))
            sink.write(Event(f, "fit/convergence", "scalars", {"sigma": 1.0 / it, "residual_mean": 0.5 / it}, it))
        sink.write(Event(f, "frames", "frame", {"source": f"f{f}.png", "stem": f"f{f}", "status": "ok",
                                                "iterations": iterations}))
        sink.frame_done(f)
    sink.close()
    return path


def _peak(fn) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_stream_holds_one_frame_at_a_time(tmp_path):
    """Peak memory of reading a recording does not grow with its length; reading it whole does."""
    short = _recording(tmp_path / "short.mcap", frames=4)  # 3 MiB of arrays a frame
    long = _recording(tmp_path / "long.mcap", frames=16)
    assert sum(1 for _ in FrameStream(long)) == 16
    stream_short, stream_long = _peak(lambda: list(map(id, FrameStream(short)))), _peak(
        lambda: list(map(id, FrameStream(long))))
    whole_short, whole_long = _peak(lambda: read_mcap(short)), _peak(lambda: read_mcap(long))
    assert stream_long < 1.3 * stream_short, (stream_short, stream_long)
    assert whole_long > 2 * whole_short and whole_long > 2 * stream_long, (whole_short, whole_long)


def test_diff_of_two_streams_holds_one_frame_each(tmp_path):
    a = _recording(tmp_path / "a.mcap", frames=10)
    b = _recording(tmp_path / "b.mcap", frames=10)
    c = _recording(tmp_path / "c.mcap", frames=10, seed=1)
    report = diff_streams(open_frames(a), open_frames(b))
    assert report.differences == [] and report.frames == 10 and report.iterations == 30
    one = _peak(lambda: sum(1 for _ in FrameStream(a)))
    both = _peak(lambda: diff_streams(open_frames(a), open_frames(b)))
    assert both < 2.6 * one, (one, both)  # one frame of each file, not ten
    differ = diff_streams(open_frames(a), open_frames(c)).differences
    assert [(d.frame, d.iteration, d.channel) for d in differ[:2]] == [(0, 1, "fit/w"), (0, 2, "fit/w")]


def test_out_of_memory_is_never_read_as_a_cut_file(tmp_path, monkeypatch):
    path = _recording(tmp_path / "r.mcap", frames=3, side=8)
    calls = {"n": 0}
    real = reader_module.decode_array

    def decode_then_run_out(data, check_only=False):
        calls["n"] += 1
        if calls["n"] > 4:
            raise MemoryError
        return real(data, check_only)

    monkeypatch.setattr(reader_module, "decode_array", decode_then_run_out)
    with pytest.raises(RecordingError, match="out of memory.*not a truncated file"):
        list(FrameStream(path))


def _mcap(path, messages):
    """An MCAP of JSON messages [(topic, body)], well-formed as MCAP."""
    with open(path, "wb") as fh:
        w = Writer(fh)
        w.start()
        sid = w.register_schema("shadowflow.Scalars", "jsonschema", b"{}")
        chans = {}
        for k, (topic, body) in enumerate(messages):
            if topic not in chans:
                chans[topic] = w.register_channel(topic, "json", sid)
            data = body if isinstance(body, bytes) else json.dumps(body).encode()
            w.add_message(chans[topic], log_time=k, data=data, publish_time=k)
        w.finish()
    return path


@pytest.mark.parametrize("name, messages", [
    ("infinite-frame", [("/fit/convergence", b'{"frame": Infinity, "iteration": 1, "values": {"sigma": 1}}')]),
    ("word-iteration", [("/fit/convergence", {"frame": 0, "iteration": "one", "values": {"sigma": 1}})]),
    ("list-scalar", [("/fit/convergence", {"frame": 0, "iteration": 1, "values": {"sigma": [1, 2]}})]),
    ("bool-frame", [("/fit/convergence", {"frame": True, "iteration": 1, "values": {"sigma": 1}})]),
    ("list-body", [("/fit/convergence", [1, 2, 3])]),
    ("record-not-object", [("/frames", {"frame": 0, "values": "done"})]),
])
def test_well_formed_hostile_recordings_exit_2_naming_the_file(tmp_path, name, messages):
    path = _mcap(tmp_path / f"{name}.mcap", messages)
    for cmd in (["replay", str(path), "--plot", str(tmp_path / "p.png")], ["diff", str(path), str(path)]):
        proc = subprocess.run(CLI + cmd, capture_output=True, text=True, timeout=60)
        assert proc.returncode == 2, (cmd, proc.stdout, proc.stderr)
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and f"{name}.mcap" in lines[0] and "Traceback" not in proc.stderr


def test_null_scalars_and_odd_records_still_replay_and_plot(tmp_path):
    path = _mcap(tmp_path / "odd.mcap", [
        ("/robust_fit/convergence", {"frame": 0, "iteration": 1, "values": {"sigma": None, "residual_mean": 0.5}}),
        ("/robust_fit/convergence", {"frame": 0, "iteration": 2, "values": {"sigma": 0.1, "residual_mean": None}}),
        ("/frames", {"frame": 0, "values": {"source": "x.png", "iterations": "two", "converged": "yes"}}),
    ])
    proc = subprocess.run(CLI + ["replay", str(path), "--plot", str(tmp_path / "p.png")], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    row = proc.stdout.splitlines()[1].split()
    assert row[:3] == ["0", "2", "0.1"] and (tmp_path / "p.png").stat().st_size > 1000


def test_the_convergence_plot_has_units_a_legend_and_the_recorded_values():
    from shadowflow.flow.replay import convergence_figure

    series = [("a.png", {1: {"sigma": 0.2, "res": -0.1}, 2: {"sigma": None, "res": 0.05}, 3: {"sigma": 0.05, "res": 0.0}}),
              ("b.png", {1: {"sigma": 0.4, "res": 0.3}, 2: {"sigma": float("nan"), "res": 0.2}})]
    fig = convergence_figure(series, ("sigma", "res"), {"sigma": "robust scale (radians)"})
    sigma, res = fig.axes[:2]
    assert sigma.get_title() == "robust scale (radians)" and res.get_title() == "res"
    assert sigma.get_yscale() == "log" and res.get_yscale() == "linear"  # a negative value: no log scale
    assert [t.get_text() for t in res.get_legend().get_texts()] == ["a.png", "b.png"]
    (xa, ya), (xb, yb) = [ln.get_data() for ln in sigma.get_lines()]
    assert list(xa) == [1, 3] and list(ya) == [0.2, 0.05] and list(xb) == [1] and list(yb) == [0.4]
    crowd = [(f"f{k}", {1: {"sigma": 1.0 + k}, 2: {"sigma": 0.5 + k}}) for k in range(20)]
    many = convergence_figure(crowd, ("sigma",), legend_max=12)
    # 20 thin grey lines and their median, not 20 labels
    assert [t.get_text() for t in many.axes[0].get_legend().get_texts()] == ["median of 20"]
    median = many.axes[0].get_lines()[-1]
    assert list(median.get_data()[0]) == [1, 2] and list(median.get_data()[1]) == [10.5, 10.0]
    odd = convergence_figure(crowd, ("sigma",), legend_max=12, highlight={"f3", "f17"})
    # the odd frames in colour and named, beside the crowd's median
    assert [t.get_text() for t in odd.axes[0].get_legend().get_texts()] == ["f3", "f17", "median of 20"]


def test_the_convergence_plot_marks_the_flagged_iterations_on_every_panel():
    """A scalar that flags an iteration (``marks``) draws an open circle on each frame's line there, on every
    panel, and names it once in the legend; in a crowd, on the grey lines too, the legend the median's and the
    mark's. Frames that never flag it get none."""
    from shadowflow.flow.replay import convergence_figure

    a = {i: {"sigma": 1.0 / i, "change": 5.0 if i == 3 else 0.1, "round": float(i == 3)} for i in range(1, 6)}
    b = {i: {"sigma": 2.0 / i, "change": 0.2, "round": 0.0} for i in range(1, 4)}
    fig = convergence_figure([("a.png", a), ("b.png", b)], ("sigma", "change"), marks={"round": "albedo again"})
    for ax in fig.axes[:2]:
        circles = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
        assert len(circles) == 1 and list(circles[0].get_xdata()) == [3]
    assert list(fig.axes[1].get_lines()[-1].get_ydata()) == [5.0]
    assert [t.get_text() for t in fig.axes[1].get_legend().get_texts()] == ["a.png", "b.png", "albedo again"]
    plain = convergence_figure([("b.png", b)], ("sigma",), marks={"round": "albedo again"})
    assert [t.get_text() for t in plain.axes[0].get_legend().get_texts()] == ["b.png"]
    crowd = [(f"f{k}", a) for k in range(20)]
    many = convergence_figure(crowd, ("sigma",), legend_max=12, marks={"round": "albedo again"})
    assert sum(ln.get_marker() == "o" for ln in many.axes[0].get_lines()) == 20
    assert [t.get_text() for t in many.axes[0].get_legend().get_texts()] == ["median of 20", "albedo again"]
