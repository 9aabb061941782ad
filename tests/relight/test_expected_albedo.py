"""The albedo the relighting knows beyond what the photo shows lit (``relight/albedo.py``): the lit skin's albedo
carried over the face by the fit's map, and the side lit less raised toward its mirror image."""
import numpy as np
from shadowflow.nodes.relight.albedo import expected_albedo, lifted, mirror_raise

H, W = 80, 100
SKIN = np.array([0.6, 0.44, 0.33], np.float32)


def _grid():
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    face = np.hypot((yy - 40) / 35, (xx - 50) / 45) <= 1
    return yy, xx, face


def test_the_expected_albedo_is_the_lit_skins_carried_into_the_shadow_by_the_fits_map():
    """Skin of one albedo lit from the left, with a deep shadow (0.2 of its light) on the right. Measured on the
    lit skin alone, the expected albedo is the skin's own everywhere (the shadow does not pull it down), in the
    skin's colour, not the fit's grey map's level; where the fit's map is half as bright (a darker part of the
    face, far from the lit skin) it is half the skin's. NaN off the face."""
    _, xx, face = _grid()
    lighting = (0.2 + 0.8 * np.clip(1.0 - xx / 70, 0, 1)).astype(np.float32)
    shadow = face & (xx > 62) & (xx < 85)
    photo = SKIN * lighting[..., None] * np.where(shadow, 0.2, 1.0)[..., None]
    lit = face & (lighting >= 0.6)
    coarse = np.where(face, 0.5, np.nan).astype(np.float32)
    expected = expected_albedo(photo, lighting, lit, coarse, face, 6.0)
    np.testing.assert_allclose(expected[face] / SKIN, 1.0, rtol=1e-4)
    assert np.isnan(expected[~face]).all()
    darker_map = np.where(face, np.where(xx > 62, 0.25, 0.5), np.nan).astype(np.float32)
    expected = expected_albedo(photo, lighting, lit, darker_map, face, 6.0)
    np.testing.assert_allclose(expected[shadow] / SKIN, 0.5, rtol=1e-3)


def test_the_side_lit_less_is_raised_toward_its_mirror_only_as_a_new_light_brightens_it():
    """A symmetric face whose measured albedo on its right (lit 0.4, its mirror 0.9) came out 0.7 of the left's (the
    fitted shading's error): the right may be raised by its mirror's level over its own, 1 / 0.7, at the strength
    (0.9 - 0.4) / 0.9; the left, lit more, not at all. A light that does not brighten the right (``S' / S`` 1)
    raises nothing, so the photo's own light gives the photo back; one brightening it 1.5x raises it by
    (1 / 0.7)^(5/9)."""
    yy, xx, face = _grid()
    albedo = np.where((xx > 50)[..., None], 0.7 * SKIN, SKIN).astype(np.float32)
    shading = np.where(xx > 50, 0.4, 0.9).astype(np.float32)
    reach = (np.clip(np.abs(xx - 50) / 5, 0, 1) * face).astype(np.float32)
    axis = np.array([[50.0, 0.0], [50.0, 79.0]])
    ratio, strength = mirror_raise(albedo, face.astype(np.float32), axis, shading, 6.0, reach)
    core = (np.abs(yy - 40) < 20) & face
    right, left = core & (xx > 62) & (xx < 85), core & (xx > 15) & (xx < 38)
    np.testing.assert_allclose(ratio[right], 1 / 0.7, rtol=0.02)
    np.testing.assert_allclose(strength[right], 0.5 / 0.9, rtol=0.01)
    np.testing.assert_allclose(ratio[left], 1.0, atol=1e-6)
    np.testing.assert_allclose(strength[left], 0.0, atol=1e-6)
    np.testing.assert_array_equal(lifted(ratio, strength, np.ones((H, W), np.float32)), 1.0)
    brighter = lifted(ratio, strength, np.full((H, W), 1.5, np.float32))
    np.testing.assert_allclose(brighter[right], (1 / 0.7) ** (0.5 / 0.9), rtol=0.02)
