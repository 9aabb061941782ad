"""Hostile use of the recordings' commands (``replay``, ``diff``): nothing read is written over, two
equal runs are equal whatever the order and folders of their inputs, and a tolerance means what it
says. Each case failed as described before its fix."""
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from shadowflow.nodes.app.cli import main

from conftest import run_cli


@pytest.fixture(scope="module")
def two_folders(tmp_path_factory):
    """Two faces with the same file name in two folders, run in one order and then the other."""
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    root = tmp_path_factory.mktemp("twins")
    for folder, seed, az in (("a", 1, 30), ("b", 2, -40)):
        (root / folder).mkdir()
        write_shadowed_face(root / folder / "face.png", np.random.default_rng(seed), light_from_angles(az))
    runs = {}
    for name, order in (("ab", ["a", "b"]), ("ba", ["b", "a"])):
        out = root / f"out-{name}"
        args = [str(root / f / "face.png") for f in order]
        assert main(["run", *args, "--out", str(out), "--quiet", "--record", "mcap"]) == 0
        runs[name] = out
    return root, runs


def test_replay_will_not_write_its_rerun_file_over_the_recording_it_reads(two_folders, capsys):
    """``replay RUN.mcap --rrd RUN.mcap`` wrote over the recording it was reading."""
    _, runs = two_folders
    rec = runs["ab"] / "run.mcap"
    before = rec.read_bytes()
    assert main(["replay", str(rec), "--rrd", str(rec)]) == 2
    assert "is the recording being read" in capsys.readouterr().err
    assert main(["replay", str(runs["ab"]), "--rrd", str(runs["ab"] / "run.mcap")]) == 2  # a file of its run
    assert rec.read_bytes() == before


def test_diff_pairs_inputs_that_share_a_file_name_by_their_path(two_folders, capsys):
    """a/face.png and b/face.png run in one order and then the other: "differ" when frames paired by
    file name; the same runs are the same."""
    _, runs = two_folders
    assert main(["diff", str(runs["ab"]), str(runs["ba"]), "--atol", "1e-6"]) == 0, capsys.readouterr().out
    assert "same: 2 frames" in capsys.readouterr().out


def test_diff_pairs_copies_of_the_inputs_elsewhere_by_file_name(two_folders, tmp_path, capsys):
    """A run over copies of the inputs in another folder still pairs its frames with the first run's."""
    root, runs = two_folders
    copy = tmp_path / "copy"
    copy.mkdir()
    for f in ("face.png", "face.json"):
        shutil.copy(root / "a" / f, copy / f)
    out = tmp_path / "out"
    assert main(["run", str(copy / "face.png"), "--out", str(out), "--quiet", "--record", "mcap"]) == 0
    single = tmp_path / "single"
    assert main(["run", str(root / "a" / "face.png"), "--out", str(single), "--quiet", "--record", "mcap"]) == 0
    capsys.readouterr()
    assert main(["diff", str(single), str(out), "--atol", "1e-6"]) == 0, capsys.readouterr().out


@pytest.mark.parametrize("tolerance", [["--atol", "nan"], ["--rtol", "nan"], ["--atol", "-1"], ["--rtol", "-0.1"],
                                       ["--atol", "inf"]])
def test_diff_refuses_a_tolerance_that_cannot_tell_runs_apart(two_folders, tolerance, capsys):
    """``diff --atol nan`` said "same" for different recordings; negative tolerances were taken."""
    root, runs = two_folders
    assert main(["diff", str(runs["ab"] / "run.mcap"), str(runs["ab"] / "run.mcap"), *tolerance]) == 2
    assert "tolerance" in capsys.readouterr().err
    records = json.loads((runs["ab"] / "summary.json").read_text())
    assert len(records) == 2


