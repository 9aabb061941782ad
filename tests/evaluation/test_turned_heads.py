"""Turned heads end to end: held-out ICT identities rendered turned under a 45-degree light with cast shadows
(painted eyes, brows and lips), found, placed and fitted through the photo path (``shadowflow.fit``)."""
from __future__ import annotations

import numpy as np
import pytest
import shadowflow
from shadowflow.nodes.evaluation.turned import render_turned, score_turned
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.model.default_model import default_model
from shadowflow.nodes.model.faces.ict import shipped_basis
from shadowflow.nodes.photo.placement import outline_on_grid
from shadowflow.nodes.relight.nodes import LEFT

LIGHT = light_from_angles(45.0, 0.0)


@pytest.fixture(scope="module")
def identities():
    basis = shipped_basis()
    rng = np.random.default_rng(1000)  # the model's identities are drawn with seed 0: these are others
    return basis, [rng.standard_normal(basis.n_identity) for _ in range(2)]


def _run(basis, w, view):
    render = render_turned(basis, w, view, LIGHT, default_model())
    result = shadowflow.fit(render.photo, light=LIGHT)
    return render, result, score_turned(result.normals, render.normals, render.face)


def test_a_head_turned_30_degrees_is_fitted_with_its_view_as_well_as_a_frontal_one(identities):
    basis, ids = identities
    frontal = [_run(basis, w, (0.0, 0.0))[2] for w in ids]
    for yaw in (30.0, -30.0):
        runs = [_run(basis, w, (yaw, 0.0)) for w in ids]
        for render, result, score in runs:
            face = result.faces[0]
            # not refused nor doubtful for its turn; the relighting may give the face back as it was (turned 30 deg
            # from a light from 45, the far eye's socket is relit with a pasted patch: relight.nodes.harm_flag)
            assert face["status"] == "ok" or face["status"].endswith(LEFT), face["status"]
            assert abs(face["model_view"]["yaw"] - yaw) <= 10.0  # measured 25-35 at 30
            assert len(result.frame.meta["view_choice"]) >= 2
            # the fit trusts the face mesh's oval; the face's products reach its whole outline (the far cheek)
            model = result.frame.data["model"]
            fitted = result.frame.data["grid_valid"] & model.mask
            products = outline_on_grid(result.frame.data["placement"], model, render.photo.shape[:2]) & model.mask
            assert not (fitted & ~products).any() and (products & ~fitted).sum() > 0.005 * products.sum()  # 1.2 %
            assert score["coverage"] > 0.88  # measured 0.90-0.93 (0.98 frontal)
        error = np.mean([r[2]["error"] for r in runs])
        # measured 9.4-10.6 deg against 10.4-10.7 frontal: within 2 deg of the frontal faces
        assert error <= np.mean([f["error"] for f in frontal]) + 2.0
    assert all(f["coverage"] > 0.95 for f in frontal)


def test_a_head_turned_45_degrees_is_fitted_as_well_as_a_frontal_one_and_one_turned_60_is_refused(identities):
    """Views reach 50 deg of yaw (measured on three held-out identities under lights from -45, 0 and +45 deg: normals
    9.5-9.9 deg at +-40 and +-50 against 9.5 frontal, 0.90-0.92 of the visible face covered); a head turned 60 deg
    reads 50-53 and is refused with its yaw."""
    basis, ids = identities
    frontal = np.mean([_run(basis, w, (0.0, 0.0))[2]["error"] for w in ids])
    for yaw in (45.0, -45.0):
        runs = [_run(basis, w, (yaw, 0.0)) for w in ids]
        assert all(result.faces[0]["status"] == "ok" for _, result, _ in runs)
        assert all(abs(result.faces[0]["model_view"]["yaw"] - yaw) <= 5.0 for _, result, _ in runs)
        assert np.mean([score["error"] for *_, score in runs]) <= frontal + 3.0
        assert min(score["coverage"] for *_, score in runs) >= 0.85
    render = render_turned(basis, ids[0], (60.0, 0.0), LIGHT, default_model())
    with pytest.raises(ValueError, match=r"turned \+5\d(\.\d)? deg \(yaw\); faces turned up to 50 deg"):
        shadowflow.fit(render.photo, light=LIGHT)


@pytest.mark.slow
def test_the_yaw_is_read_within_3_degrees_under_a_light_from_either_side(identities):
    """The landmarks' yaw leans away from a side light, the fit's toward it: their mean is read within 3 deg on
    average under a light from either side (held-out identities turned -20...+20: measured +1.1 and -1.8 deg
    against the landmarks' +2.9 and -3.6)."""
    basis, ids = identities
    for azimuth in (45.0, -45.0):
        light = light_from_angles(azimuth, 0.0)
        read, landmarks = [], []
        for yaw in (-20.0, -10.0, 10.0, 20.0):
            for w in ids:
                result = shadowflow.fit(render_turned(basis, w, (yaw, 0.0), light, default_model()).photo, light=light)
                read.append(result.faces[0]["pose"]["yaw"] - yaw)
                landmarks.append(result.frame.meta["yaw_read"]["landmarks"] - yaw)
        assert abs(np.mean(read)) <= 3.0, (azimuth, read)
        assert abs(np.mean(landmarks)) >= abs(np.mean(read)) + 1.0, (azimuth, read, landmarks)  # 1.8 both


