"""Recordings: completeness, thinning, Rerun can open them, replay, diff, golden runs, kill -9."""
import json
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import rrd_rows
from shadowflow.flow.manifest import RunManifest
from shadowflow.flow.recording import Event, McapSink, RecordingError, RecordOptions, encode_array, read_mcap
from shadowflow.flow.replay import diff_recordings
from shadowflow.nodes.app.outputs import OUTPUT_FILES

from conftest import run_cli

REPO = Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-m", "shadowflow.nodes.app.cli"]
sys.path.insert(0, str(REPO / "recordings"))
from make_golden import GOLDEN, golden_inputs, golden_model, golden_run  # noqa: E402


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """A recorded run of the built-in demo (3 faces), both formats."""
    out = tmp_path_factory.mktemp("rec")
    proc = run_cli(["run", "--demo", "--out", out, "--quiet"])
    assert proc.returncode == 0, proc.stderr
    return out


def _rewrite(src: Path, dst: Path, change) -> None:
    """Copy a recording, applying ``change(topic, header, array) -> array | None`` to arrays."""
    from mcap.reader import make_reader
    from shadowflow.flow.recording import decode_array

    sink = McapSink(dst)
    with open(src, "rb") as f:
        for schema, channel, msg in make_reader(f).iter_messages():
            data = msg.data
            if channel.message_encoding == "shadowflow.ndarray":
                header, arr = decode_array(data)
                new = change(channel.topic, header, arr)
                if new is not None:
                    data = encode_array(header["frame"], header["iteration"], new)
            sink._add(channel.topic, schema.name, channel.message_encoding,
                      Event(0, "", "array", None), data)
    sink.close()


def _golden_copies(src: Path, n: int) -> None:
    """``n`` inputs in ``src``: copies of the two golden faces (with their sidecar lights)."""
    base = golden_inputs(src)
    for k in range(n):
        p = Path(base[k % 2])
        shutil.copy(p, src / f"face-{k:02d}.png")
        shutil.copy(p.with_suffix(".json"), src / f"face-{k:02d}.json")
    for p in base:
        Path(p).unlink()
        Path(p).with_suffix(".json").unlink()


def _done(out: Path) -> list[dict]:
    """The records of the frames a run in ``out`` has finished so far (its manifest and journal)."""
    man = RunManifest.load(out)
    return [] if man is None else [e.record for e in sorted(man.entries.values(), key=lambda e: e.frame)]


def _wait_for_records(out: Path, n: int, timeout: float = 120.0) -> None:
    """Wait until the run in ``out`` has finished at least ``n`` frames."""
    deadline = time.time() + timeout
    while time.time() < deadline and len(_done(out)) < n:
        time.sleep(0.05)


def _children(pid: int) -> list[int]:
    """The child processes of ``pid`` (Linux)."""
    return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]


