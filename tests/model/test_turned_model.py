"""Models of turned heads: the ICT faces turned about the neck, their mirror map, views and the cache."""
from __future__ import annotations

import numpy as np
import pytest
from shadowflow.nodes.model import default_model as dm
from shadowflow.nodes.model.faces.ict import STOMION, mirror_pixels, placed, shipped_basis
from shadowflow.nodes.model.faces.placement import turn_to_view, view_rotation
from shadowflow.nodes.model.shape_model import load_model, save_model


def test_view_rotation_turns_the_nose_toward_the_image_right_for_positive_yaw_and_up_for_positive_pitch():
    nose = np.array([0.0, 0.0, 1.0])
    assert view_rotation(30, 0) @ nose == pytest.approx([0.5, 0.0, np.cos(np.radians(30))])
    assert view_rotation(0, 10) @ nose == pytest.approx([0.0, np.sin(np.radians(10)), np.cos(np.radians(10))])


def test_a_turned_face_keeps_its_eye_midpoint_and_foreshortens_its_eye_distance():
    basis = shipped_basis()
    verts, eyes = basis.face(np.zeros(basis.n_identity))
    grid = (128, 128)
    frontal_eyes = placed(eyes, eyes, grid)
    for yaw in (-30.0, 20.0):
        e = placed(eyes, eyes, grid, (yaw, 0.0))
        np.testing.assert_allclose(e[:, :2].mean(axis=0), frontal_eyes[:, :2].mean(axis=0), atol=1e-9)
        iod = np.linalg.norm(e[1, :2] - e[0, :2])
        assert iod == pytest.approx(36.0 * np.cos(np.radians(yaw)), rel=0.02)  # the irises lie nearly level in z
        mouth = placed(verts[list(STOMION)], eyes, grid, (yaw, 0.0))[:, 0].mean()
        assert np.sign(mouth - 64.0) == np.sign(yaw)  # the mouth, in front of the neck, swings with the turn
    assert np.array_equal(placed(verts, eyes, grid, (0.0, 0.0)), placed(verts, eyes, grid))
    p = np.random.default_rng(0).random((5, 3))
    assert turn_to_view(p, p[:2], (0.0, 0.0)) is not None and np.array_equal(turn_to_view(p, p[:2], (0.0, 0.0)), p)


def test_the_mirror_map_of_a_turned_face_is_its_own_inverse_where_both_sides_are_seen():
    basis = shipped_basis()
    model = dm.default_model()
    mask = model.mask
    for view in ((0.0, 0.0), (20.0, 0.0)):
        mirror = mirror_pixels(basis, mask, view)
        has = np.flatnonzero(mirror >= 0)
        assert len(has) > 0.3 * mask.sum()
        back = mirror[mirror[has]]
        rows, cols = np.divmod(np.flatnonzero(mask), mask.shape[1])
        ok = back >= 0
        dist = np.hypot(rows[back[ok]] - rows[has[ok]], cols[back[ok]] - cols[has[ok]])
        assert np.mean(dist <= 1.5) > 0.9
    frontal = mirror_pixels(basis, mask, (0.0, 0.0))  # frontal: about the eyes' midpoint column, to a pixel
    has = np.flatnonzero(frontal >= 0)
    assert np.mean(np.abs(cols[frontal[has]] - (2 * 64.0 - cols[has])) <= 1.0) > 0.95


