"""The needle-map shape model (nodes/model/shape_model.py): its modes and variance, files without pickles, damaged
files and cache entries refused or rebuilt."""
import numpy as np
import pytest
from shadowflow.nodes.geometry.normals import angle_deg
from shadowflow.nodes.model.shape_model import load_model, save_model
from shadowflow.nodes.model.sources import procedural


def test_model_normal_variance_is_the_modes_spread_per_pixel(procedural_model):
    m = procedural_model
    var = m.normal_variance
    assert var.shape == (m.n_pixels,) and np.all(var >= 0)
    # the variance of each pixel's AEP coordinates over samples b ~ N(0, eigenvalues)
    rng = np.random.default_rng(2)
    b = rng.standard_normal((4000, m.n_modes)) * np.sqrt(m.eigenvalues)
    v = (b @ m.modes.T.astype(np.float64)).reshape(4000, m.n_pixels, 2)
    sampled = v.var(axis=0).sum(axis=1)
    np.testing.assert_allclose(var, sampled, rtol=0.1, atol=1e-6)


def test_model_save_load_round_trip_without_pickles(tmp_path, procedural_model):
    path = save_model(procedural_model, tmp_path / "m.npz")
    with np.load(path, allow_pickle=False) as z:  # must not need pickles
        assert list(z["grid"]) == [128, 128] and z["eyes"].shape == (2, 2)
    back = load_model(path)
    assert back.grid == procedural_model.grid and back.n_modes == 60
    np.testing.assert_array_equal(back.modes, procedural_model.modes)
    np.testing.assert_array_equal(back.mask, procedural_model.mask)


def test_load_model_rejects_bad_files(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="bad.npz"):
        load_model(bad)
    np.savez(tmp_path / "partial.npz", grid=np.array([4, 4]))
    with pytest.raises(ValueError, match="lacks"):
        load_model(tmp_path / "partial.npz")
    obj = tmp_path / "obj.npz"
    np.savez(obj, grid=np.array([1, 2], dtype=object), eyes=np.zeros((2, 2)))
    with pytest.raises(ValueError):
        load_model(obj)  # object arrays would need pickles: refused


def test_model_modes_are_orthonormal_and_reconstruct_training_faces(procedural_model):
    m = procedural_model
    np.testing.assert_allclose(m.modes.T @ m.modes, np.eye(m.n_modes), atol=1e-4)
    assert np.all(np.diff(m.eigenvalues) <= 1e-6)
    depths, _ = procedural(3, seed=0)  # the first training faces
    from shadowflow.nodes.geometry.normals import normals_from_depth

    for d in depths:
        n = normals_from_depth(d)[m.mask].astype(np.float64)
        b = m.modes.T.astype(np.float64) @ (m.project(n) - m.mean_proj).reshape(-1)
        assert np.mean(angle_deg(m.synthesize(b), n)) < 0.3


def test_closest_coefficients_recover_a_needle_map_from_the_pixels_that_are_known(procedural_model):
    """The model floor of ``eval yaleb``: a needle-map in the model's span is recovered exactly
    from part of its pixels (the rest hold garbage); an unseen face lands far
    closer than the mean face, and the model's own mean (b = 0) gives zero coefficients."""
    m = procedural_model
    rng = np.random.default_rng(3)
    b = rng.standard_normal(m.n_modes) * np.sqrt(m.eigenvalues)
    n = m.synthesize(b)
    known = rng.random(m.n_pixels) < 0.6
    garbage = np.where(known[:, None], n, -n)
    np.testing.assert_allclose(m.closest_coefficients(garbage, known), b, atol=1e-3 * np.abs(b).max())
    np.testing.assert_allclose(m.closest_coefficients(m.synthesize(np.zeros(m.n_modes))), 0.0, atol=1e-4)
    from shadowflow.nodes.geometry.normals import normals_from_depth

    depths, _ = procedural(1, seed=999)  # a face the model was not trained on
    unseen = normals_from_depth(depths[0])[m.mask].astype(np.float64)
    closest = m.synthesize(m.closest_coefficients(unseen))
    error, mean_error = np.mean(angle_deg(closest, unseen)), np.mean(angle_deg(m.mean_normals, unseen))
    assert 0.05 < error < 0.5 * mean_error, (error, mean_error)
    assert not m.closest_coefficients(n, np.zeros(m.n_pixels, bool)).any()


