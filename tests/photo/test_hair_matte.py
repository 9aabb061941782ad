"""Hair in a photo (``nodes/photo/hair_matte.py``): MediaPipe's hair segmentation, shipped unchanged, shown the head
around a face's box; on scikit-image's public-domain ``astronaut`` (NASA), whose fringe and crown are hair and whose
face is not."""
import hashlib

import numpy as np
import pytest
from shadowflow.nodes.photo import hair_matte as HM

# the astronaut's face box (y0, y1, x0, x1): her crown and fringe at its top, her cheeks below her eyes (photo pixels)
ASTRONAUT_FACE = (50, 190, 170, 280)


@pytest.fixture(scope="module")
def astronaut() -> np.ndarray:
    data = pytest.importorskip("skimage.data")
    return np.ascontiguousarray(data.astronaut())


def test_the_shipped_hair_model_is_mediapipes_unchanged():
    digest = hashlib.sha256(HM.HAIR_FILE.read_bytes()).hexdigest()
    assert digest == "d2c940c4fd80edeaf38f5d7387d1b4235ee320ed120080df67c663e749e77633"
    assert "hair_segmentation.tflite" in (HM.DATA / "NOTICE").read_text()


def test_the_hair_matte_finds_the_astronauts_hair_not_her_face(astronaut):
    """Shown the head around her face's box, the matte is sure of the hair above her brow (over 0.9 on average,
    measured 0.99) and of her cheeks not being hair (under 0.05, measured 0.001); the box's own size comes back.
    Shown the whole photo as one box, her head is too small for it to see (under 0.2 on that hair): the head is
    what it must be shown."""
    pytest.importorskip("ai_edge_litert")
    share = HM.hair_in_box(astronaut / 255.0, ASTRONAUT_FACE)
    y0, y1, x0, x1 = ASTRONAUT_FACE
    assert share.shape == (y1 - y0, x1 - x0) and share.dtype == np.float32
    assert share[5:25, 20:90].mean() > 0.9, share[5:25, 20:90].mean()
    assert share[60:90, 30:80].mean() < 0.05, share[60:90, 30:80].mean()
    whole = HM.hair_in_box(astronaut / 255.0, (0, 512, 0, 512))
    assert whole[y0 + 5:y0 + 25, x0 + 20:x0 + 90].mean() < 0.2


def test_a_box_at_the_photos_edge_is_shown_black_beyond_it(astronaut):
    """The square around a box in the photo's corner reaches past the photo: what is past it is black, and the matte
    is the box's size."""
    pytest.importorskip("ai_edge_litert")
    share = HM.hair_in_box(astronaut / 255.0, (0, 100, 0, 90))
    assert share.shape == (100, 90) and np.all((share >= 0.0) & (share <= 1.0))


def test_without_litert_or_colour_there_is_no_matte(monkeypatch):
    """OpenCV's dnn gets the model wrong (its custom operators): without LiteRT the relighting gets no matte; nor for
    a grey photo, where the model takes a side light's deep shadows for hair (a Yale B cheek's cast shadow)."""
    from shadowflow.flow.frame import Frame
    from shadowflow.nodes.relight.nodes import hair_segmenter

    pytest.importorskip("ai_edge_litert")
    colour = Frame(0, "colour", data={"colour": np.zeros((64, 64, 3), np.float32)}, meta={"encoding": "srgb"})
    grey = Frame(0, "grey", data={"image": np.zeros((64, 64), np.float32)}, meta={"encoding": "linear"})
    assert hair_segmenter(colour) is not None
    assert hair_segmenter(grey) is None
    monkeypatch.setattr(HM, "available", lambda: False)
    assert hair_segmenter(colour) is None
