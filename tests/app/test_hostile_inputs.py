"""Hostile use of the inputs (the watched folder, the names of inputs, sidecars, the run's own files in
--out): nothing a user gave is lost, nothing left waiting is called done. Each case failed as described
before its fix."""
import json
import os
import shutil
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from shadowflow.nodes.app.cli import main


def _face(path, seed=3, az=30):
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    return write_shadowed_face(path, np.random.default_rng(seed), light_from_angles(az))


@pytest.mark.slow
def test_the_watch_idle_clock_starts_when_the_last_file_is_handed_on(tmp_path):
    """``--watch --idle-exit S`` ended with photos still waiting (34 of 160 processed) when the run took
    longer than S over a burst: the clock ran from when the burst was listed."""
    from shadowflow.nodes.app.inputs import FolderWatch

    for k in range(12):
        cv2.imwrite(str(tmp_path / f"f{k:02d}.png"), np.full((40, 40), 100 + k, np.uint8))
    watch = FolderWatch(tmp_path, {".png"}, idle_exit=0.3, poll=0.05, settle=0.0)
    taken = []
    for path in watch:  # a consumer slower than the idle time, as a run over a burst is
        taken.append(path)
        time.sleep(0.1)
    assert len(taken) == 12


@pytest.mark.slow
def test_inputs_named_like_the_runs_own_files_get_folders_of_their_own(tmp_path):
    """Inputs named summary.json.png, report.html.png, manifest.json.png, run.mcap.png, run.rrd.png:
    their output folders collided with the run's files ("free space" errors, no report), and
    --resume could never get past them."""
    src = tmp_path / "in"
    src.mkdir()
    base = _face(src / "face.png")
    names = ["summary.json.png", "report.html.png", "manifest.json.png", "run.mcap.png", "run.rrd.png"]
    for name in names:
        (src / name).write_bytes(base.read_bytes())
        (src / name).with_suffix(".json").write_text(base.with_suffix(".json").read_text())
    out = tmp_path / "out"
    for resume in ([], ["--resume"]):
        assert main(["run", str(src), "--out", str(out), "--quiet", *resume]) == 0
        records = json.loads((out / "summary.json").read_text())
        assert [r["status"] for r in records] == ["ok"] * 6
    stems = {r["stem"] for r in records}
    assert {"summary.json-2", "report.html-2", "manifest.json-2", "run.mcap-2", "run.rrd-2"} <= stems
    assert (out / "report.html").is_file() and (out / "run.mcap").is_file()


def test_out_in_the_input_folder_never_writes_over_a_photos_sidecar(tmp_path, capsys):
    """``--out`` the input folder: the run's summary.json and manifest.json overwrote the sidecars of
    photos called summary.png and manifest.png (and manifest.png was fitted with the run's manifest as
    its sidecar)."""
    src = tmp_path / "in"
    src.mkdir()
    base = _face(src / "face.png")
    for name in ("summary", "manifest"):
        (src / f"{name}.png").write_bytes(base.read_bytes())
        (src / f"{name}.json").write_text(base.with_suffix(".json").read_text())
    before = {p.name: p.read_bytes() for p in src.iterdir()}
    assert main(["run", str(src), "--out", str(src), "--quiet", "--record", "none"]) == 2
    assert "is the run's own" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in src.iterdir() if p.name in before} == before


def test_relight_files_are_never_written_over_an_input(tmp_path, capsys):
    """A photo sitting where a ``--relight`` file goes (``OUT/<stem>/relit_A+030E+00.png``) was overwritten. In a
    folder no run made (it holds the photo's sidecar) the photo's outputs go elsewhere (``face-2``); in an earlier
    run's output folder the frame fails rather than write over it."""
    out = tmp_path / "out"
    (out / "face").mkdir(parents=True)
    photo = _face(out / "face" / "relit_A+030E+00.png")
    src = tmp_path / "in"
    src.mkdir()
    _face(src / "face.png", seed=4)
    before = photo.read_bytes()
    args = [str(src / "face.png"), str(photo), "--out", str(out), "--quiet", "--record", "none", "--relight=30,0"]
    assert main(["run", *args]) == 0
    assert photo.read_bytes() == before and (out / "face-2" / "relit.png").is_file()
    assert not (out / "face" / "relit.png").exists()
    shutil.rmtree(out)
    assert main(["run", str(src / "face.png"), "--out", str(out), "--quiet", "--record", "none"]) == 0
    photo = _face(out / "face" / "relit_A+030E+00.png")
    photo.with_suffix(".json").unlink()
    before = photo.read_bytes()
    assert main(["run", *args]) == 1
    assert photo.read_bytes() == before
    assert "would overwrite an input" in capsys.readouterr().err


