"""The small field operations every step of the relighting shares (``relight/fields.py``), on arrays whose
right answer is known."""
import cv2
import numpy as np
from shadowflow.nodes.relight.fields import blur, distance_inside, distance_to, smoothstep, weighted_blur


def test_smoothstep_is_0_below_1_above_and_a_flat_ended_ramp_between():
    """0 at and below ``lo``, 1 at and above ``hi``, 1/2 half way, rising, and flat at both ends (C1): a
    tenth of the way in it has risen 3 t^2 - 2 t^3 = 0.028, not the tenth a straight ramp would."""
    x = np.array([-5.0, 2.0, 2.4, 4.0, 6.0, 9.0], np.float32)
    s = smoothstep(x, 2.0, 6.0)
    np.testing.assert_allclose(s[[0, 1]], 0.0, atol=0)
    np.testing.assert_allclose(s[[4, 5]], 1.0, atol=0)
    np.testing.assert_allclose(s[3], 0.5, atol=1e-6)
    np.testing.assert_allclose(s[2], 3 * 0.1**2 - 2 * 0.1**3, atol=1e-6)
    ramp = smoothstep(np.linspace(2.0, 6.0, 101), 2.0, 6.0)
    assert np.all(np.diff(ramp) >= 0)


def test_a_wide_blur_is_the_gaussian_it_stands_for():
    """A wide blur is taken on a shrunk grid; a step edge blurred so must still be the exact Gaussian's to
    within 1 % (the shrink's sigma wrongly scaled would smear it by several times that)."""
    step = np.zeros((120, 160), np.float32)
    step[:, 80:] = 1.0
    for sigma in (3.0, 8.0, 20.0):
        exact = cv2.GaussianBlur(step, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
        assert np.abs(blur(step, sigma) - exact).max() < 0.01, sigma


def test_weighted_blur_averages_only_what_is_weighted():
    """A normalised average: a constant comes back as that constant wherever there is weight (grey and
    colour, narrow and wide), values under zero weight count for nothing, and the weight returned is the
    blurred weight."""
    rng = np.random.default_rng(0)
    w = (rng.uniform(size=(90, 110)) > 0.6).astype(np.float32)
    values = np.where(w > 0, 0.37, 50.0).astype(np.float32)  # what is not weighted is far off
    for sigma in (1.5, 12.0):
        average, support = weighted_blur(values, w, sigma)
        np.testing.assert_allclose(average[support > 1e-3], 0.37, rtol=1e-4)
        np.testing.assert_allclose(support, blur(w, sigma), atol=1e-6)
        colour = np.dstack([values, 2 * values, 3 * values])
        average3, _ = weighted_blur(colour, w, sigma)
        np.testing.assert_allclose(average3[support > 1e-3] / [0.37, 0.74, 1.11], 1.0, rtol=1e-4)


def test_distances_inside_and_to_a_mask_are_euclidean_pixels():
    """A 21 x 21 square: its centre is 11 pixels from the first pixel off it, its border pixels 1, and
    nothing off the mask is inside it; a pixel 5 columns right of it is 5 from it."""
    mask = np.zeros((41, 41), bool)
    mask[10:31, 10:31] = True
    inside = distance_inside(mask)
    assert inside[20, 20] == 11.0
    assert inside[10, 20] == 1.0 and inside[20, 30] == 1.0
    assert np.all(inside[~mask] == 0.0)
    to = distance_to(mask)
    assert np.all(to[mask] == 0.0)
    np.testing.assert_allclose(to[20, 35], 5.0, atol=1e-3)
    np.testing.assert_allclose(to[5, 5], np.hypot(5, 5), atol=0.05)
