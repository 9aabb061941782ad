"""The recording package: the array message, typed events, the Rerun sink's batches."""
import json

import numpy as np
import pytest
from conftest import rrd_rows
from shadowflow.flow.recording import Event, encode_array


def test_masked_array_messages_round_trip_and_refuse_bad_payloads():
    """A masked message (bit mask + face values) reads back as the full grid, NaN off the mask,
    and is a quarter of the dense one's size at a typical face coverage."""
    import struct

    from shadowflow.flow.recording import OnMask, decode_array

    rng = np.random.default_rng(3)
    mask = rng.random((128, 128)) < 0.26
    values = rng.standard_normal((int(mask.sum()), 3)).astype(np.float32)
    data = encode_array(4, 2, values, mask)
    header, grid = decode_array(data)
    expect = OnMask(values, mask).grid()
    assert header["shape"] == [128, 128, 3] and grid.dtype == np.float32
    assert np.array_equal(np.isnan(grid), np.isnan(expect)) and np.array_equal(grid[mask], values)
    assert len(data) < 0.3 * len(encode_array(4, 2, expect))
    _, ints = decode_array(encode_array(0, None, np.arange(mask.sum(), dtype=np.int32), mask))
    assert ints[~mask].max() == 0 and np.array_equal(ints[mask], np.arange(mask.sum()))
    hlen = struct.unpack("<I", data[4:8])[0]
    head, body = data[:8 + hlen], data[8 + hlen:]
    with pytest.raises(ValueError, match="values are"):
        decode_array(head + body[:-12])  # a pixel short
    with pytest.raises(ValueError, match="mask alone"):
        decode_array(head + body[:100])  # cut inside the mask
    flat = json.dumps({"frame": 0, "iteration": 1, "dtype": "<f4", "shape": [16], "masked": True}).encode()
    with pytest.raises(ValueError, match="bad array header"):
        decode_array(b"SFA1" + struct.pack("<I", len(flat)) + flat + b"\x00" * 8)


def test_events_are_typed():
    """An event's kind is a ``Kind``; a misspelt kind fails where the event is made, not in a sink
    on the recorder's thread."""
    from shadowflow.flow.recording import Kind

    assert Event(0, "a/b", "image", np.zeros((2, 2))).kind is Kind.IMAGE
    with pytest.raises(ValueError, match="imgae"):
        Event(0, "a/b", "imgae", np.zeros((2, 2)))


def test_rerun_batches_flush_mid_frame_and_take_dense_arrays_too(tmp_path):
    """More iterations than one batch holds, of a face-pixel image and of a dense one (as
    ``replay --rrd`` sends them), and a frame closed by ``close`` alone: every row reaches the
    .rrd at its iteration with its own values."""
    from shadowflow.flow.recording import OnMask, RerunSink

    rng = np.random.default_rng(4)
    mask = rng.random((6, 5)) < 0.6
    faces = {it: rng.random(int(mask.sum())).astype(np.float32) for it in range(1, 8)}
    grids = {it: rng.random((6, 5)).astype(np.float32) for it in range(1, 8)}
    sink = RerunSink(tmp_path / "b.rrd", batch=3)
    for it in range(1, 8):
        sink.write(Event(0, "fit/weights", "image", OnMask(faces[it], mask), it))
        sink.write(Event(0, "fit/residuals", "array", grids[it], it))
        sink.write(Event(1, "fit/weights", "image", OnMask(faces[it], mask), it))
    sink.frame_done(0)
    sink.close()  # frame 1 was never closed: its held rows are written at close
    for frame, path, expect in ((0, "weights", lambda it: OnMask(faces[it], mask).grid(0)),
                                (0, "residuals", lambda it: grids[it]),
                                (1, "weights", lambda it: OnMask(faces[it], mask).grid(0))):
        rows = rrd_rows(tmp_path / "b.rrd", f"/fit/{path}/{frame:05d}", "Image:buffer")
        assert sorted(rows) == list(range(1, 8)), (frame, path)
        for it, buf in rows.items():
            assert np.array_equal(np.frombuffer(bytes(buf[0]), np.float32).reshape(6, 5), expect(it)), (frame, path, it)