def test_two_relight_lights_with_one_file_name_are_refused(tmp_path, capsys):
    """``--relight`` lights within a degree wrote one file name, the earlier ones lost."""
    src = _face(tmp_path / "face.png")
    assert main(["run", str(src), "--out", str(tmp_path / "out"), "--quiet", "--relight=30,0",
                 "--relight=30.2,0.1"]) == 2
    assert "give them a degree apart" in capsys.readouterr().err


@pytest.mark.parametrize("eyes", ["82,48,46,48", "sidecar"])
def test_eyes_given_right_eye_first_are_taken_in_image_order(tmp_path, eyes):
    """Eyes given image-right first (``--eyes`` or a sidecar) were fitted upside down and called ``ok``."""
    src = _face(tmp_path / "face.png")
    side = json.loads(src.with_suffix(".json").read_text())
    args = ["--light", "30,0"]
    if eyes == "sidecar":
        src.with_suffix(".json").write_text(json.dumps({"eyes": side["eyes"][::-1]}))
    else:
        src.with_suffix(".json").write_text(json.dumps({}))
        args += ["--eyes", eyes]
    out = tmp_path / "out"
    assert main(["run", str(src), "--out", str(out), "--quiet", "--record", "none", *args]) == 0
    rec = json.loads((out / "summary.json").read_text())[0]
    assert rec["status"] == "ok" and rec["faces"][0]["eyes"] == [[46.0, 48.0], [82.0, 48.0]]
    normals = np.load(out / "face" / "normals.npy")
    assert np.nanmedian(normals[:40, :, 1]) > 0  # the forehead faces up: the face is fitted the right way up


def test_a_folder_and_a_watched_folder_take_the_same_files(tmp_path):
    """``.webp``, ``.gif`` and ``.jfif`` were skipped in folders but read when named; ``--watch`` took a
    Mac's ``._face.png`` companions, which folder mode skips."""
    from PIL import Image
    from shadowflow.nodes.app.inputs import FolderWatch, expand_inputs
    from shadowflow.nodes.photo.loader import IMAGE_SUFFIXES, read_photo

    rng = np.random.default_rng(3)
    pixels = rng.integers(0, 255, (120, 100, 3)).astype(np.uint8)
    for name, fmt in (("a.png", "PNG"), ("b.webp", "WEBP"), ("c.gif", "GIF"), ("d.jfif", "JPEG")):
        Image.fromarray(pixels).save(tmp_path / name, format=fmt)
    (tmp_path / "._a.png").write_bytes(b"\x00\x05\x16\x07 resource fork")
    (tmp_path / "notes.txt").write_text("not an image")
    old = time.time() - 60
    for p in tmp_path.iterdir():
        os.utime(p, (old, old))
    folder = [Path(p).name for p in expand_inputs([str(tmp_path)], note=lambda msg: None)]
    watched = [Path(p).name for p in FolderWatch(tmp_path, IMAGE_SUFFIXES, idle_exit=0.0, poll=0.01, settle=0.0)]
    assert folder == watched == ["a.png", "b.webp", "c.gif", "d.jfif"]
    for name in folder:
        assert read_photo(tmp_path / name).grey.shape == (120, 100)


def test_junk_photos_are_refused_before_the_fit_and_record_no_iteration(tmp_path, capsys):
    """1,500 noise files made a 4.35 GB run.mcap (100 fit iterations each): a refused frame records
    nothing past its refusal."""
    from shadowflow.flow.replay import open_recording

    rng = np.random.default_rng(5)
    src = tmp_path / "junk"
    src.mkdir()
    for k in range(3):
        noise = rng.integers(0, 255, (240, 320, 3)).astype(np.uint8)
        cv2.imwrite(str(src / f"noise{k}.png"), cv2.GaussianBlur(noise, (0, 0), 2.0 * k + 0.5))
    assert main(["run", str(src), "--out", str(tmp_path / "out"), "--record", "mcap", "--quiet"]) == 1
    rec = open_recording(tmp_path / "out" / "run.mcap")
    assert [fr.record["status"].endswith("no face found") for fr in rec.finished_frames()] == [True] * 3
    assert all(not fr.scalars and not fr.arrays for fr in rec.finished_frames())
    assert (tmp_path / "out" / "run.mcap").stat().st_size < 20_000


# -- the fourth round (issue 64) ------------------------------------------------------------------


