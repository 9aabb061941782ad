import numpy as np
from conftest import random_unit
from shadowflow.nodes.geometry.normals import angle_deg
from shadowflow.nodes.geometry.reflectance import light_from_angles, project_to_cone, project_to_halfspace
from shadowflow.nodes.photo.lights import yaleb_light


def test_cone_projection_satisfies_lambert_and_is_closest():
    rng = np.random.default_rng(2)
    s = light_from_angles(40, 15)
    n = random_unit(3000, rng)
    intensity = rng.uniform(0, 1, len(n))
    out = project_to_cone(n, s, intensity)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1, atol=1e-12)
    np.testing.assert_allclose(out @ s, intensity, atol=1e-9)
    # the rotation stays in the plane of s and n: the azimuth about s is kept
    np.testing.assert_allclose(np.sum(np.cross(s, n) * out, axis=1), 0, atol=1e-9)
    # closest point: no other sampled point on the same cone is nearer
    phi = np.linspace(0, 2 * np.pi, 361)
    a = np.arccos(intensity[0])
    u = np.cross(s, [0, 1, 0]); u /= np.linalg.norm(u); w = np.cross(s, u)
    ring = np.cos(a) * s + np.sin(a) * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * w)
    assert angle_deg(out[:1], n[:1])[0] <= np.min(angle_deg(ring, n[0])) + 1e-6


def test_halfspace_keeps_normals_facing_away_and_moves_others_to_terminator():
    rng = np.random.default_rng(3)
    s = light_from_angles(-60)
    n = random_unit(2000, rng)
    out = project_to_halfspace(n, s)
    away = n @ s <= 0
    np.testing.assert_allclose(out[away], n[away])
    np.testing.assert_allclose(out[~away] @ s, 0, atol=1e-9)


def test_yaleb_convention_positive_azimuth_lights_image_left():
    s = yaleb_light("yaleB01_P00A+050E+00.pgm")
    np.testing.assert_allclose(s, [-np.sin(np.radians(50)), 0, np.cos(np.radians(50))], atol=1e-12)
    s = yaleb_light("yaleB01_P00A-035E+40.pgm")
    assert s[0] > 0 and s[1] > 0
    np.testing.assert_allclose(np.linalg.norm(s), 1)