def _alive(pid: int) -> bool:
    """Running (a zombie nobody has reaped yet counts as ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _wait_gone(pids: list[int], timeout: float = 60.0) -> None:
    deadline = time.time() + timeout
    while time.time() < deadline and any(_alive(p) for p in pids):
        time.sleep(0.05)
    assert not any(_alive(p) for p in pids), "the recording process outlived its run"


def test_every_iteration_of_every_frame_is_recorded(demo):
    rec = read_mcap(demo / "run.mcap")
    summary = json.loads((demo / "summary.json").read_text())
    assert not rec.truncated and len(rec.finished_frames()) == len(summary) == 3
    for fr, s in zip(rec.finished_frames(), summary):
        n = s["iterations"]
        for ch in ("robust_fit/normals", "robust_fit/weights", "robust_fit/residuals", "robust_fit/b",
                   "robust_fit/convergence"):
            assert fr.iterations(ch) == list(range(1, n + 1)), ch
        w = fr.arrays["robust_fit/weights"][n]
        assert w.dtype == np.float32 and w.shape == (128, 128)
        assert np.array_equal(np.isnan(w), ~np.isfinite(fr.arrays["integrate/depth"][None]))
        assert fr.record["status"] == "ok" and fr.record["source"] == s["source"]
        for per_frame in ("load/grid_image", "combine/normals", "integrate/depth", "albedo/albedo",
                          "relight/relit", "integrate/mesh/vertices"):
            assert None in fr.arrays[per_frame], per_frame


def test_the_final_weights_recorded_are_the_ones_written(demo):
    rec = read_mcap(demo / "run.mcap")
    fr = rec.finished_frames()[0]
    last = fr.iterations("robust_fit/weights")[-1]
    grid_w = fr.arrays["robust_fit/weights"][last]
    out_w = np.load(demo / fr.record["stem"] / "weights.npy")
    # the output is on the input grid (same size for the demo): same values where both exist
    both = np.isfinite(grid_w) & np.isfinite(out_w)
    assert both.sum() > 3000 and np.max(np.abs(grid_w[both] - out_w[both])) < 0.05


def test_rerun_opens_both_recordings(demo):
    rc = pytest.importorskip("rerun.chunk")
    summary = str(rc.RrdReader(demo / "run.rrd").store().summary())
    stems = [r["stem"] for r in json.loads((demo / "summary.json").read_text())]
    import rerun as rr

    part = rr.escape_entity_path_part(stems[2])  # a stem keeps "+": the entity path escapes it
    assert f"/robust_fit/weights/{part}" in summary and "iteration" in summary  # named by input
    assert f"/integrate/mesh/{rr.escape_entity_path_part(stems[0])}" in summary and "Mesh3D" in summary
    assert "/00000" not in summary
    info = rc.McapReader(demo / "run.mcap").info()
    topics = {c.topic for c in info.channels}
    assert "/robust_fit/weights" in topics and "/load/grid_image/foxglove" in topics
    iterations = sum(s["iterations"] for s in json.loads((demo / "summary.json").read_text()))
    assert info.message_count > 6 * iterations  # six per-iteration channels, plus the per-frame ones


def test_rerun_holds_every_iteration_as_the_mcap_records_it(demo):
    """The .rrd's per-iteration rows (sent in columns, a frame at a time) show exactly the MCAP's
    arrays: weights as float images with 0 off the face, normals as (n + 1) * 127.5 RGB,
    sigma as a scalar, at the same iterations, and the coefficients of the last one as a bar chart."""
    rec = read_mcap(demo / "run.mcap")
    fr = rec.finished_frames()[1]
    its = fr.iterations("robust_fit/weights")
    stem = fr.record["stem"]
    import rerun as rr

    part = rr.escape_entity_path_part(stem)  # a stem keeps "+": the entity path escapes it
    weights = rrd_rows(demo / "run.rrd", f"/robust_fit/weights/{part}", "Image:buffer")
    normals = rrd_rows(demo / "run.rrd", f"/robust_fit/normals/{part}", "Image:buffer")
    b = rrd_rows(demo / "run.rrd", f"/robust_fit/b/{part}", "BarChart:values")
    sigma = rrd_rows(demo / "run.rrd", f"/robust_fit/convergence/sigma/{part}", "Scalars:scalars")
    assert sorted(weights) == sorted(normals) == sorted(sigma) == its and len(its) >= 3
    assert sorted(b) == [its[-1]]  # the coefficients: the frame's last iteration (every one is in the MCAP)
    for it in its:
        w = np.frombuffer(bytes(weights[it][0]), np.float32).reshape(128, 128)
        assert np.array_equal(w, np.nan_to_num(fr.arrays["robust_fit/weights"][it]))
        n = np.frombuffer(bytes(normals[it][0]), np.uint8).reshape(128, 128, 3)
        expect = ((np.nan_to_num(fr.arrays["robust_fit/normals"][it]) + 1) * 127.5).clip(0, 255).astype(np.uint8)
        assert np.array_equal(n, expect)
        if it in b:
            assert b[it][0]["shape"] == [fr.arrays["robust_fit/b"][it].size]
            assert np.allclose(b[it][0]["buffer"], fr.arrays["robust_fit/b"][it], rtol=0, atol=1e-7)
        assert sigma[it] == [pytest.approx(fr.scalars["robust_fit/convergence"][it]["sigma"], rel=1e-12)]


def test_foxglove_copies_decode_with_the_files_own_protobuf_schemas(demo):
    """Each image's copy is a foxglove.RawImage decoded, as Foxglove does, from the protobuf
    schema stored in the file (no generated code): weights mono8 = the exact array (0 off the
    face) at every iteration, normals rgb8 = (n + 1) * 127.5, depth 32FC1 = the exact depth.
    Rerun's own MCAP reader takes them as images."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    rec = read_mcap(demo / "run.mcap")
    seen = {}
    with open(demo / "run.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for schema, channel, msg, img in reader.iter_decoded_messages(topics=[
                "/robust_fit/weights/foxglove", "/combine/normals/foxglove", "/integrate/depth/foxglove"]):
            assert schema.name == "foxglove.RawImage" and schema.encoding == "protobuf"
            frame, it = divmod(msg.log_time, 1_000_000_000)
            it = None if it == 0 else it // 1_000_000 - 1
            path = channel.topic[1:-len("/foxglove")]
            exact = rec.frames[frame].arrays[path][it]
            assert img.timestamp.ToNanoseconds() == msg.log_time and (img.height, img.width) == exact.shape[:2]
            if img.encoding == "mono8":
                pixels = np.frombuffer(img.data, np.uint8).reshape(img.height, img.width)
                assert np.array_equal(pixels, (np.nan_to_num(exact).clip(0, 1) * 255 + 0.5).astype(np.uint8))
            elif img.encoding == "rgb8":
                pixels = np.frombuffer(img.data, np.uint8).reshape(img.height, img.width, 3)
                assert np.array_equal(pixels, ((np.nan_to_num(exact) + 1) * 127.5).clip(0, 255).astype(np.uint8))
            else:
                assert img.encoding == "32FC1" and img.step == 4 * img.width
                depth = np.frombuffer(img.data, np.float32).reshape(img.height, img.width)
                assert np.array_equal(depth, np.nan_to_num(exact))
            seen[path] = seen.get(path, 0) + 1
    assert seen["robust_fit/weights"] == sum(s["iterations"] for s in json.loads((demo / "summary.json").read_text()))
    assert seen["combine/normals"] == seen["integrate/depth"] == 3
    rc = pytest.importorskip("rerun.chunk")
    shown = {ch.entity_path for ch in rc.McapReader(demo / "run.mcap").stream().collect().stream()
             if "Image:buffer" in ch.to_record_batch().schema.names}
    assert {"/robust_fit/weights/foxglove", "/combine/normals/foxglove", "/integrate/depth/foxglove",
            "/relight/relit/foxglove", "/load/grid_image/foxglove"} <= shown


