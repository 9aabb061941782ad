"""One run per --out, and --resume that knows what made each output: a lock, a run manifest
(model, options, tool version, each input's identity <-> its output name and frame id), and
folder-mode recordings that merge only the job's own parts (issue 18 #1, #2, #3, #7)."""
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from shadowflow.flow.files import FolderBusy, exclusive_folder
from shadowflow.flow.manifest import MANIFEST_NAME, RunManifest
from shadowflow.nodes.evaluation.scenes import write_shadowed_face
from shadowflow.nodes.geometry.reflectance import light_from_angles

from conftest import run_cli

pytestmark = pytest.mark.slow  # each case runs the whole command line several times
FAST = ["--max-iterations", "8", "--record", "mcap", "--light", "0.5,0,0.87"]


def _face(path: Path, seed: int) -> Path:
    return write_shadowed_face(path, np.random.default_rng(seed), light_from_angles(30, 0))


def _faces(folder: Path, n: int) -> Path:
    """``face0.png`` .. ``face<n-1>.png`` (seeds 0 ..) in a new ``folder``."""
    folder.mkdir()
    for k in range(n):
        _face(folder / f"face{k}.png", k)
    return folder


def _run(inputs, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return run_cli(["run", *map(str, inputs), "--out", str(out), *FAST, *extra])


def _mtimes(out: Path) -> dict[str, int]:
    return {p.parent.name: p.stat().st_mtime_ns for p in out.glob("*/normals.npy")}


def test_a_second_run_into_a_busy_out_says_who_holds_it_and_exits_2(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    _face(src / "face.png", 1)
    out = tmp_path / "out"
    out.mkdir()
    with exclusive_folder(out, "pid 4242 on testhost"):
        with pytest.raises(FolderBusy, match="pid 4242 on testhost"):
            with exclusive_folder(out, "me"):
                pass
        busy = _run([src], out)
        assert busy.returncode == 2, busy.stderr
        assert len(busy.stderr.strip().splitlines()) == 1 and "in use by another run (pid 4242 on testhost)" in busy.stderr
        assert not (out / "summary.json").exists() and not (out / "run.mcap").exists()
    after = _run([src], out)  # the lock went with its holder; the file left behind is no obstacle
    assert after.returncode == 0, after.stderr
    assert (out / ".lock").is_file()


def test_resume_after_changing_the_options_redoes_every_frame_and_says_why(tmp_path):
    src = _faces(tmp_path / "in", 2)
    out = tmp_path / "out"
    assert _run([src], out).returncode == 0
    man = json.loads((out / MANIFEST_NAME).read_text())
    assert man["config"]["options"]["fit"]["max_iterations"] == 8 and len(man["config"]["model"]) == 16
    assert [e["name"] for e in man["inputs"]] == ["face0", "face1"] and man["recordings"] == ["run.mcap"]
    before = _mtimes(out)
    same = _run([src], out, "--resume")
    assert same.returncode == 0 and _mtimes(out) == before  # nothing changed: nothing redone
    changed = run_cli(["run", str(src), "--out", str(out), "--resume", "--record", "mcap",
                                    "--max-iterations", "9", "--light", "0.5,0,0.87"])
    assert changed.returncode == 0, changed.stderr
    assert "differ from the earlier run" in changed.stderr and "options.fit.max_iterations" in changed.stderr
    assert all(_mtimes(out)[k] > before[k] for k in before)  # both redone under the new options
    model = tmp_path / "other.npz"
    trained = run_cli(["train", "--source", "procedural", "--n", "12", "--modes", "6", "--size", "64,64",
                                    "--out", str(model)])
    assert trained.returncode == 0, trained.stderr
    again = run_cli(["run", str(src), "--out", str(out), "--resume", "--record", "mcap", "--max-iterations",
                                  "9", "--light", "0.5,0,0.87", "--model", str(model)])
    assert again.returncode == 0 and "config.model" not in again.stderr and "model" in again.stderr, again.stderr


def test_resume_knows_inputs_by_identity_not_by_sort_order(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    _face(src / "a_b.png", 1)
    _face(src / "m.png", 2)
    out = tmp_path / "out"
    assert _run([src], out).returncode == 0
    before = _mtimes(out)
    # a file whose name folds to a taken one, and one that sorts first
    _face(src / "a b.png", 3)
    _face(src / "0first.png", 4)
    resumed = _run([src], out, "--resume")
    assert resumed.returncode == 0, resumed.stderr
    summary = {r["source"]: r["stem"] for r in json.loads((out / "summary.json").read_text())}
    assert summary == {str(src / "0first.png"): "0first", str(src / "a b.png"): "a_b-2",
                       str(src / "a_b.png"): "a_b", str(src / "m.png"): "m"}
    after = _mtimes(out)
    assert {k: after[k] for k in before} == before  # the old ones were not redone
    assert set(after) == {"0first", "a_b", "a_b-2", "m"}
    man = RunManifest.load(out)
    ids = {e.name: e.frame for e in man.entries.values()}
    assert ids == {"a_b": 0, "m": 1, "0first": 2, "a_b-2": 3}  # old ids kept, new ones after them
    # a fresh run numbers them in sort order; diff pairs frames by name, so the runs are the same
    fresh = tmp_path / "fresh"
    assert _run([src], fresh).returncode == 0
    diff = run_cli(["diff", str(out), str(fresh)])
    assert diff.returncode == 0 and diff.stdout.startswith("same: 4 frames"), diff.stdout + diff.stderr
    # an input replaced under the same name is redone, under its old name and frame id
    shutil.copy(src / "m.png", tmp_path / "m-old.png")
    _face(src / "m.png", 9)
    replaced = _run([src], out, "--resume", "--record", "none")
    assert replaced.returncode == 0 and "m.png changed since the earlier run" in replaced.stderr
    assert _mtimes(out)["m"] > after["m"] and _mtimes(out)["a_b"] == after["a_b"]
    assert {e.name: e.frame for e in RunManifest.load(out).entries.values()} == ids
    # the same bytes copied back (a new mtime) are recognised by content
    _face(src / "m.png", 2)
    restored = _run([src], out, "--resume", "--record", "none")
    assert "m.png changed" in restored.stderr  # content differs from the seed-9 face: redone
    stamp = _mtimes(out)["m"]
    shutil.copyfile(src / "m.png", tmp_path / "m-copy.png")
    shutil.copyfile(tmp_path / "m-copy.png", src / "m.png")  # same bytes, new mtime
    again = _run([src], out, "--resume", "--record", "none")
    assert "changed" not in again.stderr and _mtimes(out)["m"] == stamp


def test_folder_diff_merges_only_the_parts_of_its_own_job(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    _face(src / "face.png", 1)
    _face(src / "other.png", 2)
    old = tmp_path / "old"
    assert _run([src / "other.png"], old).returncode == 0
    out = tmp_path / "out"
    out.mkdir()
    shutil.copy(old / "run.mcap", out / "run.part2.mcap")  # a stray part of an older job
    shutil.copy(old / "run.mcap", out / "stray.mcap")
    assert _run([src / "face.png"], out).returncode == 0
    fresh = tmp_path / "fresh"
    assert _run([src / "face.png"], fresh).returncode == 0
    diff = run_cli(["diff", str(out), str(fresh)])
    assert diff.returncode == 0 and diff.stdout.startswith("same: 1 frames"), diff.stdout + diff.stderr
    (out / MANIFEST_NAME).unlink()  # without a manifest every .mcap of the folder is merged in
    merged = run_cli(["diff", str(out), str(fresh)])
    assert merged.returncode == 1


def test_a_manifest_that_cannot_be_trusted_means_every_input_is_redone(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    _face(src / "face.png", 1)
    out = tmp_path / "out"
    assert _run([src], out).returncode == 0
    before = _mtimes(out)
    for text in ["null", "[]", '{"format": 1, "config": [], "inputs": 5}', "{" * 100000, "\x00\xff"]:
        (out / MANIFEST_NAME).write_text(text)
        proc = _run([src], out, "--resume")
        assert proc.returncode == 0, proc.stderr
        assert _mtimes(out)["face"] > before["face"]
        before = _mtimes(out)


def test_resume_redoes_an_input_whose_sidecar_bytes_or_relit_files_changed(tmp_path):
    """Issue 39 #5 and #11: an input is known by its bytes and its sidecar's, not by its size and
    mtime; a frame is complete only with every file its options ask for, ``--relight`` ones included."""
    src = tmp_path / "in"
    src.mkdir()
    for name, seed in (("side.png", 1), ("swap.pgm", 2), ("lost.png", 3), ("kept.png", 4)):
        _face(src / name, seed)
    out = tmp_path / "out"
    relight = ["--relight", "30,10"]
    assert _run([src], out, *relight).returncode == 0
    before = _mtimes(out)
    assert set(before) == {"side", "swap", "lost", "kept"}
    # the sidecar's light edited (the fit depends on it)
    side = json.loads((src / "side.json").read_text())
    side["light"] = [-0.5, 0.0, 0.87]
    (src / "side.json").write_text(json.dumps(side))
    # another photo of the same size in place (a binary PGM: one pixel brighter), its mtime restored
    st = (src / "swap.pgm").stat()
    data = bytearray((src / "swap.pgm").read_bytes())
    data[-64 * 128 - 64] = min(255, data[-64 * 128 - 64] + 40)
    (src / "swap.pgm").write_bytes(bytes(data))
    os.utime(src / "swap.pgm", ns=(st.st_atime_ns, st.st_mtime_ns))
    assert (src / "swap.pgm").stat().st_size == st.st_size
    # one relit file lost
    (out / "lost" / "relit_A+030E+10.png").unlink()
    resumed = _run([src], out, "--resume", *relight)
    assert resumed.returncode == 0, resumed.stderr
    after = _mtimes(out)
    assert after["kept"] == before["kept"]
    assert all(after[k] > before[k] for k in ("side", "swap", "lost")), resumed.stderr
    assert "side.png changed since the earlier run" in resumed.stderr
    assert "swap.pgm changed since the earlier run" in resumed.stderr
    assert (out / "lost" / "relit_A+030E+10.png").is_file()


def test_resume_after_the_input_folder_was_renamed_redoes_nothing_and_keeps_the_names(tmp_path):
    """A renamed input folder made ``--resume`` redo every photo under a ``-2`` name: an input is now
    also known by what it is made of when its old path is gone."""
    src = _faces(tmp_path / "in", 3)
    out = tmp_path / "out"
    assert _run([src], out).returncode == 0
    before = _mtimes(out)
    moved = tmp_path / "renamed"
    src.rename(moved)
    _face(moved / "new.png", 7)  # and one photo added
    resumed = _run([moved], out, "--resume")
    assert resumed.returncode == 0, resumed.stderr
    after = _mtimes(out)
    assert {k: after[k] for k in before} == before and set(after) == {*before, "new"}
    summary = {r["stem"]: r["source"] for r in json.loads((out / "summary.json").read_text())}
    assert summary == {**{f"face{k}": str(moved / f"face{k}.png") for k in range(3)}, "new": str(moved / "new.png")}
    entries = RunManifest.load(out).entries.values()
    assert sorted((e.name, e.frame, e.path) for e in entries) == sorted(
        [(f"face{k}", k, str(moved / f"face{k}.png")) for k in range(3)] + [("new", 3, str(moved / "new.png"))])
    again = _run([moved], out, "--resume")
    assert again.returncode == 0 and _mtimes(out) == after
