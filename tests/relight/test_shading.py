"""The fitted shape's shading with the room's light (``relight/shading.py``): ``a + (1 - a) S`` and the room's share
``a`` fitted to a face rendered with a known one."""
import numpy as np
import pytest
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.relight.fields import distance_inside
from shadowflow.nodes.relight.shading import Shading, fit_ambient, with_ambient


def _cylinder(h=80, w=100):
    """Normals of a horizontal half-cylinder, turning 69 degrees either side of the view; the face an ellipse."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    t = (xx - w / 2) / (w / 2) * 1.2
    normals = np.dstack([np.sin(t), np.zeros_like(t), np.cos(t)]).astype(np.float32)
    face = np.hypot((yy - h / 2) / (0.45 * h), (xx - w / 2) / (0.45 * w)) <= 1
    return normals, face


def test_the_shading_is_the_rooms_share_plus_the_rest_of_the_lamps_less_its_cast_shadow():
    """``a + (1 - a) max(n . s, 0) (1 - cast)``: a normal facing the light gets 1, one turned away or fully in cast
    shadow only the room's ``a``, one half in cast shadow half the lamp's."""
    s = light_from_angles(30.0)
    away = np.array([-s[0], -s[1], -s[2]])
    normals = np.array([[s, away, s, s]], np.float32)
    cast = np.array([[0.0, 0.0, 1.0, 0.5]], np.float32)
    shading = Shading(normals, 0.2, s)
    np.testing.assert_allclose(shading.lighting(cast=cast), [[1.0, 0.2, 0.2, 0.6]], rtol=1e-6)
    np.testing.assert_allclose(shading.lighting(), with_ambient(shading.direct(), 0.2), rtol=1e-6)


def test_the_rooms_share_of_the_light_is_fitted_to_a_face_rendered_with_it():
    """A skin-coloured cylinder rendered with a lamp from 50 degrees (its far side in attached shadow) and a room's
    share of 0.1, 0.2 or 0.5: fitted on its skin (all but its rim, averaged over a pixel), the share is the true
    one to the fit's grid (10 %), whatever the skin's albedo (fitted up to one)."""
    normals, face = _cylinder()
    core = distance_inside(face) > 6
    s = light_from_angles(50.0)
    direct = np.clip(normals @ s.astype(np.float32), 0.0, None)
    assert (direct[core] == 0).mean() > 0.05
    for ambient in (0.1, 0.2, 0.5):
        photo = (np.array([0.6, 0.44, 0.33], np.float32) * with_ambient(direct, ambient)[..., None]).astype(np.float32)
        assert fit_ambient(photo, direct, core, 1.0) == pytest.approx(ambient, rel=0.1), ambient


def test_where_the_skin_cannot_tell_the_rooms_share_it_is_the_default_and_where_it_can_it_is_its_own():
    """A face lit from the view axis whose skin shows no shading (a flat disc): every share explains it alike, and the
    default (0.15) is taken, not the grid's end (0.01, which drew a side light's shadows black). The cylinder lit from
    50 degrees with a room's share of 0.02, its skin textured, tells its own: kept, not pulled to the default."""
    normals, face = _cylinder()
    core = distance_inside(face) > 6
    flat = np.where(core, 1.0, 0.0).astype(np.float32)
    photo = (np.array([0.6, 0.44, 0.33], np.float32) * np.ones(core.shape, np.float32)[..., None]).astype(np.float32)
    assert fit_ambient(photo, flat, core, 1.0) == pytest.approx(0.15, rel=0.05)
    direct = np.clip(normals @ light_from_angles(50.0).astype(np.float32), 0.0, None)
    pores = np.exp(0.1 * np.random.default_rng(0).standard_normal(core.shape)).astype(np.float32)  # skin's own
    lit = with_ambient(direct, 0.02) * pores
    photo = (np.array([0.6, 0.44, 0.33], np.float32) * lit[..., None]).astype(np.float32)
    assert fit_ambient(photo, direct, core, 1.0) == pytest.approx(0.02, rel=0.15)
