"""End-to-end runs of the ``shadowflow`` command on generated inputs."""
import json
import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest
from shadowflow.nodes.app.cli import main
from shadowflow.nodes.app.outputs import read_arrays

LAYOUT = {"normals.npy", "mask.png", "weights.npy", "depth.npy", "grid.json", "albedo.png", "shadow.png", "relit.png",
          "novel_view.png", "mesh.ply", "view.html"}


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    assert main(["run", "--demo", "--out", str(out), "--quiet"]) == 0
    return out


def test_run_writes_the_conventions_layout(demo_run):
    summary = json.loads((demo_run / "summary.json").read_text())
    assert len(summary) == 3 and all(r["status"] == "ok" for r in summary)
    for rec in summary:
        folder = demo_run / rec["stem"]
        assert {p.name for p in folder.iterdir()} == LAYOUT
        src = cv2.imread(rec["source"], cv2.IMREAD_GRAYSCALE)
        h, w = src.shape
        mask = cv2.imread(str(folder / "mask.png"), cv2.IMREAD_GRAYSCALE) == 255
        place = json.loads((folder / "grid.json").read_text())
        assert place["photo"] == [h, w] and place["depth_unit"] == "photo pixels"
        # the fit's arrays on its model grid, NaN where it did not see the face; on the photo's grid when asked
        n = np.load(folder / "normals.npy", allow_pickle=False)
        seen = np.isfinite(n[..., 0])
        assert n.shape == tuple(place["grid"]) + (3,) and n.dtype == np.float32 and seen.sum() > 4000
        for arrays in (np.load(folder / "normals.npy"), read_arrays(folder, on_photo_grid=True)["normals"]):
            known = np.isfinite(arrays[..., 0])
            np.testing.assert_allclose(np.linalg.norm(arrays[known], axis=-1), 1, atol=1e-5)
            assert np.all(arrays[known][:, 2] > 0) and np.all(np.isnan(arrays[~known]))
        on_photo = read_arrays(folder, on_photo_grid=True)
        assert on_photo["normals"].shape == (h, w, 3) and not np.isfinite(on_photo["normals"][~mask]).any()
        assert np.isfinite(on_photo["normals"][mask]).mean() > 0.99
        for name in ("weights", "depth"):
            a = np.load(folder / f"{name}.npy", allow_pickle=False)
            assert a.shape == tuple(place["grid"]) and np.array_equal(np.isfinite(a), seen)
            assert on_photo[name].shape == (h, w) and not np.isfinite(on_photo[name][~mask]).any()
        for name in ("albedo.png", "shadow.png"):
            img = cv2.imread(str(folder / name), cv2.IMREAD_UNCHANGED)
            assert img.shape == (h, w) and img.dtype == np.uint8 and not img[~mask].any()
        # relit.png is the whole photo, the face relit and put back: grey in, grey out, same size;
        # the black background of these renders stays black
        relit = cv2.imread(str(folder / "relit.png"), cv2.IMREAD_UNCHANGED)
        assert relit.shape == (h, w) and relit.dtype == np.uint8
        assert not relit[(src == 0) & ~mask].any() and relit[mask].mean() > 40
        assert rec["light_source"] == "sidecar" and rec["converged"] in (True, False)
        assert rec["iterations"] >= 1 and rec["final_sigma"] > 0


def test_run_recovers_the_demo_faces(demo_run):
    """The demo inputs are rendered from known faces; the outputs must match them."""
    from shadowflow.nodes.evaluation.scenes import draw_face, render_scene
    from shadowflow.nodes.geometry.normals import angle_deg
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    rng = np.random.default_rng(2024)  # the demo's generator
    summary = json.loads((demo_run / "summary.json").read_text())
    for rec, (az, el) in zip(summary, [(45, 0), (-60, 0), (30, 25)]):
        depth, mask, albedo = draw_face(rng, source="ict")
        s = light_from_angles(az, el)
        scene = render_scene(depth, albedo, s, mask)
        folder = demo_run / rec["stem"]
        n = np.load(folder / "normals.npy")
        ok = np.isfinite(n[..., 0]) & scene.valid
        err = np.mean(angle_deg(n[ok], scene.normals[ok]))
        relit = cv2.imread(str(folder / "relit.png"), 0) / 255.0
        truth = albedo * np.clip(scene.normals[..., 2], 0, 1)
        gain = np.sum(relit[ok] * truth[ok]) / np.sum(relit[ok] ** 2)  # relit.png is auto-exposed
        relit_err = np.mean(np.abs(gain * relit[ok] - truth[ok]))
        shadow = cv2.imread(str(folder / "shadow.png"), 0) == 255
        # shadow.png is found on the photo (far darker than the shape predicts): at grazing light,
        # n.s under 0.1, a pixel is near black either way and counts as neither
        clear = ok & (np.abs(np.nan_to_num(scene.normals) @ s) >= 0.1)
        agree = np.mean(shadow[clear] == scene.shadows.lit[clear])
        # held-out ICT identities, default (ICT) model: its floor on such faces is 5.6 deg (`shadowflow eval
        # --source ict --model ict`), the ears and nostrils it cannot represent at K = 60
        assert err < 8.0 and relit_err < 0.06 and agree > 0.95, (err, relit_err, agree)