def test_convergence_table_keeps_one_row_per_frame_whatever_the_file_name():
    """A tab, a newline or a terminal escape in a file name broke the replay table's rows."""
    from shadowflow.flow.replay import ConvergenceRow, format_table
    from shadowflow.nodes.app.record import CONVERGENCE_TABLE

    rows = [ConvergenceRow(frame=k, source=name, status="ok", iterations=3, values=((0.1,), (1.0, 0.5)), converged=True)
            for k, name in enumerate(["a\tb.png", "two\nlines.png", "\x1b[31mred.png", "plain.png"])]
    lines = format_table(rows, CONVERGENCE_TABLE).splitlines()
    assert len(lines) == 1 + len(rows)
    assert "\x1b" not in "\n".join(lines) and "a\\tb.png" in lines[1] and "two\\nlines.png" in lines[2]
    assert "residual first -> last" in lines[0] and "1 -> 0.5" in lines[1]


def test_convergence_figure_draws_names_with_dollars_and_underscores():
    """Two ``$`` in a file name were read as mathtext (a lone one failed the drawing), and a name
    starting with ``_`` was left out of the legend."""
    from shadowflow.flow.replay import convergence_figure

    series = [(name, {0: {"sigma": 1.0}, 1: {"sigma": 0.5}, 2: {"sigma": 0.4}})
              for name in ["$5 $x$.png", "cost$.png", "_hidden.png"]]
    fig = convergence_figure(series, ("sigma",))
    fig.canvas.draw()  # raised ValueError on the lone "$"
    legend = fig.axes[-1].get_legend()
    assert [t.get_text() for t in legend.get_texts()] == [r"\$5 \$x\$.png", r"cost\$.png", "_hidden.png"]


