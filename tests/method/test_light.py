"""The light estimate for photos whose light nobody wrote down (nodes/light.py)."""
import numpy as np
from conftest import random_unit
from shadowflow.nodes.geometry.normals import angle_deg
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.method.light import estimate_light, mean_face_weights


def _scene(rng, n=4000):
    """True normals, and a stand-in 'mean face' that is off by a per-pixel spread: small on most
    pixels, large (about 25 degrees) on a fifth of them, as the eyes, nose and jaw of a mean face
    are against a real one. Returns (true normals, stand-in, variance of the stand-in's error)."""
    truth = random_unit(n, rng, min_z=0.3)
    sd = np.where(rng.random(n) < 0.2, np.radians(25.0), np.radians(3.0))
    noisy = truth + sd[:, None] * rng.standard_normal((n, 3))
    # the large errors lean one way, like a mean face pitched against the photo
    noisy[:, 1] += np.where(sd > 0.1, 0.35, 0.0)
    noisy /= np.linalg.norm(noisy, axis=1, keepdims=True)
    return truth, noisy, 2 * sd**2


def test_light_is_recovered_from_true_normals_with_attached_shadow_and_albedo():
    rng = np.random.default_rng(0)
    truth, _, _ = _scene(rng)
    for az, el in ((25, 0), (-50, 10), (70, 0)):
        s = light_from_angles(az, el)
        intensity = 0.8 * np.clip(truth @ s, 0, None)  # the shadowed side included, albedo 0.8
        est = estimate_light(intensity, truth)
        assert angle_deg(est[None], s[None])[0] < 0.5, (az, el, est)


def test_trusting_the_pixels_where_the_mean_face_is_reliable_beats_trusting_all():
    rng = np.random.default_rng(1)
    truth, stand_in, var = _scene(rng)
    weighted, plain = [], []
    for az in (25, 50, 70, -50):
        s = light_from_angles(az, 0)
        intensity = 0.8 * np.clip(truth @ s, 0, None) + rng.normal(0, 0.01, len(truth))
        plain.append(angle_deg(estimate_light(intensity, stand_in)[None], s[None])[0])
        w = mean_face_weights(var)
        weighted.append(angle_deg(estimate_light(intensity, stand_in, weights=w)[None], s[None])[0])
    assert np.mean(weighted) < 0.5 * np.mean(plain), (weighted, plain)
    assert np.mean(weighted) < 3.0, weighted
