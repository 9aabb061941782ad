"""Sinks in a recording process of their own (``ProcessSinks``) and the messages sent to it (``wire``)."""
import numpy as np
import pytest
from shadowflow.flow.recording import Event, Kind, McapSink, OnMask, ProcessSinks, Recorder, read_mcap
from shadowflow.flow.recording import wire
from shadowflow.flow.recording.process import child_environment


def _events(rng: np.random.Generator) -> list[Event]:
    """Two frames of every kind a run records: face-pixel images and normals per iteration, dense
    arrays of odd byte counts, scalars with NaN, a mesh and the frame's record."""
    mask = rng.random((9, 7)) < 0.6
    other = rng.random((5, 3)) < 0.5
    out = []
    for f in range(2):
        for it in range(1, 4):
            n = rng.standard_normal((int(mask.sum()), 3)).astype(np.float32)
            out += [Event(f, "fit/normals", Kind.NORMALS, OnMask(n, mask), it),
                    Event(f, "fit/weights", Kind.IMAGE, OnMask(rng.random(int(mask.sum())).astype(np.float32), mask), it),
                    Event(f, "fit/b", Kind.ARRAY, rng.standard_normal(5), it),
                    Event(f, "fit/convergence", Kind.SCALARS, {"sigma": np.float32(0.25 / it), "change": float("nan")}, it)]
        out += [Event(f, "other/image", Kind.IMAGE, OnMask(rng.random(int(other.sum())).astype(np.float32), other)),
                Event(f, "integrate/depth", Kind.DEPTH, rng.random((9, 7)).astype(np.float64)),
                Event(f, "integrate/mesh", Kind.MESH, {"vertices": rng.random((4, 3)).astype(np.float32),
                                                        "triangles": np.array([[0, 1, 2], [1, 2, 3]], np.int32),
                                                        "colours": np.full((4, 3), 200, np.uint8)}),
                Event(f, "frames", Kind.FRAME, {"stem": f"face {f}", "status": "ok", "iterations": np.int64(3)})]
    return out


def _record(sinks, events) -> None:
    rec = Recorder(sinks)
    named = set()
    for e in events:
        if e.frame not in named:  # as a run names its frames (by input stem) before their events
            rec.name_frame(e.frame, f"face {e.frame}")
            named.add(e.frame)
        if e.kind is Kind.FRAME:
            rec.frame_done(e.frame, e.value, wait=True)
        else:
            rec.emit(e)
    rec.close()


def test_a_recording_process_writes_the_same_file_as_the_recorder_thread(tmp_path):
    """The same events through the child process and through the in-process sink give a
    byte-identical MCAP (masks sent once and named by key, arrays of every dtype and size,
    NaN scalars, frame records); a Rerun sink made there by name writes its .rrd too."""
    from shadowflow.nodes.app.blueprint import rerun_sink

    events = _events(np.random.default_rng(0))
    _record([McapSink(tmp_path / "thread.mcap")], events)
    child = ProcessSinks([(McapSink, (str(tmp_path / "child.mcap"),), {}),
                          (rerun_sink, (str(tmp_path / "child.rrd"),), {})], max_masks=1)  # masks evicted and resent
    _record([child], events)
    assert (tmp_path / "child.mcap").read_bytes() == (tmp_path / "thread.mcap").read_bytes()
    assert child.paths == [tmp_path / "child.mcap", tmp_path / "child.rrd"]
    rec = read_mcap(tmp_path / "child.mcap")
    assert [fr.record["stem"] for fr in rec.finished_frames()] == ["face 0", "face 1"]
    rc = pytest.importorskip("rerun.chunk")
    summary = str(rc.RrdReader(tmp_path / "child.rrd").stream().collect().summary())
    for f in range(2):
        assert f"/fit/weights/face\\ {f} rows=3" in summary and f"/integrate/mesh/face\\ {f} rows=1" in summary


def test_a_sink_failing_in_the_recording_process_is_reported_to_the_run(tmp_path):
    """A sink that cannot be made (its folder is missing) fails the recording with the sink's own
    message, raised where the run closes its recorder; the child process ends."""
    child = ProcessSinks([(McapSink, (str(tmp_path / "missing" / "run.mcap"),), {})])
    rec = Recorder([child])
    rec.emit(Event(0, "fit/b", Kind.ARRAY, np.zeros(3)))
    rec.frame_done(0, {"stem": "a"}, wait=True)
    assert "No such file or directory" in str(rec.error) and "missing" in str(rec.error)
    with pytest.raises(RuntimeError, match="No such file"):
        rec.close()
    assert child._proc.poll() is not None