def test_summary_record_writes_a_nan_as_null(tmp_path):
    """A NaN in a face's fields (a fit's sigma) went into summary.json as bare NaN, which strict JSON
    readers refuse."""
    from shadowflow.flow.frame import Frame
    from shadowflow.nodes.app.outputs import summary_record, write_summary

    frame = Frame(id=0, source="x.png", meta={"stem": "x", "final_sigma": float("nan"), "light": [float("inf"), 0, 1]})
    rec = summary_record(frame)
    write_summary(tmp_path, [rec])
    text = (tmp_path / "summary.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    loaded = json.loads(text, parse_constant=lambda c: pytest.fail(f"bare {c} in summary.json"))
    assert loaded[0]["light"][0] is None


def test_convergence_table_names_a_doubtful_frame_by_its_file():
    """``replay`` named a doubtful frame by its flags alone: which file to look at was not said."""
    from shadowflow.flow.replay import ConvergenceRow, format_table
    from shadowflow.nodes.app.record import CONVERGENCE_TABLE

    rows = [ConvergenceRow(frame=0, source="/photos/cut-off.png", status="doubtful: 64 % of the face outside the frame",
                           iterations=15, values=((0.02,), (0.3, 0.01)), converged=True),
            ConvergenceRow(frame=1, source="/photos/ok.png", status="ok", iterations=12, values=((0.1,), (0.3, 0.1)),
                           converged=True)]
    lines = format_table(rows, CONVERGENCE_TABLE).splitlines()
    assert "64 % of the face outside the frame" in lines[1] and "/photos/cut-off.png" in lines[1]
    assert lines[2].endswith("/photos/ok.png")


def _mcap_with_chunk(path, compression: str, data: bytes, declared: int) -> None:
    """An MCAP file: its magic, a header, and one chunk of ``data`` that declares ``declared``
    bytes once decompressed (a file cut there, as after a kill)."""
    from mcap.data_stream import RecordBuilder
    from mcap.records import Chunk, Header

    b = RecordBuilder()
    Header(profile="", library="hostile").write(b)
    Chunk(compression=compression, data=data, message_end_time=0, message_start_time=0, uncompressed_crc=0,
          uncompressed_size=declared).write(b)
    path.write_bytes(b"\x89MCAP0\r\n" + bytes(b.end()))


def _peak_rss_mib() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


@pytest.mark.parametrize("compression", ["zstd", "lz4", ""])
def test_a_chunk_declaring_3_gb_is_refused_before_it_is_decompressed(tmp_path, compression, capsys):
    """Issue 39 #12: a small file whose one chunk declares 3 GB drove replay and diff to 3 GB."""
    import lz4.frame
    import zstandard

    small = b"\x00" * 4096
    data = {"zstd": zstandard.ZstdCompressor(write_content_size=False).compress(small),
            "lz4": lz4.frame.compress(small), "": small}[compression]
    path = tmp_path / "run.mcap"
    _mcap_with_chunk(path, compression, data, 3 << 30)
    assert path.stat().st_size < 100_000
    before = _peak_rss_mib()
    assert main(["replay", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and "3221225472 bytes" in err[0] and "1 GiB" in err[0], err
    assert _peak_rss_mib() - before < 200


def test_a_chunk_that_decompresses_past_its_declared_size_is_refused_without_holding_it(tmp_path, capsys):
    """The declared size is the bound: 256 MiB of zeros in 1 MB of zstd declaring 64 kB is not read on."""
    import zstandard

    comp = zstandard.ZstdCompressor(level=1, write_content_size=False).compressobj()
    data = b"".join([comp.compress(b"\x00" * (16 << 20)) for _ in range(16)]) + comp.flush()
    path = tmp_path / "run.mcap"
    _mcap_with_chunk(path, "zstd", data, 65536)
    before = _peak_rss_mib()
    assert main(["replay", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "more than the 65536 bytes it declares" in err[0], err
    assert _peak_rss_mib() - before < 100


@pytest.mark.parametrize("args, says", [
    (["train", "--size", "0,0"], "--size"),
    (["train", "--size", "5000,5000"], "--size"),
    (["train", "--size", "128"], "--size"),
    (["train", "--size", "a,b"], "--size"),
    (["train", "--n", "1"], "--n"),
    (["train", "--modes", "0"], "--modes"),
    (["train", "--n", "10", "--modes", "20"], "--modes"),
    (["eval", "--angles", "90"], "--angles"),
    (["eval", "--angles", "-400"], "--angles"),
    (["eval", "--angles", "45,nan"], "--angles"),
    (["eval", "--size", "0,0"], "--size"),
    (["eval", "--n-test", "0"], "--n-test"),
])
def test_train_and_eval_arguments_that_cannot_work_are_refused_in_one_line(tmp_path, args, says, capsys):
    """The smaller cases of issue 39: ``train --size 0,0`` trained 0 modes and exited 0, others gave
    Python's messages; ``eval`` took 90 and -400 degrees and printed half a table for nan."""
    extra = ["--out", str(tmp_path / "m.npz")] if args[0] == "train" else []
    assert main([*args, *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0], err
    assert not (tmp_path / "m.npz").exists()


def _mcap_with(path: Path, encoding: str, data: bytes) -> None:
    """A well-formed MCAP file holding one message of ``encoding`` with body ``data``."""
    from mcap.writer import Writer

    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("other.Thing", "jsonschema", b"{}")
        cid = w.register_channel("/thing", encoding, sid)
        w.add_message(cid, log_time=1, data=data, publish_time=1)
        w.finish()


@pytest.mark.slow
def test_replay_and_diff_refuse_hostile_recordings_with_exit_2(tmp_path):
    import struct

    from shadowflow.flow.recording import Event, McapSink
    from shadowflow.flow.recording.codec import ARRAY_ENCODING

    good = tmp_path / "good.mcap"
    sink = McapSink(good)
    sink.write(Event(0, "fit/w", "array", np.ones((4, 4), np.float32), 1))
    sink.frame_done(0)
    sink.close()
    data = good.read_bytes()
    header = b'{"frame": 0, "iteration": 1, "dtype": "<f8", "shape": [1048576, 1048576]}'
    cases = {
        "garbage.mcap": b"\x00\x01garbage" * 50,
        "magic-only.mcap": data[:8],
        "cut.mcap": data[:20],  # inside its header (cut after it, it is a recording cut short: docs/faults.md)
        "huge-length.mcap": data[:9] + (2**62).to_bytes(8, "little") + data[17:],
    }
    for name, blob in cases.items():
        (tmp_path / name).write_bytes(blob)
    _mcap_with(tmp_path / "foreign.mcap", "json", b'{"x": 1.0}')  # another tool's recording
    _mcap_with(tmp_path / "huge-array.mcap", ARRAY_ENCODING, b"SFA1" + struct.pack("<I", len(header)) + header)
    _mcap_with(tmp_path / "pickled.mcap", ARRAY_ENCODING, b"SFA1" + struct.pack("<I", 15) + b'{"dtype": "|O"}')
    _mcap_with(tmp_path / "odd-encoding.mcap", "cdr", b"\x00" * 16)
    (tmp_path / "empty-dir").mkdir()
    for name in [*cases, "foreign.mcap", "huge-array.mcap", "pickled.mcap", "odd-encoding.mcap",
                 "missing.mcap", "empty-dir"]:
        path = tmp_path / name
        for cmd in (["replay", str(path)], ["diff", str(path), str(good)]):
            proc = run_cli(cmd)
            assert proc.returncode == 2, (name, cmd[0], proc.stdout, proc.stderr)
            lines = proc.stderr.strip().splitlines()
            assert len(lines) == 1 and name in lines[0], (name, proc.stderr)


# -- the fourth round (issue 64) ------------------------------------------------------------------


def test_replay_will_not_write_over_a_hard_link_of_its_recording(two_folders, tmp_path, capsys):
    """``replay OUT --rrd X`` where X is a hard link of the run's own ``run.mcap`` truncated the recording (a
    symbolic link was refused, a hard link has a path of its own); ``--plot`` wrote over it the same way."""
    _, runs = two_folders
    rec = runs["ab"] / "run.mcap"
    before = rec.read_bytes()
    link = tmp_path / "elsewhere.rrd"
    os.link(rec, link)
    for args in (["replay", str(runs["ab"]), "--rrd", str(link)], ["replay", str(rec), "--plot", str(link)]):
        assert main(args) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(link) in err[0] and "is the recording being read" in err[0], err
    assert rec.read_bytes() == before


@pytest.mark.parametrize("damage", ["200 bytes in a row", "200 scattered bytes"])
def test_a_recording_damaged_in_its_middle_is_named_corrupt_not_cut(two_folders, tmp_path, damage, capsys):
    """A recording with 200 flipped bytes in its middle replayed as "ends early (a killed run?)", exit 0,
    half its frames shown (or, the flips inside an array, as whole, exit 0). A file cut in the middle is
    still a killed run's."""
    _, runs = two_folders
    data = bytearray((runs["ab"] / "run.mcap").read_bytes())
    mid = len(data) // 2
    where = (range(mid, mid + 200) if damage == "200 bytes in a row"
             else np.random.default_rng(0).choice(np.arange(64, len(data) - 64), 200, replace=False))
    for i in where:
        data[i] ^= 0x5A
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    for args in (["replay", str(bad)], ["diff", str(bad), str(runs["ab"])]):
        assert main(args) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(bad) in err[0] and "corrupt" in err[0], err
    cut = tmp_path / "cut.mcap"
    cut.write_bytes((runs["ab"] / "run.mcap").read_bytes()[:mid])
    assert main(["replay", str(cut)]) == 0
    assert "ends early" in capsys.readouterr().out


def _tiny_message_chunks(path: Path, chunk_bytes: int, chunks: int) -> None:
    """An MCAP file of ``chunks`` zstd chunks, each ``chunk_bytes`` of one tiny scalar message repeated (a
    few kB each on disk)."""
    import zstandard
    from mcap.data_stream import RecordBuilder
    from mcap.records import Channel, Chunk, Header, Message, Schema

    b = RecordBuilder()
    Schema(id=1, name="shadowflow.Scalars", encoding="jsonschema", data=b"{}").write(b)
    Channel(id=1, schema_id=1, topic="/fit/convergence", message_encoding="json", metadata={}).write(b)
    head = bytes(b.end())
    b = RecordBuilder()
    Message(channel_id=1, sequence=0, log_time=0, publish_time=0, data=b'{"frame":0,"iteration":1,"values":{}}').write(b)
    one = bytes(b.end())
    block = one * ((1 << 20) // len(one))
    n_blocks = chunk_bytes // len(block)
    comp = zstandard.ZstdCompressor(level=3, write_content_size=False)
    out = RecordBuilder()
    Header(profile="", library="hostile").write(out)
    for _ in range(chunks):
        z = comp.compressobj()
        data = z.compress(head) + b"".join(z.compress(block) for _ in range(n_blocks)) + z.flush()
        Chunk(compression="zstd", data=data, message_end_time=0, message_start_time=0, uncompressed_crc=0,
              uncompressed_size=len(head) + n_blocks * len(block)).write(out)
    path.write_bytes(b"\x89MCAP0\r\n" + bytes(out.end()))


@pytest.mark.parametrize("chunk_mib, chunks", [(256, 1), (4, 64)])
def test_chunks_of_tiny_messages_inflating_far_past_the_file_are_refused(tmp_path, chunk_mib, chunks, capsys):
    """A 25 kB file whose chunk of tiny messages declared 256 MiB took replay 27-56 s and 1.5 GB (1 GiB: 3.4 GB
    and a traceback): each message costs microseconds, and the chunk was held as a list of them. Many chunks
    of 4 MiB each (under any one chunk's limit) did the same."""
    path = tmp_path / "bomb.mcap"
    _tiny_message_chunks(path, chunk_mib << 20, chunks)
    assert path.stat().st_size < 200_000
    before = _peak_rss_mib()
    assert main(["replay", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and "times as many" in err[0], err
    assert _peak_rss_mib() - before < 100


@pytest.mark.slow
def test_a_pipe_named_like_a_recording_is_refused_not_waited_on(two_folders, tmp_path):
    """A FIFO named ``*.mcap``, given or in a run's folder, hung ``replay`` and ``diff`` forever (opened for
    reading, it waits for a writer)."""
    import subprocess
    import sys

    _, runs = two_folders
    folder = tmp_path / "run"
    shutil.copytree(runs["ab"], folder)
    (folder / "manifest.json").unlink()  # a folder without a manifest: every .mcap in it is read
    os.mkfifo(folder / "stray.mcap")
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    cli = [sys.executable, "-m", "shadowflow.nodes.app.cli"]
    for args, named in ((["replay", str(fifo)], fifo), (["diff", str(fifo), str(runs["ab"])], fifo),
                        (["replay", str(folder)], folder / "stray.mcap")):
        proc = subprocess.run(cli + args, capture_output=True, text=True, timeout=120)
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2 and len(lines) == 1, proc.stderr
        assert str(named) in lines[0] and "not a regular file" in lines[0], lines


def test_a_part_a_kill_left_empty_is_read_as_a_part_cut_short(two_folders, tmp_path, capsys):
    """After ``kill -9`` of a ``--dask`` run and ``--resume``, ``replay`` and ``diff`` failed ("run.mcap: not an
    MCAP file"): the client's own part, listed in the manifest when the run began, was 0 bytes (its header was
    still in the writer's buffer). Its header is on disk at once now, and a part cut before it is read as empty."""
    from shadowflow.flow.manifest import RunManifest
    from shadowflow.flow.recording import McapSink

    sink = McapSink(tmp_path / "opened.mcap")
    assert (tmp_path / "opened.mcap").stat().st_size > 8  # the magic and the header, before any frame
    sink.close()
    _, runs = two_folders
    folder = tmp_path / "run"
    shutil.copytree(runs["ab"], folder)
    (folder / "run.mcap").rename(folder / "run.worker-0.mcap")
    for name, data in (("run.mcap", b""), ("run.part2.mcap", b"\x89MCAP0\r\n\x01")):
        (folder / name).write_bytes(data)  # as a kill leaves them: nothing, or cut in its header
    man = RunManifest.load(folder)
    man.recordings = ["run.mcap", "run.worker-0.mcap", "run.part2.mcap"]
    man.save(folder)
    assert main(["replay", str(folder)]) == 0
    out = capsys.readouterr().out
    assert out.count("face.png") == 2 and "ends early" not in out
    assert main(["diff", str(folder), str(runs["ab"])]) == 0
    assert capsys.readouterr().out.startswith("same: 2 frames")