def test_views_are_the_nearest_step_and_its_neighbours_in_yaw_within_the_reach():
    assert dm.view_of(12.4, 9.6) == (10.0, 0.0)
    assert dm.view_of(-33.0, -12.0) == (-35.0, -10.0)
    assert dm.view_of(80.0, 30.0) == (50.0, 30.0)  # fitted out to 50 deg
    assert dm.view_of(0.0, 27.0) == (0.0, 20.0)  # a render tilted 20 deg reads 20-27
    assert dm.view_of(0.0, -48.0) == (0.0, -30.0)  # the pitched views' reach
    assert dm.views_near(0.0, -24.0) == [(0.0, -20.0), (-5.0, -20.0), (5.0, -20.0)]
    assert dm.views_near(12.4, 0.0) == [(10.0, 0.0), (5.0, 0.0), (15.0, 0.0)]
    assert dm.views_near(34.0, 0.0) == [(35.0, 0.0), (30.0, 0.0), (40.0, 0.0)]
    assert dm.views_near(-58.0, 0.0) == [(-60.0, 0.0), (-55.0, 0.0)]  # measured out to 60


def test_a_turned_model_is_built_once_cached_and_read_back_with_its_view(tmp_path, monkeypatch):
    monkeypatch.setenv("SHADOWFLOW_CACHE", str(tmp_path))
    monkeypatch.setattr(dm, "_views", {})
    frontal = dm.default_model()
    told = []
    turned = dm.turned_model(frontal, (20.0, 0.0), note=told.append)
    assert len(told) == 1 and told[0].parent == tmp_path and told[0].exists()
    assert dm.turned_model(frontal, (20.0, 0.0), note=told.append) is turned and len(told) == 1
    assert dm.turned_model(frontal, (0.0, 0.0)) is frontal
    assert turned.view == (20.0, 0.0) and turned.mirror is not None and turned.mirror.shape == (turned.n_pixels,)
    assert np.linalg.norm(turned.eyes[1] - turned.eyes[0]) == pytest.approx(36.0 * np.cos(np.radians(20)), rel=0.02)
    assert turned.fingerprint != frontal.fingerprint
    # the chin's normal, below the mouth, turns with the head: toward the image's right by about the yaw
    def chin_turn(m):
        c, r = np.rint(m.mouth).astype(int) + [0, 12]
        n = m.to_image(m.mean_normals)[r - 2:r + 3, c - 2:c + 3].reshape(-1, 3).mean(axis=0)
        return np.degrees(np.arctan2(n[0], n[2]))
    assert chin_turn(turned) - chin_turn(frontal) == pytest.approx(20.0, abs=5.0)
    again = load_model(save_model(turned, tmp_path / "again.npz"))
    assert again.view == turned.view and np.array_equal(again.mirror, turned.mirror)
    assert again.fingerprint == turned.fingerprint
    assert dm.turned_model(again, (10.0, 0.0)) is None  # a model already turned has no further views


def test_a_model_file_with_a_broken_mirror_map_is_refused(tmp_path):
    model = dm.default_model()
    bad = dm.ShapeModel(model.grid, model.eyes, model.mask, model.mean_normals, model.mean_proj, model.modes[:, :2],
                        model.eigenvalues[:2], "x", model.mouth, (10.0, 0.0), np.full(model.n_pixels, model.n_pixels))
    path = save_model(bad, tmp_path / "bad.npz")
    with pytest.raises(ValueError, match="mirror"):
        load_model(path)


def test_the_yaw_that_explains_a_face_best_is_the_vertex_of_its_views_misfits():
    """The views' misfits (``method.turned.misfits``) are read between the views: the parabola through the least and
    its neighbours; at the end of the views tried, the next view out is tried while within the measured reach."""
    from shadowflow.nodes.method.turned import _further, least_misfit_yaw

    curve = {y: 0.01 * (y - 32.0) ** 2 + 1.0 for y in (20.0, 25.0, 30.0, 35.0, 40.0)}
    assert least_misfit_yaw(curve) == pytest.approx(32.0)
    assert _further(curve) is None  # the least is inside
    assert least_misfit_yaw({45.0: 2.0, 50.0: 1.5, 55.0: 1.0}) == 55.0 and _further({45.0: 2.0, 50.0: 1.0}) == 55.0
    assert _further({-55.0: 1.0, -50.0: 2.0}) == -60.0 and _further({-60.0: 1.0, -55.0: 2.0}) is None
