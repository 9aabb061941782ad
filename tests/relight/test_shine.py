"""The photo's shine (``relight/shine.py``): what of it a new light keeps, where its highlight moves, and how
much of a skin pixel is shine rather than the skin's colour."""
import numpy as np
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.relight.shine import SHEEN_MARGIN, sheen, shine_kept, shine_lobe


def test_the_photos_own_light_keeps_all_its_shine_a_darker_one_its_share():
    """``S' / S`` within [0, 1] and at most the lobe: the same lighting keeps all of it, half the light half,
    a brighter light no more than all (no shine is made), darkness none, and a moved highlight (lobe 0.2) no
    more than 0.2."""
    lighting = np.array([0.2, 0.5, 0.9, 0.6, 0.6], np.float32)
    np.testing.assert_array_equal(shine_kept(lighting, lighting), 1.0)
    new = np.array([0.1, 0.25, 1.0, 0.0, 0.6], np.float32)
    lobe = np.array([1.0, 1.0, 1.0, 1.0, 0.2], np.float32)
    np.testing.assert_allclose(shine_kept(lighting, new, lobe), [0.5, 0.5, 1.0, 0.0, 0.2], rtol=1e-6)


def test_a_highlight_moves_with_the_half_vector_as_blinn_phong_says():
    """Under its own light every pixel keeps its shine; a highlight's peak (its normal the half vector of a
    frontal light and the view: +z) keeps ``cos(30 deg)^14`` = 13 % of it under a light moved 60 degrees
    (the half vector moves 30), and a normal that turns toward the new half vector keeps all of it."""
    frontal, side = light_from_angles(0.0), light_from_angles(60.0)
    half_new = (side + [0.0, 0.0, 1.0]) / np.linalg.norm(side + [0.0, 0.0, 1.0])
    tilt = np.radians(10.0)  # a normal 10 degrees toward the new light
    normals = np.array([[[0.0, 0.0, 1.0], [-np.sin(tilt), 0.0, np.cos(tilt)], half_new]], np.float32)
    np.testing.assert_allclose(shine_lobe(normals, frontal, frontal), 1.0, rtol=1e-6)
    lobe = shine_lobe(normals, frontal, side)[0]
    np.testing.assert_allclose(lobe[0], np.cos(np.radians(30.0)) ** 14, rtol=1e-4)
    assert lobe[1] > lobe[0]
    assert lobe[2] == 1.0


def test_sheen_is_what_skin_shows_over_a_tenth_above_its_local_level():
    """An even skin albedo (0.5) with a highlight at 0.75 on it: the shine is the highlight over 1.1x the skin's
    level, 0.75 - 0.55 = 0.2 (a highlight does not raise the level it is measured on); the even skin has none,
    and a bright pixel off the skin (an eye's white) is not shine."""
    albedo = np.full((40, 40, 3), 0.5, np.float32)
    yy, xx = np.mgrid[0:40, 0:40]
    spot = np.hypot(yy - 20, xx - 20) <= 2
    white = np.hypot(yy - 8, xx - 30) <= 2
    albedo[spot] = 0.75
    albedo[white] = 0.9
    skin = ~white
    excess = sheen(albedo, skin, np.ones((40, 40), bool), 6.0)
    np.testing.assert_allclose(excess[spot], 0.75 - SHEEN_MARGIN * 0.5, atol=0.01)
    assert np.all(excess[skin & ~spot & (np.hypot(yy - 20, xx - 20) > 3)] == 0.0)
    assert np.all(excess[white] == 0.0)