@pytest.mark.slow
def test_replay_and_diff_commands(demo, tmp_path):
    out = run_cli(["replay", demo / "run.mcap", "--plot", tmp_path / "c.png", "--rrd", tmp_path / "re.rrd"])
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].split()[:3] == ["frame", "iters", "sigma"] and len([ln for ln in lines if "demo-" in ln]) == 3
    assert (tmp_path / "c.png").stat().st_size > 1000 and (tmp_path / "re.rrd").stat().st_size > 1000
    same = run_cli(["diff", demo / "run.mcap", demo / "run.mcap"])
    assert same.returncode == 0 and same.stdout.startswith("same: 3 frames")
    (tmp_path / "junk.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\xff" * 64)
    bad = run_cli(["diff", demo / "run.mcap", tmp_path / "junk.mcap"])
    assert bad.returncode == 2 and "junk.mcap" in bad.stderr


def test_diff_finds_a_one_ulp_change_and_says_where(demo, tmp_path):
    target = ("/robust_fit/residuals", 1, 7)  # topic, frame, iteration

    def nudge(topic, header, arr):
        if (topic, header["frame"], header["iteration"]) == target:
            arr = arr.copy()
            i = np.flatnonzero(np.isfinite(arr))[100]
            arr.flat[i] = np.nextafter(arr.flat[i], np.float32(np.inf))
            return arr
        return None

    _rewrite(demo / "run.mcap", tmp_path / "nudged.mcap", nudge)
    diffs = diff_recordings(read_mcap(demo / "run.mcap"), read_mcap(tmp_path / "nudged.mcap"))
    assert len(diffs) == 1
    d = diffs[0]
    assert (d.frame, d.iteration, d.channel) == (1, 7, "robust_fit/residuals") and 0 < d.max_abs < 1e-6
    # within a tolerance of one part in a million it is the same
    assert diff_recordings(read_mcap(demo / "run.mcap"), read_mcap(tmp_path / "nudged.mcap"), rtol=1e-6) == []


