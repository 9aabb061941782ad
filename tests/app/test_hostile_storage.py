"""Hostile storage under a run: a full disk or file-size limit, a store that takes no more, an unwritable
``--out``, links planted in it. Every file is complete or absent, the run stops with one line naming the
file, and ``--resume`` completes the job. Moved here from the app's hostile suite (storage is its layer)."""
import json
import os
import re
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from shadowflow.flow.manifest import RunManifest

from conftest import run_cli

CLI = [sys.executable, "-m", "shadowflow.nodes.app.cli"]
REPO = Path(__file__).resolve().parents[2]


def _limit_file_size(limit: int):
    def apply() -> None:  # Python ignores SIGXFSZ, so writes past the limit fail with EFBIG
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return apply


@pytest.mark.slow
@pytest.mark.parametrize("record", ["none", "mcap"])
def test_a_full_disk_stops_the_run_with_a_clear_error_and_resume_finishes(tmp_path, record, shadowed_faces):
    src = shadowed_faces(tmp_path / "in", 3, seed=3)
    out = tmp_path / "out"
    cmd = CLI + ["run", str(src), "--out", str(out), "--record", record, "--max-iterations", "10"]
    limit = 60_000 if record == "none" else 400_000  # normals.npy (196 KB) / a frame of MCAP won't fit
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, timeout=300,
                          preexec_fn=_limit_file_size(limit))
    assert proc.returncode == 1
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and "File too large" in errors[0] and "--resume" in errors[0], proc.stderr
    # the last line names no report: none was written
    assert "done in" in proc.stderr.splitlines()[-1] and "report" not in proc.stderr.splitlines()[-1], proc.stderr
    assert not (out / "report.html").exists()
    # no file is left half-written under its real name: each is complete or absent
    for p in out.rglob("*"):
        assert not p.name.endswith(".tmp"), p
        if p.suffix == ".npy":
            np.load(p, allow_pickle=False)
    done = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else []
    # summary.json calls done exactly the frames --resume will reuse: not the one whose output or
    # recording failed, nor any that finished after the run stopped taking data
    journaled = RunManifest.load(out)
    assert sorted(r["stem"] for r in done) == sorted(e.name for e in journaled.entries.values())
    assert len(done) < 3
    resumed = run_cli(cmd[len(CLI):] + ["--resume"])
    assert resumed.returncode == 0, resumed.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert [r["status"] for r in summary] == ["ok"] * 3
    if record == "mcap":  # issue 39 #8: the cut part does not make the job's recording unreadable
        replay = run_cli(["replay", out])
        assert replay.returncode == 0, replay.stderr
        assert all(r["stem"] in replay.stdout for r in summary), replay.stdout
        fresh = tmp_path / "fresh"
        made = run_cli([str(fresh) if x == str(out) else x for x in cmd[len(CLI):]])
        assert made.returncode == 0, made.stderr
        diff = run_cli(["diff", out, fresh])
        assert diff.returncode == 0 and diff.stdout.startswith("same: 3 frames"), diff.stdout + diff.stderr


def test_a_run_store_that_takes_no_more_stops_the_run_and_resume_finishes(tmp_path, monkeypatch, capsys,
                                                                          procedural_model, shadowed_faces):
    """The records' store (``OUT/.run.sqlite``) failing as a full disk does: the same as any output."""
    import errno

    import shadowflow
    from shadowflow.flow.runstore import RunStore

    src = shadowed_faces(tmp_path / "in", 3, seed=5)
    out = tmp_path / "out"
    put, calls = RunStore.put_record, []

    def full_on_the_second(self, name, record):
        calls.append(name)
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "database or disk is full", str(self.path))
        put(self, name, record)

    monkeypatch.setattr(RunStore, "put_record", full_on_the_second)
    result = shadowflow.run([src], out, model=procedural_model, record=(), quiet=False)
    err = capsys.readouterr().err
    assert result.storage_error == f"{out / '.run.sqlite'}: cannot be written (database or disk is full)"
    assert f"error: {result.storage_error}; stopping" in err and not result.stopped
    summary = json.loads((out / "summary.json").read_text())
    assert result.frames == len(summary) < 3 and all(r["status"] == "ok" for r in summary)
    assert calls[1] not in [r["stem"] for r in summary]
    # frames that finish after the stop are not recorded as done: --resume redoes them
    assert len(calls) == 2
    assert sorted(r["stem"] for r in summary) == sorted(e.name for e in RunManifest.load(out).entries.values())
    assert not (out / ".run.sqlite").exists()
    monkeypatch.setattr(RunStore, "put_record", put)
    again = shadowflow.run([src], out, model=procedural_model, record=(), resume=True)
    assert again.storage_error is None and [r["status"] for r in again.records] == ["ok"] * 3


