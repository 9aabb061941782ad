import json

import cv2
import numpy as np
from shadowflow.nodes.geometry.reflectance import light_from_angles
import pytest
from shadowflow.nodes.photo.input_error import InputError
from shadowflow.nodes.photo.lights import parse_light, yaleb_light
from shadowflow.nodes.photo.loader import load_image, load_photo
from shadowflow.nodes.photo.sidecar import read_sidecar


@pytest.fixture
def gradient():
    return np.tile(np.linspace(0, 1, 48), (40, 1))


@pytest.mark.parametrize("ext", [".png", ".pgm", ".tif", ".jpg"])
def test_8_and_16_bit_grey(tmp_path, gradient, ext):
    for dtype, top in ((np.uint8, 255), (np.uint16, 65535)):
        if ext == ".jpg" and dtype == np.uint16:
            continue
        p = tmp_path / f"img{np.dtype(dtype).itemsize}{ext}"
        cv2.imwrite(str(p), np.round(gradient * top).astype(dtype))
        img = load_image(p)
        assert img.dtype == np.float32 and img.shape == (40, 48)
        np.testing.assert_allclose(img, gradient, atol=0.02 if ext == ".jpg" else 1.0 / top)


def test_colour_and_alpha_to_luminance(tmp_path, gradient):
    bgr = np.zeros((40, 48, 3), np.uint8)
    bgr[..., 1] = np.round(gradient * 255)  # pure green
    p = tmp_path / "c.png"
    cv2.imwrite(str(p), bgr)
    np.testing.assert_allclose(load_image(p), 0.587 * gradient, atol=0.01)
    bgra = np.dstack([bgr, np.full((40, 48), 7, np.uint8)])
    cv2.imwrite(str(tmp_path / "a.png"), bgra)
    np.testing.assert_allclose(load_image(tmp_path / "a.png"), 0.587 * gradient, atol=0.01)


def test_npy_input_and_its_errors(tmp_path, gradient):
    np.save(tmp_path / "ok.npy", gradient)
    np.testing.assert_allclose(load_image(tmp_path / "ok.npy"), gradient)
    bad = gradient.copy()
    bad[3, 3] = np.nan
    np.save(tmp_path / "nan.npy", bad)
    with pytest.raises(InputError, match="nan.npy.*NaN"):
        load_image(tmp_path / "nan.npy")
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(InputError, match="obj.npy"):
        load_image(tmp_path / "obj.npy")  # never unpickled


def test_unreadable_files_name_the_file(tmp_path):
    (tmp_path / "empty.png").write_bytes(b"")
    (tmp_path / "text.jpg").write_text("hello")
    for name in ("empty.png", "text.jpg", "missing.png"):
        with pytest.raises(InputError, match=name) as e:
            load_image(tmp_path / name)
        assert "\n" not in str(e.value)


def test_light_sources(tmp_path):
    np.testing.assert_allclose(parse_light("-1,0,1"), np.array([-1, 0, 1]) / np.sqrt(2))
    for bad, why in (("0,0,0", "zero"), ("1,0,-1", "away"), ("1,2,3,4", "three"), ("a,b,c", "three"),
                     ("nan,0,1", "finite"), ("200,0", "azimuth"), ("0,95", "elevation"), ("120,0", "away")):
        with pytest.raises(ValueError, match=why):
            parse_light(bad)
    # two numbers: azimuth and elevation in degrees, Yale B's convention (azimuth toward the image's left)
    np.testing.assert_allclose(parse_light("30,10"), light_from_angles(30, 10))
    assert parse_light("60,0")[0] < -0.8  # toward the image's left: x negative
    with pytest.raises(InputError, match="impossible"):
        yaleb_light("yaleB01_P00A+200E+00.pgm")
    with pytest.raises(InputError, match="no Yale B light"):
        yaleb_light("portrait.png")
    img = tmp_path / "face.png"
    img.write_bytes(b"")
    assert read_sidecar(img).light is None
    (tmp_path / "face.json").write_text(json.dumps({"light": [0, 1, 1], "eyes": [[10, 20], [30, 20]]}))
    side = read_sidecar(img)
    np.testing.assert_allclose(side.light, [0, 1 / np.sqrt(2), 1 / np.sqrt(2)])
    np.testing.assert_allclose(side.eyes, [[10, 20], [30, 20]])
    (tmp_path / "face.json").write_text("{not json")
    with pytest.raises(InputError, match="face.png: malformed sidecar face.json"):
        read_sidecar(img)


def _pnm(path, samples: np.ndarray, maxval: int, magic: bytes = b"P5") -> None:
    """Write a binary PGM/PPM by the format's rules: two bytes big-endian per sample over 255."""
    h, w = samples.shape[:2]
    body = samples.astype(">u2" if maxval > 255 else np.uint8).tobytes()
    path.write_bytes(magic + f"\n# made by the test\n{w} {h}\n{maxval}\n".encode() + body)


@pytest.mark.parametrize("maxval", [1023, 4095, 255, 65535])
def test_pgm_of_any_maxval_is_read_on_its_own_scale(tmp_path, maxval):
    """10- and 12-bit PGM were read with their bytes swapped (normals 32 deg off); every maxval now
    reads as sample / maxval."""
    rng = np.random.default_rng(maxval)
    samples = rng.integers(0, maxval + 1, (40, 50))
    path = tmp_path / "deep.pgm"
    _pnm(path, samples, maxval)
    np.testing.assert_allclose(load_image(path), samples / maxval, atol=1e-6)
    colour = rng.integers(0, maxval + 1, (40, 50, 3))
    ppm = tmp_path / "deep.ppm"
    _pnm(ppm, colour, maxval, b"P6")
    grey, rgb = load_photo(ppm)
    np.testing.assert_allclose(rgb, colour / maxval, atol=1e-6)
    np.testing.assert_allclose(grey, (colour / maxval) @ np.array([0.299, 0.587, 0.114]), atol=2e-3)


def test_an_image_whose_name_is_as_long_as_names_go_has_no_sidecar(tmp_path):
    """A 255-byte name: its sidecar's (``.json`` for ``.png``) would be 256 bytes, which no file
    system allows. The frame used to fail with ``File name too long``."""
    import cv2

    path = tmp_path / ("a" * 251 + ".png")
    cv2.imwrite(str(path), (np.arange(64 * 64).reshape(64, 64) % 251).astype(np.uint8))
    side = read_sidecar(path)
    assert side.light is None and side.eyes is None