def test_diff_reports_first_where_the_runs_split_in_the_methods_order(demo, tmp_path):
    """A later step's product (albedo, alphabetically first, per frame) and the fit at iteration 3
    both differ: the split is the fit's iteration 3. When the input grid differs, that comes first."""
    from shadowflow.nodes.app.record import stage_rank

    def bump(*targets):
        def change(topic, header, arr):
            if (topic, header["iteration"]) in targets and header["frame"] == 0:
                return np.where(np.isfinite(arr), arr + np.float32(0.01), arr).astype(arr.dtype)
            return None
        return change

    _rewrite(demo / "run.mcap", tmp_path / "late.mcap", bump(("/albedo/albedo", None), ("/robust_fit/weights", 3)))
    diffs = diff_recordings(read_mcap(demo / "run.mcap"), read_mcap(tmp_path / "late.mcap"), stage=stage_rank)
    assert [(d.frame, d.iteration, d.channel) for d in diffs] == [(0, 3, "robust_fit/weights"), (0, None, "albedo/albedo")]
    out = run_cli(["diff", demo / "run.mcap", tmp_path / "late.mcap"])
    assert out.returncode == 1 and "iteration 3, channel robust_fit/weights" in out.stdout.splitlines()[0], out.stdout
    _rewrite(demo / "run.mcap", tmp_path / "early.mcap", bump(("/load/grid_image", None), ("/robust_fit/weights", 1)))
    first = diff_recordings(read_mcap(demo / "run.mcap"), read_mcap(tmp_path / "early.mcap"), stage=stage_rank)[0]
    assert (first.iteration, first.channel) == (None, "load/grid_image")


def test_golden_recording_is_reproduced_whatever_the_thread_count(tmp_path):
    for workers in (1, 2):
        rec = golden_run(tmp_path / f"w{workers}", fit_workers=workers)
        diffs = diff_recordings(read_mcap(rec), read_mcap(GOLDEN), atol=1e-6, rtol=1e-5)
        assert diffs == [], diffs[:3]
    exact = diff_recordings(read_mcap(tmp_path / "w1/result/run.mcap"), read_mcap(tmp_path / "w2/result/run.mcap"))
    assert exact == []
    golden = read_mcap(GOLDEN)
    assert len(golden.finished_frames()) == 2
    assert all(f.iterations("robust_fit/normals") == list(range(1, 7)) for f in golden.finished_frames())


def test_an_older_releases_dense_recording_still_reads_and_diffs_equal():
    """``golden-64-dense.mcap``: the golden run as an earlier release recorded it, every array dense
    (before masked messages) and its albedo filled as the paper fills it. It reads, and equals today's
    golden on every channel of its second face but the four the albedo changed (its fill ceiling, then
    its measurement only where the photo shows the face), and the names of its fit's scalars: each iteration's
    record says since whether the albedo was measured again before it (``albedo_round``), the others equal.
    Its first face's fit moved since: the render's black beyond the face, inside the model's edge, is left out as
    what covers the face (``cover.py``)."""
    old, new = read_mcap(GOLDEN.with_name("golden-64-dense.mcap")), read_mcap(GOLDEN)
    diffs = diff_recordings(old, new, atol=1e-6, rtol=1e-5)
    second = [d for d in diffs if d.frame == 1]
    fit = [d for d in second if d.iteration is not None]  # no fit iteration differs but by its new scalar
    assert {d.channel for d in second if d.iteration is None} == {
        "albedo/albedo", "integrate/mesh/colours", "relight/relit", "relight/novel_view"}, second
    assert fit and all(d.channel == "robust_fit/convergence" and d.what == "different scalar names" for d in fit)
    then, now = (r.finished_frames()[1].scalars["robust_fit/convergence"] for r in (old, new))
    assert sorted(then) == sorted(now)
    for it in now:
        assert set(now[it]) - set(then[it]) == {"albedo_round"} and now[it]["albedo_round"] == 0.0
        assert all(now[it][k] == pytest.approx(v, rel=1e-5, abs=1e-6) for k, v in then[it].items())
    assert {d.channel for d in diffs if d.frame == 0 and d.iteration is not None} >= {"robust_fit/normals"}
    assert len(old.finished_frames()) == 2