def test_the_run_store_names_itself_when_the_disk_is_full(tmp_path):
    """A real write limit (RLIMIT_FSIZE, as a full disk): ``OSError`` naming the store's file."""
    code = ("import resource, sys\n"
            "from shadowflow.flow.runstore import RunStore\n"
            "store = RunStore(sys.argv[1])\n"
            "resource.setrlimit(resource.RLIMIT_FSIZE, (40_000, 40_000))\n"
            "try:\n"
            "    for i in range(10_000):\n"
            "        store.put_record(f'r{i}', {'x': 'y' * 200})\n"
            "except OSError as exc:\n"
            "    print(exc.errno, exc.filename, exc.strerror, sep='|')\n")
    proc = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=120)
    errno_, filename, why = proc.stdout.strip().split("|")
    assert filename == str(tmp_path / ".run.sqlite") and why, proc.stderr
    assert int(errno_) > 0


def test_an_unwritable_out_is_refused_before_any_work(tmp_path, unprivileged):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    proc = subprocess.run(CLI + ["run", "--demo", "--out", str(blocker / "out")], capture_output=True, text=True,
                          cwd=REPO, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"shadowflow run: --out {blocker / 'out'}: cannot write there (Not a directory)"
    ro = tmp_path / "ro"
    ro.mkdir()
    os.chmod(ro, 0o555)
    proc = subprocess.run(unprivileged + CLI + ["run", "--demo", "--out", str(ro)], capture_output=True,
                          text=True, cwd=REPO, timeout=120)
    assert proc.returncode == 2 and "cannot write there (Permission denied)" in proc.stderr
    assert list(ro.iterdir()) == []


@pytest.mark.slow
def test_links_planted_in_out_are_never_written_through(tmp_path):
    """A run.mcap, run.rrd or OUT/<stem> that is a symbolic link to a file or folder outside --out
    was followed, and what it named overwritten."""
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    src = tmp_path / "in"
    src.mkdir()
    write_shadowed_face(src / "face.png", np.random.default_rng(2), light_from_angles(30))
    victim = tmp_path / "precious.txt"
    victim.write_text("keep me")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    for planted in ("run.mcap", "run.rrd"):
        out = tmp_path / f"out-{planted}"
        out.mkdir()
        (out / planted).symlink_to(victim)
        proc = subprocess.run(CLI + ["run", str(src), "--out", str(out), "--quiet"], capture_output=True, text=True,
                              timeout=300)
        assert proc.returncode == 2 and "symbolic link" in proc.stderr, proc.stderr
        assert victim.read_text() == "keep me"
    out = tmp_path / "out-stem"
    out.mkdir()
    (out / "face").symlink_to(elsewhere, target_is_directory=True)  # not a run's folder: the photo takes another name
    proc = subprocess.run(CLI + ["run", str(src), "--out", str(out), "--quiet", "--record", "none"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert list(elsewhere.iterdir()) == [] and (out / "face-2" / "relit.png").is_file()


def test_a_manifest_with_a_400_digit_frame_is_redone_not_a_traceback(tmp_path, procedural_model):
    """``--resume`` over a manifest whose entry held a 400-digit ``frame`` ended in a traceback (``OverflowError:
    Python int too large to convert to SQLite INTEGER``): frame ids are under 2^53 (as recordings' are), such an
    entry is not one this code wrote, and its input is redone."""
    import shadowflow
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    src = write_shadowed_face(tmp_path / "face.png", np.random.default_rng(3), light_from_angles(30))
    out = tmp_path / "out"
    shadowflow.run([src], out, model=procedural_model, record=())
    man = json.loads((out / "manifest.json").read_text())
    man["inputs"][0]["frame"] = int("9" * 400)
    (out / "manifest.json").write_text(json.dumps(man))
    again = shadowflow.run([src], out, model=procedural_model, record=(), resume=True)
    assert [r["status"] for r in again.records] == ["ok"]
    assert RunManifest.load(out).entries[str(src)].frame == 0


def _two_faces(folder: Path) -> Path:
    """A photo of two rendered faces side by side (ICT-FaceKit identities, no sidecar): both are found."""
    import cv2
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    folder.mkdir()
    rng = np.random.default_rng(5)
    faces = [cv2.imread(str(write_shadowed_face(folder / f"{k}.png", rng, light_from_angles(az), grid=(192, 192),
                                                source="ict")), cv2.IMREAD_GRAYSCALE) for k, az in ((0, 20), (1, -20))]
    for k in range(2):
        (folder / f"{k}.png").unlink()
        (folder / f"{k}.json").unlink()
    pad = np.zeros((192, 40), np.uint8)
    cv2.imwrite(str(folder / "two.png"), np.hstack([pad, faces[0], pad, faces[1], pad]))
    return folder / "two.png"


def test_resume_after_a_face_folder_was_deleted_writes_it_again(tmp_path, cli):
    """``--resume`` after ``OUT/two/face-2/`` (a photo's second face) was deleted said "done": the folder was never
    written again, and the summary still listed it. A photo is complete only with every face folder its record
    lists; a file gone from one of them counts the same."""
    photo = _two_faces(tmp_path / "in")
    out = tmp_path / "out"
    args = ["run", str(photo), "--out", str(out), "--quiet", "--record", "none"]
    assert cli(args).returncode == 0
    faces = json.loads((out / "summary.json").read_text())[0]["faces"]
    assert [f.get("dir") for f in faces] == ["two", "two/face-2"]
    before = (out / "two" / "face-2" / "normals.npy").read_bytes()
    for gone in ("two/face-2", "two/face-2/mesh.ply"):
        target = out / gone
        shutil.rmtree(target) if target.is_dir() else target.unlink()
        assert cli(args + ["--resume"]).returncode == 0
        assert (out / "two" / "face-2" / "normals.npy").read_bytes() == before
        assert (out / "two" / "face-2" / "mesh.ply").is_file()


def test_a_killed_writes_temporary_files_go_when_its_photo_is_written_again(tmp_path, cli):
    """A worker killed while it wrote a photo's files (a Dask worker, ``kill -9``) leaves its atomic write's temporary
    file; the photo is written again, by another worker or by ``--resume``, and that write takes the temporaries of
    its folders away (a cluster's run whose worker was killed mid-write left ``.novel_view.png.*.tmp`` behind)."""
    photo = _two_faces(tmp_path / "in")
    out = tmp_path / "out"
    args = ["run", str(photo), "--out", str(out), "--quiet", "--record", "none"]
    assert cli(args).returncode == 0
    stale = [out / "two" / ".relit.png.k1l2m3.tmp", out / "two" / "face-2" / ".novel_view.png.x9y8z7.tmp"]
    for path in stale:
        path.write_bytes(b"half a file")
    (out / "two" / "face-2" / "mesh.ply").unlink()  # so --resume writes the photo again
    assert cli(args + ["--resume"]).returncode == 0
    assert (out / "two" / "face-2" / "mesh.ply").is_file()
    assert [path.name for path in stale if path.exists()] == []


def _wait_for(predicate, what: str, seconds: float = 120.0) -> None:
    import time

    deadline = time.time() + seconds
    while not predicate():
        assert time.time() < deadline, f"waited {seconds:.0f} s for {what}"
        time.sleep(0.05)


@pytest.mark.slow
def test_out_removed_under_a_run_stops_it_and_the_next_run_owns_the_folder(tmp_path, shadowed_faces, cli):
    """``rm -rf OUT`` during a run, then a second run into ``OUT``: not refused (the first run's lock file was
    gone with the folder), and both wrote there: the final summary and manifest were the first run's, ``run.mcap``
    the second's. The first run now stops writing there at its next frame (one line, exit 1); the folder is the
    second run's alone."""
    import time

    watched = shadowed_faces(tmp_path / "watched", 1, seed=3)
    later = shadowed_faces(tmp_path / "later", 1, seed=4)
    other = shadowed_faces(tmp_path / "other", 1, seed=5)
    out = tmp_path / "out"
    first = subprocess.Popen(CLI + ["run", "--watch", str(watched), "--idle-exit", "8", "--settle", "0.1", "--out",
                                    str(out), "--quiet", "--record", "mcap"], stderr=subprocess.PIPE, text=True)
    _wait_for(lambda: (out / "f0" / "relit.png").is_file() and (out / "summary.json").is_file(), "the first frame")
    shutil.rmtree(out)
    assert cli(["run", str(other), "--out", str(out), "--quiet", "--record", "mcap"]).returncode == 0
    second = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file() and p.name != ".lock"}
    time.sleep(0.2)
    for p in later.iterdir():  # a new photo for the first run
        shutil.copy(p, watched / f"new{p.suffix}")
    _, err = first.communicate(timeout=300)
    assert first.returncode == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "removed or replaced during the run" in lines[0] and str(out) in lines[0], lines
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file() and p.name != ".lock"} == second
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ["f0"]  # the second run's only
    assert [Path(r["source"]).parent.name for r in json.loads((out / "summary.json").read_text())] == ["other"]


@pytest.mark.slow
def test_an_out_made_unwritable_mid_run_stops_with_one_line_and_resume_finishes(tmp_path, shadowed_faces,
                                                                                unprivileged):
    """An output folder made immutable mid-run (``chattr +i``) failed the frames one by one and ended in exit 2
    (``OUT/.run.sqlite``: the scratch store could not be removed); made read-only the same. Permission refused on
    a write into ``--out`` now stops the run as a full disk does: one ``error:`` line naming the file, exit 1."""
    watched = shadowed_faces(tmp_path / "watched", 1, seed=3)
    later = shadowed_faces(tmp_path / "later", 2, seed=4)
    out = tmp_path / "out"
    cmd = ["run", "--watch", str(watched), "--idle-exit", "8", "--settle", "0.1", "--out", str(out), "--record", "none"]
    first = subprocess.Popen(unprivileged + CLI + cmd, stderr=subprocess.PIPE, text=True)
    _wait_for(lambda: (out / "f0" / "relit.png").is_file() and (out / "summary.json").is_file(), "the first frame")
    os.chmod(out, 0o555)
    for p in later.iterdir():
        shutil.copy(p, watched / f"new-{p.name}")
    try:
        _, err = first.communicate(timeout=300)
    finally:
        os.chmod(out, 0o755)
    assert first.returncode == 1, err
    assert "Traceback" not in err and not any(line.startswith("shadowflow run:") for line in err.splitlines()), err
    errors = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and str(out) in errors[0] and "--resume" in errors[0], err
    resumed = subprocess.run(unprivileged + CLI + [*cmd[:4], "1", *cmd[5:], "--resume"], capture_output=True,
                             text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert len(json.loads((out / "summary.json").read_text())) == 3


def _read_arrays_bounded(folder: Path, limit: int = 2 << 30, timeout: float = 300) -> str:
    """``read_arrays(folder, on_photo_grid=True)`` in a process of its own limited to ``limit`` bytes of address
    space (a broken check then fails there, not on the machine): what it raised, or "read"."""
    code = ("import sys, shadowflow\n"
            "try:\n"
            "    shadowflow.read_arrays(sys.argv[1], on_photo_grid=True)\n"
            "    print('read')\n"
            "except (ValueError, MemoryError) as exc:\n"
            "    print(type(exc).__name__, exc)\n")
    proc = subprocess.run([sys.executable, "-c", code, str(folder)], capture_output=True, text=True, timeout=timeout,
                          preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit)))
    return proc.stdout.strip() or proc.stderr.strip()[-500:]