def _model_arrays(model, folder) -> dict:
    with np.load(save_model(model, folder / "model.npz"), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


@pytest.mark.parametrize("change, says", [
    (lambda a: a["mean_normals"].__setitem__((3, 1), np.nan), "NaN"),
    (lambda a: a["eigenvalues"].__setitem__(0, np.inf), "NaN or infinite"),
    (lambda a: a.__setitem__("eyes", np.zeros((3, 2))), "'eyes'"),
    (lambda a: a.__setitem__("grid", np.array([64, 65])), "'grid'"),
    (lambda a: a.__setitem__("mean_proj", a["mean_proj"][:-1]), "'mean_proj'"),
    (lambda a: a.__setitem__("eigenvalues", a["eigenvalues"][:-1]), "'eigenvalues'"),
    (lambda a: a.__setitem__("version", np.array([1, 2])), "'version'"),
])
def test_a_damaged_model_is_refused_at_load_naming_what_is_wrong(tmp_path, procedural_model, change, says):
    """A NaN used to give 'ok' frames with all-NaN normals; wrong shapes, tracebacks mid-fit."""
    arrays = _model_arrays(procedural_model.truncated(6), tmp_path)
    change(arrays)
    path = tmp_path / "damaged.npz"
    np.savez(path, **arrays)
    with pytest.raises(ValueError, match=says):
        load_model(path)


def test_a_corrupt_or_odd_cache_entry_is_rebuilt_and_a_zip_bomb_refused(tmp_path, monkeypatch, procedural_model):
    """A truncated or bit-flipped cache entry, or a FIFO in its place, used to fail (or hang) every run
    until deleted by hand: now it is rebuilt. A model whose members unpack past the limit is refused
    before anything is read."""
    import os

    import shadowflow.nodes.model.default_model as dm
    from shadowflow.nodes.model import shape_model

    monkeypatch.setenv("SHADOWFLOW_CACHE", str(tmp_path))
    monkeypatch.setitem(dm.RECIPES, "tiny", {"source": "procedural", "n": 12, "seed": 0, "modes": 4, "size": [32, 32]})
    good = dm.built_in_model("tiny")
    entry = next(tmp_path.glob("tiny-*.npz"))
    blob = entry.read_bytes()
    for damaged in (blob[: len(blob) // 2], blob[:200] + bytes([blob[200] ^ 0x10]) + blob[201:]):
        entry.write_bytes(damaged)
        with pytest.raises(ValueError, match="not a readable model file"):
            load_model(entry)
        rebuilt = dm.built_in_model("tiny")
        np.testing.assert_array_equal(rebuilt.modes, good.modes)
        assert entry.read_bytes() == blob
    entry.unlink()
    os.mkfifo(entry)
    with pytest.raises(ValueError, match="not a regular file"):
        load_model(entry)
    np.testing.assert_array_equal(dm.built_in_model("tiny").modes, good.modes)
    assert entry.is_file()
    monkeypatch.setattr(shape_model, "MAX_MODEL_BYTES", 1000)
    with pytest.raises(ValueError, match="over the 1000-byte limit"):
        load_model(save_model(procedural_model, tmp_path / "big.npz"))


def test_a_model_grid_past_the_side_limit_is_refused_before_its_arrays_are_used(tmp_path, procedural_model):
    """Issue 39 #15: a 1 MB model file of a 5000 x 5000 grid (a few face pixels, the rest masked off) took
    over 6.5 GB and 92 s to fit; its size on disk is far under the 1 GiB limit on members."""
    arrays = _model_arrays(procedural_model.truncated(6), tmp_path)
    mask = np.zeros((5000, 5000), bool)
    mask[:128, :128] = arrays["mask"]
    arrays.update(mask=mask, grid=np.array([5000, 5000]))
    path = tmp_path / "huge-grid.npz"
    np.savez_compressed(path, **arrays)
    assert path.stat().st_size < 2_000_000
    with pytest.raises(ValueError, match=r"'grid' 5000 x 5000 is over the 512-pixel limit of a side"):
        load_model(path)


@pytest.mark.parametrize("eyes, says", [
    ([[82.0, 48.0], [46.0, 48.0]], "image-left first"),  # swapped
    ([[64.0, 30.0], [64.0, 70.0]], "image-left first"),  # one above the other
    ([[46.0, 40.0], [82.0, 60.0]], "not on one row"),
    ([[46.0, 48.0], [182.0, 48.0]], "outside the 128 x 128 grid"),
    ([[46.0, 98.0], [82.0, 98.0]], "is not below the eyes"),  # under the mouth
])
def test_a_model_whose_eyes_are_not_an_upright_faces_is_refused(tmp_path, procedural_model, eyes, says):
    """A model file whose eyes were swapped (image-right first) loaded, placed every face mirrored and upside
    down, and fitted it ``ok`` without a flag; eyes one above the other, off the grid or under the mouth were
    taken too. The model's own face must be an upright one."""
    from shadowflow.nodes.app.cli import main

    arrays = _model_arrays(procedural_model.truncated(6), tmp_path)
    arrays["eyes"] = np.array(eyes)
    arrays["mouth"] = np.array([64.0, 87.0])
    path = tmp_path / "odd.npz"
    np.savez(path, **arrays)
    with pytest.raises(ValueError, match=f"odd.npz: .*{says}"):
        load_model(path)
    assert main(["run", "--demo", "--out", str(tmp_path / "out"), "--model", str(path)]) == 2
    assert not (tmp_path / "out").exists()