def test_record_every_and_float16(tmp_path):
    model = golden_model()
    from shadowflow.nodes.app.runner import RunOptions, run_stream
    from shadowflow.nodes.method.options import MethodOptions
    from shadowflow.nodes.method.robust_fit import FitConfig

    paths = golden_inputs(tmp_path)
    opts = MethodOptions(fit=FitConfig(max_iterations=11, tolerance_deg=0.0))
    run_stream(paths, tmp_path / "thin", model, opts,
               RunOptions(record=("mcap",), record_options=RecordOptions(every=4, float16=True), quiet=True))
    rec = read_mcap(tmp_path / "thin" / "run.mcap")
    for fr in rec.finished_frames():
        assert fr.iterations("robust_fit/weights") == [1, 5, 9, 11]  # and always the last
        assert fr.arrays["robust_fit/weights"][11].dtype == np.float16
        assert fr.scalars["robust_fit/convergence"][11]["sigma"] > 0


def test_truncated_and_hostile_files(demo, tmp_path):
    data = (demo / "run.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    from mcap.reader import SeekingReader

    with open(demo / "run.mcap", "rb") as fh:
        chunks = SeekingReader(fh).get_summary().chunk_indexes
    finished = []
    for chunk in chunks:  # killed a few bytes after each chunk: what was flushed before survives
        cut.write_bytes(data[: chunk.chunk_start_offset + chunk.chunk_length + 5])
        rec = read_mcap(cut)
        assert rec.truncated
        finished.append(len(rec.finished_frames()))
    assert finished == sorted(finished) and finished[-1] == 3 and any(1 <= f <= 2 for f in finished), finished
    for name, blob in (("garbage.mcap", b"hello world" * 100), ("empty.mcap", b""),
                       ("header-only.mcap", data[:8] + b"\x00" * 5)):
        (tmp_path / name).write_bytes(blob)
        with pytest.raises(RecordingError, match=name):
            read_mcap(tmp_path / name)
    # a message whose header claims a huge array is refused, not allocated
    huge = tmp_path / "huge.mcap"
    _rewrite(demo / "run.mcap", huge, lambda *_: None)
    import struct

    from shadowflow.flow.recording import decode_array
    header = json.dumps({"frame": 0, "iteration": 1, "dtype": "<f8", "shape": [1 << 20, 1 << 20]}).encode()
    with pytest.raises(ValueError, match="payload"):
        decode_array(b"SFA1" + struct.pack("<I", len(header)) + header + b"\x00" * 16)
    with pytest.raises(ValueError):
        decode_array(b"SFA1" + struct.pack("<I", 20) + b'{"dtype": "|O"}' + b" " * 5)


@pytest.mark.slow
def test_kill_9_then_resume_completes_without_redoing(tmp_path):
    """A run killed hard mid-stream leaves readable recordings of its finished frames, and
    --resume finishes the job without redoing them; the outputs equal an uninterrupted run's."""
    src = tmp_path / "in"
    src.mkdir()
    _golden_copies(src, 16)  # enough that the kill lands mid-stream
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "shadowflow.nodes.app.cli", "run", str(src), "--out", str(out), "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _wait_for_records(out, 2)
    recording_process = _children(proc.pid)
    assert len(recording_process) == 1  # the sinks write in a process of their own
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    _wait_gone(recording_process)  # it reads end-of-file and closes the files
    done_before = _done(out)  # the journal: every frame is there once its files and recording are
    assert 2 <= len(done_before) < 16
    listed = json.loads((out / "summary.json").read_text())  # rewritten about once a second: may lag
    assert [r["stem"] for r in listed] == [r["stem"] for r in done_before[:len(listed)]]
    rec = read_mcap(out / "run.mcap")
    assert len(rec.finished_frames()) >= len(done_before) - 1  # the last flush may be cut by the kill
    for fr in rec.finished_frames():
        assert fr.iterations("robust_fit/normals") == list(range(1, fr.record["iterations"] + 1))
    rc = pytest.importorskip("rerun.chunk")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. "no footer": the file was cut, not closed
        store = rc.RrdReader(out / "run.rrd").stream().collect()
    killed_rrd = str(store.summary())
    for k in range(len(done_before) - 1):
        assert f"/robust_fit/weights/{done_before[k]['stem']}" in killed_rrd
    mtimes = {r["stem"]: (out / r["stem"] / "normals.npy").stat().st_mtime_ns for r in done_before}
    resumed = subprocess.run(cmd + ["--resume"], capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary) == 16 and all(r["status"] == "ok" for r in summary)
    assert {s: (out / s / "normals.npy").stat().st_mtime_ns for s in mtimes} == mtimes  # not redone
    part2 = read_mcap(out / "run.part2.mcap")
    assert len(part2.finished_frames()) == 16 - len(done_before)
    fresh = tmp_path / "fresh"
    assert subprocess.run(cmd[:-3] + ["--out", str(fresh), "--quiet", "--record", "mcap"]).returncode == 0
    for r in summary:
        for name in OUTPUT_FILES:
            assert (out / r["stem"] / name).read_bytes() == (fresh / r["stem"] / name).read_bytes(), name
    # the killed run's recording and the resumed part, merged, equal the uninterrupted recording
    same = run_cli(["diff", out, fresh])
    assert same.returncode == 0 and same.stdout.startswith("same: 16 frames"), same.stdout + same.stderr
    alone = run_cli(["diff", out / "run.part2.mcap", fresh])
    assert alone.returncode == 1 and "frame only in B" in alone.stdout  # the merge is what makes them equal


@pytest.mark.slow
def test_sigterm_stops_cleanly_with_complete_recordings(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    _golden_copies(src, 12)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "shadowflow.nodes.app.cli", "run", str(src), "--out", str(out), "--quiet"],
                            stderr=subprocess.PIPE, text=True)
    _wait_for_records(out, 2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "--resume" in err
    summary = json.loads((out / "summary.json").read_text())
    assert 2 <= len(summary) < 12 and all(r["status"] == "ok" for r in summary)
    assert summary == _done(out)  # written in full at the stop
    rec = read_mcap(out / "run.mcap")
    assert not rec.truncated and len(rec.finished_frames()) == len(summary)  # closed properly
    rc = pytest.importorskip("rerun.chunk")
    assert f"/status/{summary[-1]['stem']}" in str(rc.RrdReader(out / "run.rrd").store().summary())


def test_a_script_without_a_main_guard_records_through_the_api(tmp_path):
    """``shadowflow.run`` from a plain script records in its own process without running the
    script again (a spawned ``multiprocessing`` child would re-import ``__main__``): the script's
    top level runs once, and the recording holds the frame."""
    src = tmp_path / "in"
    src.mkdir()
    _golden_copies(src, 1)
    script = tmp_path / "plain.py"
    script.write_text(
        "import shadowflow\n"
        f"print('top level ran', flush=True)\n"
        f"run = shadowflow.run([{str(src / 'face-00.png')!r}], {str(tmp_path / 'out')!r}, record=('mcap', 'rerun'))\n"
        "print(run.records[0]['status'])\n")
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == ["top level ran", "ok"]
    assert [fr.record["stem"] for fr in read_mcap(tmp_path / "out" / "run.mcap").finished_frames()] == ["face-00"]
    assert (tmp_path / "out" / "run.rrd").stat().st_size > 0