def test_read_arrays_of_a_hostile_grid_json_is_refused_before_anything_photo_sized(tmp_path, procedural_model):
    """``read_arrays(folder, on_photo_grid=True)`` given a ``grid.json`` whose ``photo`` was ``[40000, 40000]`` tried
    to allocate 6.4 GB an array, and more for the warp's own (23 GB when tried here unbounded). The photo must be
    within the loader's limits and be ``mask.png``'s size, its placement a finite matrix; what is brought to the
    photo is brought into the face's box only (checked here under a 2 GiB address-space limit)."""
    import shadowflow
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    src = write_shadowed_face(tmp_path / "face.png", np.random.default_rng(3), light_from_angles(30))
    shadowflow.run([src], tmp_path / "out", model=procedural_model, record=())
    folder = tmp_path / "out" / "face"
    good = json.loads((folder / "grid.json").read_text())
    assert _read_arrays_bounded(folder) == "read"
    cases = [("photo", [40000, 40000], r"grid.json: photo \[40000, 40000\] is not a photo within the 40-megapixel"),
             ("photo", [6000, 6000], r"mask.png: 128x128, not the 6000x6000 photo grid.json gives"),
             ("to_photo", [[1e308, 0, 0], [0, "x", 0]], "grid.json: not a grid.json shadowflow wrote")]
    for field, value, says in cases:
        (folder / "grid.json").write_text(json.dumps({**good, field: value}))
        said = _read_arrays_bounded(folder)
        assert said.startswith("ValueError") and re.search(says, said), said
    (folder / "grid.json").unlink()
    os.mkfifo(folder / "grid.json")  # a pipe is not read: it would wait for a writer
    said = _read_arrays_bounded(folder, timeout=60)
    assert said.startswith("ValueError") and "grid.json: not a regular file" in said, said
