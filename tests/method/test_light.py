"""The light estimate for photos whose light nobody wrote down (nodes/method/light.py)."""
import numpy as np
from conftest import random_unit
from shadowflow.nodes.geometry.normals import aep_inverse, angle_deg, tangent_basis
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.method.light import estimate_light, expected_normals


def _faces(rng, n=6000):
    """A mean face's normals and photos' normals drawn around them as a model draws faces (AEP
    coordinates from a zero-mean Gaussian): faces differ much (25 degrees) where the mean face
    turns down, as under the nose and brows and at the chin, and little (3 degrees) elsewhere.
    Returns (a face's normals, mean normals, variance per pixel in radians squared, both axes)."""
    mean = random_unit(n, rng, min_z=0.8)
    var = np.where(mean[:, 1] < -0.2, 2 * np.radians(25.0) ** 2, 2 * np.radians(3.0) ** 2)
    e1, e2 = tangent_basis(mean)
    v = rng.standard_normal((n, 2)) * np.sqrt(var / 2)[:, None]
    return aep_inverse(v, mean, e1, e2), mean, var


def test_light_is_recovered_from_true_normals_with_attached_shadow_and_albedo():
    rng = np.random.default_rng(0)
    truth = random_unit(4000, rng, min_z=0.3)
    for az, el in ((25, 0), (-50, 10), (70, 0)):
        s = light_from_angles(az, el)
        intensity = 0.8 * np.clip(truth @ s, 0, None)  # the shadowed side included, albedo 0.8
        est = estimate_light(intensity, truth)
        assert angle_deg(est[None], s[None])[0] < 0.5, (az, el, est)


def test_expected_normals_are_the_average_of_normals_drawn_around_the_mean():
    rng = np.random.default_rng(2)
    mean = random_unit(200, rng, min_z=0.5)
    var = rng.uniform(0.0, 0.15, 200)  # up to 27 degrees a pixel
    e1, e2 = tangent_basis(mean)
    drawn = np.mean([aep_inverse(rng.standard_normal((200, 2)) * np.sqrt(var / 2)[:, None], mean, e1, e2)
                     for _ in range(4000)], axis=0)
    assert np.abs(drawn - expected_normals(mean, var)).max() < 0.02
    assert np.abs(drawn - mean).max() > 0.05  # the mean normal is not it


def test_the_light_from_expected_normals_does_not_lean_toward_where_faces_differ():
    """The photo's normals differ from the mean face's most where the mean turns down; fitted on
    the mean normals the light leans (5-7 degrees here), on the expected normals it does not."""
    rng = np.random.default_rng(1)
    truth, mean, var = _faces(rng)
    on_mean, on_expected = [], []
    for az, el in ((15, 0), (-10, 10), (0, -15)):
        s = light_from_angles(az, el)
        intensity = 0.8 * np.clip(truth @ s, 0, None) + rng.normal(0, 0.01, len(truth))
        on_mean.append(angle_deg(estimate_light(intensity, mean)[None], s[None])[0])
        on_expected.append(angle_deg(estimate_light(intensity, expected_normals(mean, var))[None], s[None])[0])
    assert min(on_mean) > 3.0, on_mean
    assert max(on_expected) < 2.0 and np.mean(on_expected) < 0.3 * np.mean(on_mean), (on_expected, on_mean)