def test_bad_inputs_fail_alone_and_inputs_are_never_overwritten(tmp_path, demo_run):
    good = sorted((demo_run / "demo-inputs").glob("*.png"))[0]
    folder = tmp_path / "in"
    folder.mkdir()
    shutil.copy(good, folder / "a face.png")
    shutil.copy(good.with_suffix(".json"), folder / "a face.json")
    (folder / "broken.png").write_bytes(b"\x89PNG garbage")
    (folder / "notes.txt").write_text("not an image")
    sub = folder / "sub"
    sub.mkdir()
    shutil.copy(good, sub / "a face.png")  # same stem as the other one
    shutil.copy(good.with_suffix(".json"), sub / "a face.json")
    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "shadowflow.nodes.app.cli", "run", str(folder), str(sub / "a face.png"),
                           "--out", str(out)], capture_output=True, text=True)
    assert proc.returncode == 1  # one frame failed
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "broken.png" in errors[0]
    assert "notes.txt: skipped" in proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert [r["status"] == "ok" for r in summary] == [True, False, True]
    assert [r["stem"] for r in summary] == ["a_face", "broken", "a_face-2"]
    assert {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} == before


def test_train_and_eval_commands(tmp_path, capsys):
    model = tmp_path / "small.npz"
    assert main(["train", "--source", "procedural", "--n", "30", "--modes", "20", "--size", "64,64",
                 "--out", str(model)]) == 0
    report = tmp_path / "r.json"
    assert main(["eval", "--model", str(model), "--n-test", "2", "--angles", "30", "--fit", "all",
                 "--json", str(report)]) == 0
    r = json.loads(report.read_text())
    assert set(r["results"]) == {"gauss-newton", "irls", "paper"} and r["grid"] == [64, 64]
    newton, alternating = r["results"]["gauss-newton"]["30"], r["results"]["irls"]["30"]
    assert 0 < newton["err_all"] < 10
    # two routes to the same fixed point: the same answer, in fewer Gauss-Newton steps
    assert abs(newton["err_all"] - alternating["err_all"]) < 0.2, (newton, alternating)
    assert newton["iterations"] < alternating["iterations"]
    assert "model floor" in capsys.readouterr().out


@pytest.mark.slow
def test_watch_processes_files_that_arrive_then_exits_when_idle(tmp_path, demo_run):
    import threading
    import time

    good = sorted((demo_run / "demo-inputs").glob("*.png"))
    inbox = tmp_path / "inbox"
    inbox.mkdir()
    shutil.copy(good[0], inbox / "first.png")
    shutil.copy(good[0].with_suffix(".json"), inbox / "first.json")

    def later():
        time.sleep(1.5)
        shutil.copy(good[1].with_suffix(".json"), inbox / "second.json")
        shutil.copy(good[1], inbox / "second.png")

    threading.Thread(target=later).start()
    out = tmp_path / "out"
    code = main(["run", "--watch", str(inbox), "--idle-exit", "3", "--out", str(out), "--quiet", "--record", "none"])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert [r["stem"] for r in summary] == ["first", "second"] and all(r["status"] == "ok" for r in summary)