def test_the_rerun_sink_holds_at_most_its_bound_of_rows_whatever_frames_are_in_flight(tmp_path):
    """A run's pipeline has several frames in its fit at once; their per-iteration rows are held
    until each frame ends, so without a bound the recording process held as much as the timing
    put in flight. Five frames interleaved, none closed until the end, a bound of three rows:
    never more than three rows held, and every row still reaches the file with its values."""
    from shadowflow.flow.recording import OnMask, RerunSink

    rng = np.random.default_rng(7)
    mask = rng.random((6, 5)) < 0.6
    values = {(f, it): rng.random(int(mask.sum())).astype(np.float32) for f in range(5) for it in range(1, 7)}
    row = values[0, 1].nbytes
    sink = RerunSink(tmp_path / "b.rrd", max_held_bytes=3 * row)
    held = []
    for it in range(1, 7):
        for f in range(5):
            sink.write(Event(f, "fit/weights", "image", OnMask(values[f, it], mask), it))
            held.append(sink.held_bytes)
    for f in range(5):
        sink.frame_done(f)
    sink.close()
    assert max(held) == 3 * row and sink.held_bytes == 0
    for f in range(5):
        rows = rrd_rows(tmp_path / "b.rrd", f"/fit/weights/{f:05d}", "Image:buffer")
        assert sorted(rows) == list(range(1, 7)), f
        for it, buf in rows.items():
            got = np.frombuffer(bytes(buf[0]), np.float32).reshape(6, 5)
            assert np.array_equal(got, OnMask(values[f, it], mask).grid(0)), (f, it)


def test_a_long_rerun_recording_goes_on_in_segments_of_one_recording(tmp_path):
    """The Rerun SDK keeps a few kB per entity path while a stream lives (RSS grew 290 -> 460 MiB
    over 2,000 frames): every ``segment_frames`` frames the sink starts a new file of the same
    recording, and every frame's rows are in exactly one of them."""
    rc = pytest.importorskip("rerun.chunk")
    from shadowflow.flow.recording import RerunSink

    sink = RerunSink(tmp_path / "run.rrd", segment_frames=2)
    for frame in range(5):
        for it in (1, 2):
            sink.write(Event(frame, "fit/w", "image", np.full((4, 4), frame + it / 10, np.float32), it))
        sink.write(Event(frame, "frames", "frame", {"source": f"f{frame}"}))
        sink.frame_done(frame)
    sink.close()
    names = [p.name for p in sink.paths]
    assert names == ["run.rrd", "run.s2.rrd", "run.s3.rrd"] and sorted(p.name for p in tmp_path.iterdir()) == sorted(names)
    found = {}
    for path in sink.paths:
        assert [e.recording_id for e in rc.RrdReader(path).recordings()] == [sink.recording_id]
        for frame in range(5):
            rows = rrd_rows(path, f"/fit/w/{frame:05d}", "Image:buffer")
            if rows:
                assert frame not in found
                found[frame] = (path.name, sorted(rows))
    assert found == {0: ("run.rrd", [1, 2]), 1: ("run.rrd", [1, 2]), 2: ("run.s2.rrd", [1, 2]),
                     3: ("run.s2.rrd", [1, 2]), 4: ("run.s3.rrd", [1, 2])}


def test_the_scalars_tap_keeps_one_channel_for_the_first_frames_by_name():
    """What a run's report plots without reading its recording back: the channel's scalars by
    iteration, for the first ``limit`` frames that have any, named by their record's file name."""
    from shadowflow.flow.recording import ScalarsTap

    tap = ScalarsTap("fit/convergence", limit=2)
    for frame in (3, 1, 2):
        for it in (1, 2):
            tap.write(Event(frame, "fit/convergence", "scalars", {"sigma": frame + it / 10}, it))
            tap.write(Event(frame, "fit/other", "scalars", {"sigma": -1.0}, it))
        tap.write(Event(frame, "frames", "frame", {"source": f"/in/f{frame}.png", "status": "ok"}))
    assert tap.series() == [("f1.png", {1: {"sigma": 1.1}, 2: {"sigma": 1.2}}),
                            ("f3.png", {1: {"sigma": 3.1}, 2: {"sigma": 3.2}})]


def test_a_long_mcap_recording_holds_no_per_channel_index_in_memory(tmp_path):
    """The MCAP writer keeps every chunk's index until the file ends (a chunk a frame): with each
    channel's message offsets in it, 40 channels held about 2.9 kB a frame; the chunk index alone
    is under 1 kB, and the file still reads back frame by frame."""
    import tracemalloc

    from shadowflow.flow.recording import Kind, McapSink, read_mcap

    sink = McapSink(tmp_path / "long.mcap")

    def frame(f: int) -> None:
        for it in range(1, 3):
            for c in range(40):
                sink.write(Event(f, f"node/c{c}", Kind.ARRAY, np.full(4, f, np.float32), it))
        sink.write(Event(f, "frames", Kind.FRAME, {"stem": f"f{f}"}))
        sink.frame_done(f)

    for f in range(20):
        frame(f)
    tracemalloc.start()
    before = tracemalloc.take_snapshot()
    for f in range(20, 320):
        frame(f)
    grown = sum(d.size_diff for d in tracemalloc.take_snapshot().compare_to(before, "filename")) / 300
    tracemalloc.stop()
    sink.close()
    assert grown < 1000, f"{grown:.0f} bytes a frame"
    rec = read_mcap(tmp_path / "long.mcap")
    assert len(rec.finished_frames()) == 320
    assert rec.finished_frames()[317].iterations("node/c39") == [1, 2]
