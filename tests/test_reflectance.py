import numpy as np
from conftest import random_unit
from shadowflow.nodes.geometry.normals import angle_deg
from shadowflow.nodes.geometry.reflectance import light_from_angles, project_to_cone, project_to_halfspace
from shadowflow.nodes.photo.loader import yaleb_light


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


def test_smooth_albedo_recovers_slow_skin_changes_and_leaves_shadow_alone():
    """``I / shading`` averaged over trusted pixels: a slow albedo ramp comes back relative to its
    median; a pixel far from any trusted one (deep shadow) gets 1; a dark speck does not move it."""
    from shadowflow.nodes.method.albedo import smooth_albedo

    h = w = 64
    yy, xx = np.mgrid[:h, :w]
    mask = (xx - 32) ** 2 + (yy - 32) ** 2 < 28**2
    albedo = 0.6 + 0.4 * xx / w  # brighter toward the right
    rng = np.random.default_rng(1)
    shading = rng.uniform(0.4, 1.0, (h, w))
    intensity = albedo * shading
    intensity[30:32, 20:22] = 0.0  # a speck of lashes
    trusted = (xx < 50) & (intensity > 0)
    got = smooth_albedo(mask, intensity[mask], shading[mask], trusted[mask], sigma_px=2.0)
    want = albedo[mask] / np.median(albedo[mask & trusted])
    inner = (xx[mask] > 12) & (xx[mask] < 44) & (np.abs(yy[mask] - 32) < 16)
    np.testing.assert_allclose(got[inner], want[inner], rtol=0.03)
    assert np.all(got[xx[mask] > 58] == 1.0)  # > 4 sigma from any trusted pixel
