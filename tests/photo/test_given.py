"""What comes with a photo (``photo.given``) and a placed face as the fit sees it (``placement.face_on_grid``):
pure functions, tested without a node."""
from types import SimpleNamespace

import numpy as np
import pytest
from shadowflow.nodes.photo.align import Alignment
from shadowflow.nodes.photo.given import given_eyes, known_light
from shadowflow.nodes.photo.input_error import InputError
from shadowflow.nodes.photo.placement import FacePlacement, face_on_grid
from shadowflow.nodes.photo.sidecar import Sidecar

EYES = np.array([[100.0, 120.0], [160.0, 121.0]])


def test_a_sidecars_eyes_win_and_follow_a_photo_read_reduced():
    side = Sidecar(eyes=EYES)
    eyes, how = given_eyes("a.jpg", (400, 300), side, EYES + 50, scale=0.5)
    assert how == "sidecar eyes" and np.allclose(eyes, EYES * 0.5)
    eyes, how = given_eyes("a.jpg", (400, 300), Sidecar(), EYES + 50, scale=1.0)
    assert how == "given eyes" and np.allclose(eyes, EYES + 50)
    assert given_eyes("a.jpg", (400, 300), None, None, scale=1.0) is None


@pytest.mark.parametrize("eyes, says", [
    (np.array([[1.0, 2.0], [np.nan, 3.0]]), "four finite numbers"),
    (np.array([[50.0, 50.0], [50.5, 50.0]]), "one on the other"),
    (np.array([[50.0, 50.0], [5000.0, 50.0]]), "far outside the 300x400 photo"),
])
def test_eyes_that_cannot_place_a_face_are_refused_naming_the_file(eyes, says):
    with pytest.raises(InputError, match=f"^b.png: given eyes .*{says}"):
        given_eyes("b.png", (400, 300), None, eyes, scale=1.0)


def test_the_light_known_before_the_faces_sidecar_then_given_then_the_yale_b_name():
    side = Sidecar(light=np.array([0.0, 0.6, 0.8]))
    vector = np.array([0.6, 0.0, 0.8])
    assert known_light("x.png", side, vector)[1] == "sidecar"
    light, how = known_light("x.png", Sidecar(), vector)
    assert how == "given" and light is vector
    light, how = known_light("yaleB01_P00A+035E+15.pgm", None, "yaleb")
    assert how == "yaleb name"
    assert np.allclose(light, [-np.sin(np.radians(35)) * np.cos(np.radians(15)), np.sin(np.radians(15)),
                               np.cos(np.radians(35)) * np.cos(np.radians(15))])
    assert known_light("x.png", None, "auto") is None


def test_a_face_on_the_grid_shows_only_what_the_photo_holds_inside_its_outline():
    model = SimpleNamespace(grid=(40, 40))
    # model pixel -> photo pixel: twice as large, the grid's left 10 columns off the photo's left edge
    al = Alignment(np.array([[2.0, 0.0, -20.0], [0.0, 2.0, 0.0]]), "test")
    image = np.tile(np.linspace(0, 1, 100, dtype=np.float32), (100, 1))
    oval = np.array([[20.0, 20.0], [70.0, 20.0], [70.0, 70.0], [20.0, 70.0]])  # photo pixels
    placement = FacePlacement(al, "detected", EYES, np.zeros(4), outlines={"oval": [oval]})
    grid, seen = face_on_grid(image, placement, model)
    assert grid.shape == seen.shape == (40, 40)
    # column c of the grid is photo column 2c - 20: the photo's brightness there
    assert np.isclose(grid[20, 30], image[40, 40], atol=0.02)
    assert not seen[:, :10].any()  # off the photo
    rows, cols = np.nonzero(seen)  # inside the oval: photo 20..70 is grid rows 10..35, columns 20..45
    assert rows.min() >= 9 and rows.max() <= 36 and cols.min() >= 19 and cols.max() <= 40
    assert seen[20, 30]
    _, no_outline = face_on_grid(image, FacePlacement(al, "given", EYES, np.zeros(4)), model)
    assert no_outline[:, 10:].all() and not no_outline[:, :10].any()


def test_a_small_faces_doubt_never_reads_as_enough():
    """Eyes just short of what the fit wants are said to be short of it: rounded both ways, 15.6 px against
    16.0 read "16 px apart; the fit wants 16" (seen on a composite group photo)."""
    import re

    from shadowflow.nodes.photo.placement import MIN_FIT_IOD_SHARE, small_face

    model = SimpleNamespace(eyes=np.array([[40.0, 50.0], [80.0, 50.0]]))  # 40 px apart on the grid
    least = MIN_FIT_IOD_SHARE * 40.0
    for iod in (least - 0.4, least - 0.01, least * 0.5):
        (doubt,) = small_face(iod, model)
        apart, wants = (int(n) for n in re.search(r"eyes (\d+) px apart; the fit wants at least (\d+)", doubt).groups())
        assert apart < wants, doubt
    assert small_face(least, model) == []
