"""A photo's encoding (``nodes/photo/encoding.py``): colour photos are decoded from sRGB to linear
light before the fit and encoded back after, grey ones are taken as linear; what no face changes
comes back as the file had it."""
import cv2
import numpy as np
import pytest
from shadowflow.nodes.photo.encoding import decode_samples, linear_to_srgb, resolve, srgb_to_linear
from shadowflow.nodes.photo.loader import read_photo


def test_srgb_decodes_as_the_standard_says_and_every_8_and_16_bit_value_comes_back():
    # IEC 61966-2-1: 0.5 encoded is 0.214 linear; the linear segment below 0.04045
    assert srgb_to_linear(np.float32(0.5)) == pytest.approx(0.21404, abs=1e-5)
    assert srgb_to_linear(np.float32(0.02)) == pytest.approx(0.02 / 12.92)
    for levels, dtype in ((256, np.uint8), (65536, np.uint16)):
        v = np.arange(levels, dtype=dtype)
        back = np.round(linear_to_srgb(decode_samples(v, float(levels - 1))) * (levels - 1)).astype(np.int64)
        assert np.array_equal(back, v.astype(np.int64)), levels


def test_colour_is_srgb_and_grey_is_linear_unless_told(tmp_path):
    rgb = np.zeros((64, 64, 3), np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 200, np.arange(64)[None, :] * 2, 90
    cv2.imwrite(str(tmp_path / "c.png"), rgb[..., ::-1])
    cv2.imwrite(str(tmp_path / "g.png"), rgb[..., 1])
    colour = read_photo(tmp_path / "c.png", encoding="auto")
    assert colour.encoding == "srgb" and np.array_equal(colour.rgb8, rgb)
    assert colour.colour[0, 0, 0] == pytest.approx(srgb_to_linear(np.float32(200 / 255)), abs=1e-6)
    grey = read_photo(tmp_path / "g.png", encoding="auto")
    assert grey.encoding == "linear" and grey.grey[0, 10] == pytest.approx(20 / 255)
    told = read_photo(tmp_path / "g.png", encoding="srgb")
    assert told.encoding == "srgb" and told.grey[0, 10] == pytest.approx(srgb_to_linear(np.float32(20 / 255)))
    assert resolve("linear", 3) == "linear"
    with pytest.raises(ValueError, match="encoding"):
        resolve("gamma", 3)


def test_a_colour_portrait_comes_back_srgb_its_surroundings_as_they_were(tmp_path):
    """A rendered face tinted like skin, saved sRGB-encoded as a camera would in a coloured frame, eyes
    and light given: the relit photo is sRGB too, the frame's pixels the file's own, and the face
    relit in linear light: its lit side, relit by the same light, keeps the photo's values."""
    import json

    import shadowflow
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    light = light_from_angles(40)
    face_png = write_shadowed_face(tmp_path / "face.png", np.random.default_rng(9), light, source="ict")
    linear = cv2.imread(str(face_png), cv2.IMREAD_GRAYSCALE) / 255.0  # the render: linear light
    frame = np.dstack([np.full((180, 240), v) for v in (0.2, 0.35, 0.5)])
    on = linear > 0
    frame[20:148, 60:188][on] = linear[on][:, None] * np.array([1.0, 0.78, 0.62])
    photo = tmp_path / "portrait.png"
    cv2.imwrite(str(photo), (linear_to_srgb(frame)[..., ::-1] * 255 + 0.5).astype(np.uint8))
    side = json.loads(face_png.with_suffix(".json").read_text())
    photo.with_suffix(".json").write_text(json.dumps({"light": side["light"],
                                                      "eyes": (np.array(side["eyes"]) + [60, 20]).tolist()}))
    out = shadowflow.fit(str(photo), options=shadowflow.MethodOptions(relight_light=light))
    assert out.photo.meta["encoding"] == "srgb"
    given = cv2.imread(str(photo))[..., ::-1]
    relit8 = (out.relit * 255 + 0.5).astype(np.uint8)
    assert np.array_equal(relit8[:, :40], given[:, :40]) and np.array_equal(relit8[160:], given[160:])
    lit = out.mask & out.lit & (out.weights > 0.9)
    diff = np.abs(relit8[lit].astype(int) - given[lit].astype(int))
    assert np.median(diff) <= 1  # relit by its own light, the lit face is itself


def test_a_black_and_white_jpeg_is_srgb_as_a_camera_saved_it(tmp_path):
    grey = np.tile(np.linspace(40, 220, 64).astype(np.uint8), (64, 1))
    cv2.imwrite(str(tmp_path / "bw.jpg"), grey, [cv2.IMWRITE_JPEG_QUALITY, 100])
    cv2.imwrite(str(tmp_path / "bw.png"), grey)
    assert read_photo(tmp_path / "bw.jpg", encoding="auto").encoding == "srgb"
    assert read_photo(tmp_path / "bw.png", encoding="auto").encoding == "linear"
    assert read_photo(tmp_path / "bw.jpg", encoding="linear").encoding == "linear"


def test_an_8_bit_colour_photo_is_decoded_where_it_is_read_never_whole(tmp_path):
    """An 8-bit sRGB colour photo's linear RGB is a ``Decoded8``: any part of it indexed is the table's decoding of
    those values, bit for bit what the whole decoded at once gives, and so is its grey; reading a 4-megapixel
    photo never holds its 48 MB of linear floats (its file, its decoded samples, 12 MB, their 8-bit RGB, 12 MB,
    and its grey, 16 MB)."""
    import tracemalloc

    from shadowflow.nodes.photo.encoding import Decoded8, linear_luminance

    rng = np.random.default_rng(2)
    small = rng.integers(0, 256, (50, 40, 3), np.uint8)
    rgb = cv2.resize(small, (2000, 2000), interpolation=cv2.INTER_CUBIC)
    path = tmp_path / "big.png"
    cv2.imwrite(str(path), rgb[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 1])
    tracemalloc.start()
    photo = read_photo(path, encoding="auto")
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert isinstance(photo.colour, Decoded8) and photo.colour.shape == (2000, 2000, 3)
    assert peak < 70e6, peak / 1e6  # 53 MB; decoded whole (and its grey from it): 94 MB
    whole = decode_samples(photo.rgb8, 255.0)
    assert np.array_equal(np.asarray(photo.colour), whole)
    assert np.array_equal(photo.colour[300:420, 1500:1720], whole[300:420, 1500:1720])
    assert np.array_equal(photo.colour[..., ::-1][5:9], whole[..., ::-1][5:9])
    assert np.array_equal(photo.grey, linear_luminance(whole))


def test_a_colour_photo_over_the_working_size_is_reduced_once_in_its_own_colours(tmp_path):
    """A colour photo larger than ``max_pixels`` keeps its colours in order when reduced (R stays R), its grey is the
    reduced colours' decoded luminance, and its file's values are what the area average of its RGB gives; the
    same photo given in grey is reduced as its own samples."""
    from shadowflow.nodes.photo.encoding import decoded_luminance

    rng = np.random.default_rng(3)
    rgb = cv2.resize(rng.integers(0, 256, (30, 40, 3), np.uint8), (1600, 1200), interpolation=cv2.INTER_CUBIC)
    rgb[..., 0] = np.maximum(rgb[..., 0], 150)  # red over its other channels, so a swap would show
    cv2.imwrite(str(tmp_path / "big.png"), rgb[..., ::-1])
    photo = read_photo(tmp_path / "big.png", max_pixels=1_000_000, encoding="auto")
    expected = cv2.resize(rgb, (1154, 866), interpolation=cv2.INTER_AREA)
    assert photo.rgb8.shape == (866, 1154, 3) and photo.rgb8.flags.c_contiguous
    assert np.array_equal(photo.rgb8, expected)
    assert np.array_equal(photo.grey, decoded_luminance(expected))
    assert photo.scale == pytest.approx(1154 / 1600) and photo.size == (1600, 1200)
    grey = rgb[..., 1].copy()
    cv2.imwrite(str(tmp_path / "grey.png"), grey)
    told = read_photo(tmp_path / "grey.png", max_pixels=1_000_000, encoding="linear")
    assert told.colour is None and told.grey.shape == (866, 1154)
    assert np.allclose(told.grey * 255.0, cv2.resize(grey, (1154, 866), interpolation=cv2.INTER_AREA), atol=1e-3)