@pytest.mark.slow
def test_watch_waits_for_a_slow_copy_and_takes_a_changed_file_again(tmp_path, demo_run, capsys):
    """A file copied in slowly was read half-written and failed; one that failed was never retried."""
    import threading
    import time

    good = sorted((demo_run / "demo-inputs").glob("*.png"))[0]
    data = good.read_bytes()
    inbox = tmp_path / "inbox"
    inbox.mkdir()
    for name in ("slow", "stall"):
        shutil.copy(good.with_suffix(".json"), inbox / f"{name}.json")

    def copy_in():
        with open(inbox / "slow.png", "wb") as f:  # grows for 1.8 s, never still for a second
            for k in range(6):
                f.write(data[k * len(data) // 6:(k + 1) * len(data) // 6])
                f.flush()
                time.sleep(0.3)
        (inbox / "stall.png").write_bytes(data[:len(data) // 2])  # a copy that stalls: taken, fails
        time.sleep(3.0)
        (inbox / "stall.png").write_bytes(data)  # completed: taken again

    writer = threading.Thread(target=copy_in)
    writer.start()
    out = tmp_path / "out"
    code = main(["run", "--watch", str(inbox), "--idle-exit", "4", "--out", str(out), "--record", "none"])
    writer.join()
    err = capsys.readouterr().err
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert {r["stem"]: r["status"] for r in summary} == {"slow": "ok", "stall": "ok"}
    assert err.count("stall.png: corrupt or truncated") == 1 and "slow.png: corrupt" not in err


@pytest.mark.slow
def test_watch_stops_with_one_line_when_its_folder_is_removed(tmp_path, demo_run, capsys):
    import threading
    import time

    inbox = tmp_path / "inbox"
    inbox.mkdir()
    shutil.copy(sorted((demo_run / "demo-inputs").glob("*.png"))[0], inbox / "a.png")

    def remove():
        time.sleep(2.0)
        shutil.rmtree(inbox)

    threading.Thread(target=remove).start()
    out = tmp_path / "out"
    code = main(["run", "--watch", str(inbox), "--out", str(out), "--record", "none", "--quiet"])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err
    assert f"error: --watch {inbox}: No such file or directory; stopped watching" in err
    assert [r["stem"] for r in json.loads((out / "summary.json").read_text())] == ["a"]


@pytest.mark.parametrize("given, says", [
    (["{tmp}/nothing/*.png"], "nothing/*.png: no file matches"),
    (["{tmp}/empty"], "empty holds no image file"),
    (["{tmp}/data"], "data holds no image file (folders inside are not read: name them, e.g. photos/)"),
])
def test_inputs_that_name_no_image_are_refused_and_nothing_is_written(tmp_path, capsys, given, says):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("not an image")
    (tmp_path / "data" / "photos").mkdir(parents=True)  # a data folder whose photos are a folder further in
    (tmp_path / "data" / "photos" / "face.png").write_bytes(b"")
    out = tmp_path / "out"
    code = main(["run", *[g.format(tmp=tmp_path) for g in given], "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and says in err[0] and err[0].startswith("shadowflow run: no input image"), err
    assert not out.exists()


def test_every_option_says_what_it_does_and_the_version_is_shown(capsys):
    import argparse

    from shadowflow.nodes.app.cli import build_parser
    from shadowflow.nodes.app.runner import tool_version

    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    silent = [f"{name} {a.option_strings or a.dest}" for name, sub in commands.items() for a in sub._actions
              if not a.help and not isinstance(a, argparse._HelpAction)]
    assert silent == []
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out.strip() == f"shadowflow {tool_version()}"


def test_an_input_given_twice_is_processed_once_under_one_name(tmp_path, demo_run, capsys):
    """The run remembers what it gave each input (in its store on disk): the second mention is
    said and skipped, and a same-named file elsewhere gets the next name."""
    good = sorted((demo_run / "demo-inputs").glob("*.png"))[0]
    other = tmp_path / "other"
    other.mkdir()
    for suffix in (".png", ".json"):
        shutil.copy(good.with_suffix(suffix), other / ("face" + suffix))
        shutil.copy(good.with_suffix(suffix), tmp_path / ("face" + suffix))
    face, twin = tmp_path / "face.png", other / "face.png"
    out = tmp_path / "out"
    code = main(["run", str(face), str(twin), str(face), "--out", str(out), "--record", "none"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert err.count(f"{face}: given more than once; processed once") == 1
    assert [r["stem"] for r in json.loads((out / "summary.json").read_text())] == ["face", "face-2"]


def test_a_light_given_by_its_angles_is_the_light_given_by_its_vector(tmp_path):
    """``--light=30,10`` (azimuth, elevation in degrees, Yale B's convention) and the vector it names,
    ``--light=-0.4924,0.1736,0.8529``, give the same fit; so do ``--relight`` and a sidecar's angles."""
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    src = tmp_path / "in"
    src.mkdir()
    photo = write_shadowed_face(src / "face.png", np.random.default_rng(6), light_from_angles(30, 10))
    eyes = json.loads(photo.with_suffix(".json").read_text())["eyes"]
    photo.with_suffix(".json").write_text(json.dumps({"eyes": eyes}))  # the light from the command line
    outs = {}
    for name, light in (("angles", "--light=30,10"), ("vector", "--light=-0.4924,0.1736,0.8529")):
        outs[name] = tmp_path / name
        assert main(["run", str(photo), "--out", str(outs[name]), "--quiet", "--record", "none", light,
                     "--relight=-20,0"]) == 0
    recs = [json.loads((outs[k] / "summary.json").read_text())[0] for k in outs]
    assert np.allclose(recs[0]["light"], recs[1]["light"], atol=1e-4)
    assert recs[0]["iterations"] == recs[1]["iterations"]
    a, b = (np.load(outs[k] / "face" / "normals.npy") for k in outs)
    # the vector is the angles' rounded to 4 decimals (5e-5 apart): the normals agree to 0.1 degree
    assert np.nanmax(np.abs(a - b)) < 3e-3 and np.nanmean(np.abs(a - b)) < 2e-4
    assert (outs["angles"] / "face" / "relit_A-020E+00.png").is_file()
    # the same angles in a sidecar
    photo.with_suffix(".json").write_text(json.dumps({"eyes": eyes, "light": [30, 10]}))
    side = tmp_path / "sidecar"
    assert main(["run", str(photo), "--out", str(side), "--quiet", "--record", "none"]) == 0
    rec = json.loads((side / "summary.json").read_text())[0]
    assert rec["light_source"] == "sidecar" and np.allclose(rec["light"], light_from_angles(30, 10), atol=1e-6)
    assert main(["run", str(photo), "--out", str(tmp_path / "bad"), "--quiet", "--light=200,0"]) == 2


def test_the_papers_variant_is_one_preset_and_what_is_given_wins():
    """``--fit paper`` used to swap the brightness scale and the albedo fill inside the chain, whatever was
    asked: ``--fit paper --remap ratio`` ran with the paper's peak. The variant is ``MethodOptions.paper()``
    now; an option given explicitly is kept."""
    from shadowflow.nodes.app.cli import build_parser, method_options
    from shadowflow.nodes.method.nodes import method_nodes
    from shadowflow.nodes.method.options import MethodOptions
    from shadowflow.nodes.method.robust_fit import FitConfig

    paper = MethodOptions.paper()
    assert (paper.fit, paper.remap, paper.albedo_fill) == (FitConfig.paper(), "peak", "mirror")
    parse = build_parser().parse_args
    plain = method_options(parse(["run", "--demo", "--out", "o", "--fit", "paper"]))
    assert (plain.remap, plain.albedo_fill) == ("peak", "mirror")
    asked = method_options(parse(["run", "--demo", "--out", "o", "--fit", "paper", "--remap", "ratio",
                                  "--albedo-fill", "ceiling"]))
    assert (asked.fit.solver, asked.remap, asked.albedo_fill) == ("paper", "ratio", "ceiling")
    default = method_options(parse(["run", "--demo", "--out", "o"]))
    assert (default.remap, default.albedo_fill) == ("ratio", "ceiling")
    for options, scale, ceiling in ((asked, "ratio", True), (plain, "peak", False)):
        nodes = {type(n).__name__: n for n in method_nodes(options, with_views=False)}
        assert nodes["RemapNode"].scale == scale and (nodes["AlbedoNode"].ceiling is not None) == ceiling


def test_the_command_lines_choices_are_the_options_own():
    """Every named choice of ``MethodOptions`` (``CHOICES``) and the fit's solvers are what ``run`` and ``eval``
    offer, defaults included: a new integrator or encoding reaches the command line without a second list."""
    import argparse

    from shadowflow.nodes.app.cli import build_parser
    from shadowflow.nodes.method.options import CHOICES, MethodOptions
    from shadowflow.nodes.method.robust_fit.config import SOLVERS

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for command in ("run", "eval"):
        actions = {a.dest: a for a in sub.choices[command]._actions}
        for name, allowed in CHOICES.items():
            if name in actions:
                assert tuple(actions[name].choices) == allowed, (command, name)
                default = actions[name].default
                assert default is None or default == getattr(MethodOptions(), name), (command, name)
        assert set(SOLVERS) <= set(actions["fit"].choices)
    assert set(CHOICES) - {"encoding", "arrays"} <= set(a.dest for a in sub.choices["eval"]._actions)


def test_each_numeric_options_rule_is_the_options_own():
    """Every numeric option's rule (``options.RANGES``) is stated once: the command line refuses a value past it
    with the rule's own words and flag, and the API's ``MethodOptions`` with the same words; the values on either
    edge are taken. A second, differently worded check in the command line (there were three) fails it."""
    from shadowflow.nodes.app.cli import build_parser, method_options
    from shadowflow.nodes.method.options import RANGES, MethodOptions

    parse = build_parser().parse_args
    flags = {a.option_strings[0]: a for a in parse.__self__._subparsers._group_actions[0].choices["run"]._actions
             if a.option_strings}
    for name, rule in RANGES.items():
        assert rule.flag in flags, (name, rule.flag)
        kind = flags[rule.flag].type or str
        for ok in (rule.lo, rule.hi):
            got = getattr(method_options(parse(["run", "--demo", "--out", "o", rule.flag, str(kind(ok / rule.per))])), name)
            assert got == pytest.approx(ok), (name, got)
        bad = kind(2 * rule.hi / rule.per + 1)
        with pytest.raises(ValueError) as cli:
            method_options(parse(["run", "--demo", "--out", "o", rule.flag, str(bad)]))
        with pytest.raises(ValueError) as api:
            MethodOptions(**{name: bad * rule.per})
        assert str(cli.value).startswith(f"{rule.flag} {rule.says}, not {bad:g}"), str(cli.value)
        assert str(api.value) == str(cli.value)


def test_a_line_on_stderr_is_one_write_so_threads_never_run_two_into_one(monkeypatch):
    """The run's status and notes go to stderr a whole line at a time: ``print`` writes a line's text and its
    newline apart, and a second thread writing between them runs two lines into one (a hostile stream's
    stderr once held 31 error lines for 32 failed inputs)."""
    import sys
    import threading

    from shadowflow.nodes.app.terminal import Progress, say

    class Writes:
        def __init__(self):
            self.calls, self.lock = [], threading.Lock()

        def write(self, text):
            with self.lock:
                self.calls.append(text)

        def flush(self):
            pass

        def isatty(self):
            return False

    stderr = Writes()
    monkeypatch.setattr(sys, "stderr", stderr)
    threads = [threading.Thread(target=lambda k=k: [say(f"error: {k}-{i}") for i in range(200)]) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    Progress(None, enabled=False).write("doubtful: a.png: small")
    assert len(stderr.calls) == 801 and all(c.endswith("\n") and c.count("\n") == 1 for c in stderr.calls)


def test_eval_yaleb_lights_are_the_tuned_eight_the_held_out_set_or_pairs_given():
    from shadowflow.nodes.app.cli.evaluate import yaleb_lights
    from shadowflow.nodes.evaluation.yaleb_benchmark import HELD_OUT_LIGHTS, INPUT_LIGHTS

    assert yaleb_lights("default") == INPUT_LIGHTS
    assert yaleb_lights("held-out") == HELD_OUT_LIGHTS and not set(HELD_OUT_LIGHTS) & set(INPUT_LIGHTS)
    assert yaleb_lights("25,0; -35,15") == [(25, 0), (-35, 15)]
    for bad in ("", "25", "25,0;x,1", "25,0,3"):
        with pytest.raises(ValueError, match="--lights"):
            yaleb_lights(bad)


@pytest.mark.parametrize("flag", [[], ["--foreign-shadows"]])
def test_eval_yaleb_relights_with_the_shadows_from_elsewhere_looked_for_when_asked(monkeypatch, tmp_path, flag):
    from shadowflow.nodes.app.cli import evaluate as cli_evaluate
    from shadowflow.nodes.app.cli import main

    seen = {}

    def fake_evaluate_yaleb(data, model, options, **kwargs):
        seen["options"] = options
        return {"rows": []}

    monkeypatch.setattr(cli_evaluate, "evaluate_yaleb", fake_evaluate_yaleb)
    monkeypatch.setattr(cli_evaluate, "summarise", lambda rows: {})
    monkeypatch.setattr(cli_evaluate, "format_report", lambda report, summary: "")
    assert main(["eval", "yaleb", "--data", str(tmp_path), *flag]) == 0
    assert seen["options"].foreign_shadows is bool(flag) and seen["options"].light == "yaleb"