def test_the_recording_process_returns_freed_memory_at_once_unless_told_otherwise():
    """The child's allocator is told to give freed pages back at once (mimalloc, under Rerun's
    bindings: otherwise its RSS saws by tens of MiB on a long run); a user's own setting wins."""
    env = child_environment({"HOME": "/h"})
    assert env["MIMALLOC_PURGE_DELAY"] == "0" and env["HOME"] == "/h" and "PYTHONPATH" in env
    assert child_environment({"MIMALLOC_PURGE_DELAY": "250"})["MIMALLOC_PURGE_DELAY"] == "250"


def test_a_renewed_recording_process_goes_on_in_the_next_files_of_one_recording(tmp_path):
    """The Rerun SDK keeps something for every entity path a process has logged, whatever stream
    it was (the soak's recording process grew about 20 kB a frame): ``renewed_sink`` makes the
    sink anew in a fresh process every ``every`` frames. Over 5 frames at 2 a process: three
    processes, one after the other, and the files of one recording, each frame in exactly one."""
    rc = pytest.importorskip("rerun.chunk")
    from conftest import rrd_rows
    from shadowflow.flow.recording.process import renewed_sink

    sink = renewed_sink("shadowflow.flow.recording.rerun_sink:RerunSink", [str(tmp_path / "run.rrd")],
                        {"segment_frames": 1, "recording_id": "one"}, 2)
    pids = []
    for frame in range(5):
        pids.append(sink._proc.pid)
        sink.name_frame(frame, f"face{frame}")
        for it in (1, 2):
            sink.write(Event(frame, "fit/w", Kind.IMAGE, np.full((4, 4), frame + it / 10, np.float32), it))
        sink.frame_done(frame)
    sink.name_frame(5, "face5")  # a frame under way when the process is renewed keeps its name
    sink.name_frame(6, "face6")
    sink.frame_done(6)  # the sixth frame done: renewed
    sink.write(Event(5, "fit/w", Kind.IMAGE, np.full((4, 4), 5.1, np.float32), 1))
    sink.frame_done(5)
    sink.close()
    assert pids[0] == pids[1] != pids[2] == pids[3] != pids[4] and pids[0] != pids[4]
    names = ["run.rrd"] + [f"run.s{k}.rrd" for k in range(2, 8)]  # frame 6 in s6, frame 5 after the renewal
    assert [p.name for p in sink.paths] == names and sorted(p.name for p in tmp_path.iterdir()) == sorted(names)
    assert sorted(rrd_rows(sink.paths[-1], "/fit/w/face5", "Image:buffer")) == [1]
    assert not rrd_rows(sink.paths[-1], "/fit/w/00005", "Image:buffer")
    for frame, path in enumerate(sink.paths[:5]):
        assert [e.recording_id for e in rc.RrdReader(path).recordings()] == ["one"]
        for other in range(5):
            rows = rrd_rows(path, f"/fit/w/face{other}", "Image:buffer")
            assert sorted(rows) == ([1, 2] if other == frame else []), (path.name, other)


def test_wire_messages_round_trip_without_pickle():
    """Header, nested values, arrays of odd sizes (padded to 8 bytes, read back aligned), masks by
    key; a message whose header does not account for its bytes is refused."""
    rng = np.random.default_rng(1)
    mask = rng.random((4, 5)) < 0.5
    value = {"a": rng.random(3).astype(np.float16), "b": [np.arange(7, dtype=np.uint8), {"c": np.float64(2.5)}],
             "d": OnMask(rng.random((int(mask.sum()), 3)).astype(np.float32), mask), "e": float("nan"), "f": None}
    data = wire.encode({"op": "event", "frame": 3}, value, lambda m: 7)
    assert len(data) % 8 == 0
    back = wire.decode(data, {7: mask})
    assert back["op"] == "event" and back["frame"] == 3
    v = back["value"]
    assert np.array_equal(v["a"], value["a"]) and v["a"].dtype == np.float16
    assert np.array_equal(v["b"][0], value["b"][0]) and v["b"][1] == {"c": 2.5} and v["f"] is None
    assert v["d"].mask is mask and np.array_equal(v["d"].values, value["d"].values) and np.isnan(v["e"])
    assert all(a.flags.aligned for a in (v["a"], v["b"][0], v["d"].values))
    with pytest.raises(ValueError, match="accounts for"):
        wire.decode(data + bytes(8), {7: mask})