def test_an_empty_out_is_refused_and_a_folder_no_run_made_keeps_its_files(tmp_path, monkeypatch, capsys):
    """``--out ""`` wrote into the working folder and overwrote the ``report.html``, ``manifest.json`` and
    ``summary.json`` that were there (exit 0); so did ``--out .`` or any folder holding files of those names that
    no run wrote. A run's own folder (its ``.lock``, its manifest) is still written over, as before."""
    photo = _face(tmp_path / "in" / "face.png") if (tmp_path / "in").mkdir() is None else None
    work = tmp_path / "work"
    work.mkdir()
    mine = {"report.html": "<p>my report</p>", "manifest.json": '{"mine": 1}', "summary.json": "[1, 2]",
            "run.mcap": "my recording"}
    for name, text in mine.items():
        (work / name).write_text(text)
    monkeypatch.chdir(work)
    for out in ("", "  ", ".", str(work)):
        assert main(["run", str(photo), "--out", out, "--quiet", "--record", "none"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and ("an empty name" in err[0] if not out.strip() else "which no shadowflow run wrote"
                                  in err[0] and "manifest.json" in err[0]), err
    assert {p.name: p.read_text() for p in work.iterdir()} == mine
    with pytest.raises(ValueError, match="an empty name"):
        import shadowflow
        shadowflow.run([photo], "")
    out = tmp_path / "out"  # a run's own folder: run again over it, with or without its manifest
    for _ in range(2):
        assert main(["run", str(photo), "--out", str(out), "--quiet", "--record", "none"]) == 0
        (out / "manifest.json").unlink()
    assert json.loads((out / "summary.json").read_text())[0]["status"] == "ok"


def test_a_users_file_or_folder_named_like_an_output_folder_is_left_alone(tmp_path):
    """``--out`` the input folder: a user's own folder ``README/`` beside ``README.png`` had its ``relit.png``
    overwritten without a word, and a user's file ``notes`` beside ``notes.png`` made that photo fail every run
    (``FileExistsError``). Each photo takes another name now, on every run, and what was there is left as it was."""
    src = tmp_path / "in"
    src.mkdir()
    for name in ("README", "notes", "plain"):
        _face(src / f"{name}.png")
    (src / "README").mkdir()
    (src / "README" / "relit.png").write_bytes(b"my own picture")
    (src / "README" / "todo.txt").write_text("mine")
    (src / "notes").write_text("my notes")
    (src / "plain").mkdir()
    (src / "plain" / "relit.png").write_bytes(b"my own picture")  # holds only a name a run writes, but no run made it
    for _ in range(2):  # and the names stay the same on the next run
        assert main(["run", str(src), "--out", str(src), "--quiet", "--record", "none"]) == 0
        records = json.loads((src / "summary.json").read_text())
        assert sorted((r["stem"], r["status"]) for r in records) == [("README-2", "ok"), ("notes-2", "ok"),
                                                                      ("plain-2", "ok")]
    assert (src / "README" / "relit.png").read_bytes() == b"my own picture" == (src / "plain" / "relit.png").read_bytes()
    assert (src / "notes").read_text() == "my notes" and sorted(p.name for p in (src / "README").iterdir()) == \
        ["relit.png", "todo.txt"]
    assert all((src / f"{n}-2" / "normals.npy").is_file() for n in ("README", "notes", "plain"))
    shutil.rmtree(src / "plain-2")  # and a folder a run made, replaced by the user's own: --resume goes elsewhere
    (src / "plain-2").mkdir()
    (src / "plain-2" / "relit.png").write_bytes(b"mine now")
    assert main(["run", str(src), "--out", str(src), "--quiet", "--record", "none", "--resume"]) == 0
    assert (src / "plain-2" / "relit.png").read_bytes() == b"mine now" and (src / "plain-3" / "relit.png").is_file()


@pytest.mark.slow
def test_a_sidecar_arriving_after_its_photo_is_applied_by_the_watch(tmp_path):
    """``--watch``: a sidecar arriving 3 s after its photo was never applied (the watch knew the photo by its own
    size and time, and the run took it again only if those changed); only a later ``--resume`` noticed. The photo
    is taken again when its sidecar comes or changes, and redone under its name."""
    import threading

    from shadowflow.nodes.geometry.reflectance import light_from_angles

    src, out = tmp_path / "watched", tmp_path / "out"
    src.mkdir()
    sidecar = json.loads(_face(tmp_path / "face.png", az=-40).with_suffix(".json").read_text())
    (tmp_path / "face.png").rename(src / "face.png")  # the photo alone first
    given = light_from_angles(-40).tolist()

    def sidecar_later():
        deadline = time.time() + 120
        while time.time() < deadline and not (out / "summary.json").is_file():
            time.sleep(0.1)
        (src / "face.json").write_text(json.dumps(sidecar))

    writer = threading.Thread(target=sidecar_later)
    writer.start()
    # the idle clock runs from when the photo is handed on, and the photo may take 40 s (its turned views built into
    # a fresh cache): the watch must outlast it for the sidecar to arrive
    code = main(["run", "--watch", str(src), "--idle-exit", "60", "--settle", "0.2", "--out", str(out), "--quiet",
                 "--record", "none"])
    writer.join()
    assert code == 0
    records = json.loads((out / "summary.json").read_text())
    assert [r["stem"] for r in records] == ["face"] and records[0]["light_source"] == "sidecar"
    np.testing.assert_allclose(records[0]["light"], given, atol=1e-6)


def test_file_names_cannot_drive_the_terminal_or_forge_a_line(tmp_path, capsys):
    """Escape sequences in file names (ESC, OSC, BEL, C1) were printed raw on the terminal by ``run``: a name could
    retitle or recolour it, or forge an ``error:`` line with a newline (``replay`` already escaped them)."""
    src = tmp_path / "in"
    src.mkdir()
    names = ["\x1b]0;owned\x07title.png", "\x1b[31mred\x1b[0m.png", "\x9b2Jclear.png", "two\nerror: forged.png",
             "bell\x07.txt"]
    for name in names:
        (src / name).write_bytes(b"not an image")
    assert main(["run", str(src), "--out", str(tmp_path / "out"), "--record", "none"]) == 1
    assert main(["run", str(src / "\x1b[2Jnone*.png"), "--out", str(tmp_path / "out2")]) == 2  # an argument's too
    err = capsys.readouterr().err
    assert not any(c in err for c in "\x1b\x07\x9b"), repr(err)
    lines = err.splitlines()
    assert sum(line.startswith("error: ") for line in lines) == 4, lines  # one a bad file: none forged
    assert not any(line.startswith("error: forged") for line in lines)
    assert any("\\x1b]0;owned\\x07title.png" in line for line in lines)


def test_demo_inputs_are_never_written_through_a_link(tmp_path, capsys):
    """``--demo`` with ``OUT/demo-inputs`` a symbolic link out of ``--out`` wrote the demo's photos and sidecars
    where it pointed; a link at one of the demo's file names was written through the same way."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (out / "demo-inputs").symlink_to(elsewhere, target_is_directory=True)
    assert main(["run", "--demo", "--out", str(out), "--quiet", "--record", "none"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "demo-inputs: is a symbolic link" in err[0], err
    assert list(elsewhere.iterdir()) == []
    from shadowflow.nodes.app.cli.run import write_demo_inputs

    (out / "demo-inputs").unlink()
    (out / "demo-inputs").mkdir()
    victim = elsewhere / "victim.png"
    victim.write_bytes(b"keep me")
    (out / "demo-inputs" / "demo-1_A+045E+00.png").symlink_to(victim)
    written = write_demo_inputs(out, count=1)
    assert victim.read_bytes() == b"keep me" and list(elsewhere.iterdir()) == [victim]
    assert not Path(written[0]).is_symlink() and Path(written[0]).stat().st_size > 1000


def test_a_novel_view_larger_than_the_surface_it_shows_is_refused(tmp_path, capsys):
    """``--view-size 4096`` cost 4.4 GB for one face, ``--view-size 2048`` on a photo of 49 faces ran past the frame
    timeout in the novel view and lost all 49 faces: rendering costs memory and time with the square of the side,
    and the surface shown is the fit's (128^2, at most 512^2). Over 512 is refused in one line before any work,
    by the command line and the API alike."""
    import cv2

    import shadowflow
    from shadowflow.nodes.method.options import MethodOptions

    photo = _face(tmp_path / "face.png")
    for size in ("513", "2048", "4096"):
        assert main(["run", str(photo), "--out", str(tmp_path / f"out{size}"), "--view-size", size]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--view-size is a side of 32 to 512 pixels" in err[0], err
        assert not (tmp_path / f"out{size}").exists()
    with pytest.raises(ValueError, match="--view-size is a side of 32 to 512"):
        shadowflow.run([photo], tmp_path / "api", options=MethodOptions(novel_size=4096))
    assert main(["run", str(photo), "--out", str(tmp_path / "out"), "--view-size", "512", "--quiet", "--record",
                 "none"]) == 0
    assert cv2.imread(str(tmp_path / "out" / "face" / "novel_view.png")).shape[:2] == (512, 512)
