"""The blur the live page does as the product's Gaussian (``relight/live.py``): three boxes."""
import numpy as np
from shadowflow.nodes.relight.live import blur_radius, gaussian_blur


def test_three_boxes_blur_as_a_gaussian_of_the_sigma_asked():
    """An impulse blurred by three boxes of radius r keeps its mass and spreads to the variance r (r + 1) along each
    axis (three boxes of width 2r + 1), which is the sigma asked for to within half a pixel of the box's rounding."""
    for sigma in (1.0, 3.0, 7.5):
        r = blur_radius(sigma)
        impulse = np.zeros((101, 101), np.float32)
        impulse[50, 50] = 1.0
        out = gaussian_blur(impulse, sigma).astype(np.float64)
        assert abs(out.sum() - 1.0) < 1e-5
        x = np.arange(101) - 50
        np.testing.assert_allclose((out.sum(axis=0) * x**2).sum(), r * (r + 1), rtol=1e-4)
        np.testing.assert_allclose((out.sum(axis=1) * x**2).sum(), r * (r + 1), rtol=1e-4)
        assert abs(np.sqrt(r * (r + 1)) - sigma) <= 0.5, sigma
