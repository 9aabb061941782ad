"""The colour of the light a relighting adds (``relight/light_colour.py``), on synthetic skin."""
import numpy as np
from shadowflow.nodes.relight.light_colour import light_tint, tinted

SKIN = np.array([0.6, 0.42, 0.33], np.float32)


ROOM = np.array([0.8, 0.95, 1.25], np.float32)


def _half_in_shade(room=ROOM, shade=0.3, size=(80, 120)):
    """(h, w, 3) skin lit by the room's light of colour ``room`` (``shade`` of a white lamp's level) and on its left
    half by the lamp too; the lighting (h, w) each half shows; the skin (h, w) bool; the right half (h, w) bool."""
    h, w = size
    right = np.zeros(size, bool)
    right[:, w // 2:] = True
    light = (shade * np.asarray(room, np.float32) + np.where(right, 0.0, 1.0)[..., None]).astype(np.float32)
    return SKIN * light, light.mean(axis=-1), np.ones(size, bool), right


def test_shade_lit_by_the_room_lifted_to_the_lamps_level_takes_the_lit_skins_colour():
    """Skin lit by a white lamp on its left half and by a blue room everywhere: its tint is 1 on the lit half and the
    lit skin's colour over the shade's on the shaded half (within 2 %, away from the border, across which the colour
    is averaged); the shade lifted to the lit half's level by ``tinted`` is the lit skin (within 7 %: the light added
    is the lit skin's, a quarter of which is the room's), where one gain in every channel leaves it blue (by over
    15 %)."""
    photo, lighting, skin, right = _half_in_shade()
    tint = light_tint(photo, skin, lighting, sigma_px=3.0)
    assert tint.shape == photo.shape
    lit, shade = ~right.copy(), right.copy()
    lit[:, 50:] = False
    shade[:, :70] = False
    np.testing.assert_allclose(tint[lit], 1.0, atol=0.02)
    chroma = lambda rgb: rgb / rgb.mean(axis=-1, keepdims=True)  # noqa: E731
    expected = chroma(photo[lit][0]) / chroma(photo[shade][0])
    np.testing.assert_allclose(tint[shade], np.broadcast_to(expected / expected.mean(), tint[shade].shape), rtol=0.02)
    g = np.where(right, photo[lit][0].mean() / photo[shade][0].mean(), 1.0)[..., None] * np.ones(3, np.float32)
    lifted = photo * tinted(g.astype(np.float32), tint)
    np.testing.assert_allclose(lifted[shade], np.broadcast_to(photo[lit][0], lifted[shade].shape), rtol=0.07)
    assert np.abs((photo * g)[shade] / photo[lit][0] - 1.0).max() > 0.15


def test_no_change_of_light_no_change_of_colour_and_a_grey_photo_has_none():
    """A gain of 1 stays 1 whatever the tint, and so does a gain that darkens (the colour of what is left would be
    the difference of two near quantities); without a tint (a grey photo, too little skin) the gain is as it was."""
    photo, lighting, skin, right = _half_in_shade()
    tint = light_tint(photo, skin, lighting, sigma_px=3.0)
    ones = np.ones_like(photo)
    np.testing.assert_array_equal(tinted(ones, tint), ones)
    g = np.full_like(photo, 1.7)
    np.testing.assert_array_equal(tinted(g, None), g)
    assert light_tint(photo.mean(axis=-1, keepdims=True), skin, lighting, 3.0) is None
    few = np.zeros_like(skin)
    few[:5, :5] = True
    assert light_tint(photo, few, lighting, 3.0) is None
    dark = np.full_like(photo, 0.3)
    np.testing.assert_array_equal(tinted(dark, tint), dark)
