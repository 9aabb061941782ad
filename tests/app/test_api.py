"""The Python API (``shadowflow.fit``, ``shadowflow.run``) and the README's example of it."""
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shadowflow
from shadowflow.nodes.evaluation.scenes import write_shadowed_face
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.method.robust_fit import FitConfig
from shadowflow.nodes.photo.input_error import InputError

README = Path(__file__).resolve().parents[2] / "README.md"


def _readme_python_example() -> str:
    text = README.read_text()
    section = text[text.index("\n## Python\n"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


@pytest.mark.slow
def test_the_readme_python_example_runs(tmp_path):
    """Run as a user would paste it, in a fresh interpreter, in an empty folder."""
    proc = subprocess.run([sys.executable, "-c", _readme_python_example()], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (tmp_path / "out" / "face" / "normals.npy").is_file()
    assert (tmp_path / "out" / "stream" / "summary.json").is_file()
    assert "converged True" in proc.stdout, proc.stdout


def test_fit_gives_what_shadowflow_run_writes(tmp_path, procedural_model):
    """The API and the command line run the same nodes: the saved files are byte-identical."""
    photo = write_shadowed_face(tmp_path / "face.png", np.random.default_rng(4), light_from_angles(50))
    result = shadowflow.fit(photo, model=procedural_model)
    result.save(tmp_path / "api")
    run = shadowflow.run([photo], tmp_path / "run", model=procedural_model, record=())
    assert [r["status"] for r in run.records] == ["ok"]
    for name in ("normals.npy", "depth.npy", "grid.json", "albedo.png", "shadow.png", "relit.png", "mesh.ply"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "run" / "face" / name).read_bytes(), name
    assert result.iterations == run.records[0]["iterations"] == len(result.history)
    assert result.history[-1]["change_deg"] < FitConfig().stop_tolerance_deg and result.converged
    # the products on the photo's grid: unit normals on the face, NaN off it, shadows where lit is not
    face = result.mask
    assert face.mean() > 0.2 and np.allclose(np.linalg.norm(result.normals[face], axis=1), 1, atol=1e-4)
    assert np.isnan(result.depth[~face]).all() and not result.shadow[~face].any()
    assert len(result.mesh["triangles"]) > 1000


def test_fit_takes_an_array_as_the_file_loader_reads_it(tmp_path, procedural_model):
    """An RGB uint8 array is the file's luminance: same light and eyes, same normals."""
    import cv2

    photo = write_shadowed_face(tmp_path / "face.png", np.random.default_rng(5), light_from_angles(-40))
    from_file = shadowflow.fit(photo, model=procedural_model)
    grey = cv2.imread(str(photo), cv2.IMREAD_GRAYSCALE)
    rgb = np.dstack([grey, grey, grey])
    eyes = np.array([[46.0, 48.0], [82.0, 48.0]])  # the sidecar's: where the generator put them
    from_array = shadowflow.fit(rgb, light=from_file.light, eyes=eyes, model=procedural_model)
    np.testing.assert_allclose(from_array.normals, from_file.normals, atol=1e-5)
    assert from_array.relit.shape == rgb.shape  # colour in, colour out
    with pytest.raises(InputError, match="shape"):
        shadowflow.fit(np.zeros((4, 4, 4, 4)), model=procedural_model)
    with pytest.raises(InputError, match="no contrast"):
        shadowflow.fit(np.full((200, 200), 0.5), model=procedural_model)


def test_a_colour_photo_comes_back_a_colour_photo_of_its_size_with_the_face_relit(tmp_path, procedural_model):
    """A face lit from the left, skin-coloured, in a larger frame with a coloured background: the
    relit photo is that frame, in colour, the face lit from the front, the background untouched
    but for the one exposure gain."""
    import json

    import cv2
    from scipy import ndimage

    face_png = write_shadowed_face(tmp_path / "face.png", np.random.default_rng(8), light_from_angles(50))
    grey = cv2.imread(str(face_png), cv2.IMREAD_GRAYSCALE) / 255.0
    h, w = 260, 300
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    frame = np.dstack([0.2 + 0.3 * xx, 0.5 - 0.2 * yy, 0.3 + 0.1 * xx * yy])  # RGB background
    top, left = 60, 90
    region = frame[top:top + 128, left:left + 128]
    # the face's pixels, its black cast shadow among them (not holes showing the background through the face)
    on_face = ndimage.binary_fill_holes(grey > 0)
    region[on_face] = grey[on_face][:, None] * np.array([1.0, 0.78, 0.62])  # skin
    photo = tmp_path / "portrait.png"
    cv2.imwrite(str(photo), (np.clip(frame, 0, 1)[..., ::-1] * 255 + 0.5).astype(np.uint8))
    side = json.loads(face_png.with_suffix(".json").read_text())
    eyes = (np.array(side["eyes"]) + [left, top]).tolist()
    photo.with_suffix(".json").write_text(json.dumps({"light": side["light"], "eyes": eyes}))

    result = shadowflow.fit(photo, model=procedural_model)
    relit = result.relit
    assert relit.shape == (h, w, 3) and result.albedo.shape == (h, w, 3)
    face = result.mask
    rgb = relit[face].mean(axis=0)
    assert rgb[0] > rgb[1] > rgb[2]  # still skin-coloured
    turned = result.novel_view  # the face turned is in colour too
    assert turned.ndim == 3 and turned.shape[2] == 3
    tone = turned[turned.max(axis=-1) > 0.05].mean(axis=0)
    assert tone[0] > tone[1] > tone[2]
    # the background, far from the face, is the photo times one gain
    from scipy import ndimage

    far = ndimage.distance_transform_edt(~face) > 40
    original = cv2.imread(str(photo))[..., ::-1] / 255.0
    ratio = relit[far] / np.maximum(original[far], 1e-3)
    assert far.sum() > 10000 and np.std(ratio) < 0.01 * np.mean(ratio)
    # lit from the front: the face's two halves come out about as bright; in the photo the far one is dark
    cols = np.nonzero(face.any(axis=0))[0]
    mid = (cols.min() + cols.max()) // 2
    left_half, right_half = face.copy(), face.copy()
    left_half[:, mid:] = False
    right_half[:, :mid] = False
    lum = relit.mean(axis=-1)
    before = original.mean(axis=-1)
    assert before[right_half].mean() < 0.6 * before[left_half].mean()
    assert 0.8 < lum[right_half].mean() / lum[left_half].mean() < 1.25
    result.save(tmp_path / "out")
    saved = cv2.imread(str(tmp_path / "out" / "relit.png"), cv2.IMREAD_UNCHANGED)
    assert saved.shape == (h, w, 3)
    # the sRGB photo is relit in linear light as a linear one is, the face's inner feather included, and
    # its 8-bit file is that rounded: the file's own values beyond the face's box
    from shadowflow.nodes.relight.compose import compose
    from shadowflow.nodes.relight.products import relit_photo, relit_photo_8bit
    from shadowflow.nodes.photo.encoding import linear_to_srgb

    whole = result.photo
    layers = [f.data["photo_layers"][0][1] for f in whole.parts]
    linear = linear_to_srgb(compose(whole.data["colour"], layers))
    assert np.abs(relit_photo(whole, 0) - linear).max() < 1e-5
    assert layers[0].alpha is not None and (layers[0].alpha[layers[0].inside] < 1).sum() > 100
    eight = relit_photo_8bit(whole, 0)
    assert np.array_equal(eight, (linear * 255 + 0.5).astype(np.uint8))
    assert np.array_equal(saved[..., ::-1], eight)


@pytest.mark.slow
def test_fit_of_a_colour_array_is_fit_of_the_file_holding_it(tmp_path):
    """The astronaut (scikit-image, public domain) as a uint8 array and as the PNG of it: the same
    numbers out, bit for bit (they differed by up to 0.59 on 0.5 % of the relit pixels)."""
    import cv2

    data = pytest.importorskip("skimage.data")
    rgb = np.ascontiguousarray(data.astronaut())
    cv2.imwrite(str(tmp_path / "a.png"), rgb[..., ::-1])
    from_file, from_array = shadowflow.fit(tmp_path / "a.png"), shadowflow.fit(rgb)
    assert np.array_equal(from_file.relit, from_array.relit)
    assert np.array_equal(from_file.normals, from_array.normals, equal_nan=True)
    assert from_file.faces == from_array.faces


def test_run_given_one_path_runs_that_file_and_quiet_says_nothing(tmp_path, procedural_model, monkeypatch, capfd):
    """``shadowflow.run("face.png", out)`` iterated the string's characters: ``.`` expanded to the working folder
    and every photo in it was run, and ``quiet=True`` (the default) still printed an ``error:`` line for each of
    ``f``, ``a``, ``c``... Now one path (a string or a ``Path``) is one input, and quiet prints nothing."""
    monkeypatch.chdir(tmp_path)
    write_shadowed_face("face.png", np.random.default_rng(4), light_from_angles(30))
    write_shadowed_face("other.png", np.random.default_rng(5), light_from_angles(30))
    for given in ("face.png", Path("face.png")):
        result = shadowflow.run(given, tmp_path / "out", model=procedural_model, record=())
        assert [(r["source"], r["status"]) for r in result.records] == [("face.png", "ok")]
    (tmp_path / "bad.png").write_bytes(b"not an image")
    result = shadowflow.run(["bad.png", "face.png"], tmp_path / "out2", model=procedural_model, record=())
    assert result.not_ok == 1 and "not a recognised image" in result.records[0]["status"]
    assert capfd.readouterr() == ("", "")
    shadowflow.run(["bad.png"], tmp_path / "out3", model=procedural_model, record=(), quiet=False)
    assert "error: bad.png: not a recognised image" in capfd.readouterr().err