def test_the_frontal_model_alone_cannot_fit_a_turned_head(identities, monkeypatch):
    """What the turned models are for: the same 30-degree render fitted frontally is 3x off."""
    from shadowflow.nodes.method import turned

    basis, ids = identities
    turned_error = _run(basis, ids[0], (30.0, 0.0))[2]["error"]
    monkeypatch.setattr(turned, "views_near", lambda yaw, pitch: [(0.0, 0.0)])
    render, result, score = _run(basis, ids[0], (30.0, 0.0))
    assert "model_view" not in result.faces[0]
    assert score["error"] > turned_error + 10.0  # measured 33 against 8


def test_a_head_tilted_20_degrees_is_fitted_with_its_pitched_view_and_one_tilted_50_is_doubtful(identities,
                                                                                                   monkeypatch):
    """A face looking down, as in many portraits: read at -20...-24 deg of pitch it is fitted with the heads tilted
    20 deg (measured 11.0 / 11.3 deg against 16.7 / 18.8 frontally); read at -48 its normals are off by 19-20 deg
    whatever the view, and it says so."""
    from shadowflow.nodes.method import turned

    basis, ids = identities
    pitched = [_run(basis, w, (0.0, -20.0)) for w in ids]
    for render, result, score in pitched:
        assert result.faces[0]["status"] == "ok" and result.faces[0]["model_view"]["pitch"] == -20.0
    # a head tilted, not turned, mirrors about its midline as a frontal one: the fill takes the detail across it
    from shadowflow.nodes.method.options import MethodOptions
    from shadowflow.nodes.relight.nodes import PhotoRelightNode

    relight = PhotoRelightNode(MethodOptions()).face_relight(pitched[0][1].frame)
    assert relight.mirror_raise is not None and relight.seen.max() > 0.5
    render, result, _ = _run(basis, ids[0], (0.0, -50.0))
    assert result.faces[0]["status"].startswith("doubtful") and "tilted -4" in result.faces[0]["status"]
    # a model without pitched views (not ICT's: no turned heads to build) fits it frontally, and says so
    status = shadowflow.fit(pitched[1][0].photo, light=LIGHT, model="procedural").faces[0]["status"]
    assert status.startswith("doubtful") and "the frontal model fits up to 20 deg" in status  # read -24
    monkeypatch.setattr(turned, "FRONTAL_PITCH", 90.0)
    frontal = [_run(basis, w, (0.0, -20.0))[2]["error"] for w in ids]
    assert np.mean([r[2]["error"] for r in pitched]) < np.mean(frontal) - 3.0


def test_turned_surrey_faces_held_out_from_the_model_source_are_fitted_too(sfm_path):
    """Faces of another face model (the Surrey Face Model, evaluation only): 30 and 45 degrees within 3 of frontal
    (measured over three faces under lights from -45, 0 and +45: 10.0-10.1 at 30, 10.4-10.7 at 40, against 9.1),
    60 refused."""
    from shadowflow.nodes.evaluation.turned import render_turned_mesh
    from shadowflow.nodes.model.sources import eos_samples

    faces = eos_samples(str(sfm_path), 2, 1000)

    def error(face, view):
        render = render_turned_mesh(*face, view, LIGHT, default_model())
        result = shadowflow.fit(render.photo, light=LIGHT)
        assert result.faces[0]["status"] == "ok"
        return score_turned(result.normals, render.normals, render.face)["error"]

    frontal = np.mean([error(f, (0.0, 0.0)) for f in faces])
    for yaw in (30.0, -30.0, 45.0, -45.0):
        assert np.mean([error(f, (yaw, 0.0)) for f in faces]) <= frontal + 3.0
    with pytest.raises(ValueError, match="faces turned up to 50 deg"):
        shadowflow.fit(render_turned_mesh(*faces[0], (62.0, 0.0), LIGHT, default_model()).photo, light=LIGHT)


def test_a_run_says_once_that_it_builds_a_views_model_and_is_quiet_when_asked(identities, tmp_path, monkeypatch, cli):
    import cv2
    from shadowflow.nodes.model import default_model as dm

    basis, ids = identities
    monkeypatch.setenv("SHADOWFLOW_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(dm, "_views", {})
    for k in range(2):
        render = render_turned(basis, ids[0], (20.0, 0.0), LIGHT, default_model())
        cv2.imwrite(str(tmp_path / f"turned{k}.png"), render.photo[..., ::-1])
    proc = cli(["run", str(tmp_path / "turned0.png"), str(tmp_path / "turned1.png"), "--out", str(tmp_path / "out"),
                "--record", "none", "--light=" + ",".join(str(x) for x in LIGHT)])
    notes = [line for line in proc.stderr.splitlines() if "built the model of heads turned" in line]
    assert proc.returncode == 0 and len(notes) == len(list((tmp_path / "cache").glob("ict-yaw*.npz"))) >= 2
    quiet = cli(["run", str(tmp_path / "turned0.png"), "--out", str(tmp_path / "quiet"), "--record", "none", "--quiet"])
    assert quiet.stderr == ""
