"""The brightness scale: the paper's peak remap, the ratio to the mean face, over-exposure."""
import numpy as np
import pytest
from shadowflow.nodes.geometry.reflectance import light_from_angles


def test_remap_ignores_hot_pixels_and_uses_the_peak_shading():
    from shadowflow.nodes.method.remap import expected_peak_shading, lambertian_remap

    rng = np.random.default_rng(0)
    img = rng.uniform(0.1, 0.6, (50, 50))
    img[20:23, 20:23] = 0.8  # the real brightest spot (3x3)
    img[5, 5] = img[40, 7] = 1.0  # isolated hot pixels
    mask = np.ones_like(img, bool)
    out, scale = lambertian_remap(img, mask)
    assert scale == pytest.approx(0.8) and out[21, 21] == pytest.approx(1.0)
    assert out[5, 5] == 1.0  # clipped, not trusted as the scale
    out2, scale2 = lambertian_remap(img, mask, peak_shading=0.9)
    assert scale2 == pytest.approx(0.8 / 0.9) and out2[21, 21] == pytest.approx(0.9)
    normals = np.array([[0, 0, 1.0], [np.sin(0.3), 0, np.cos(0.3)]])
    s = light_from_angles(-60)  # toward the image's right: +x
    assert expected_peak_shading(normals, s) == pytest.approx(np.cos(np.radians(60) - 0.3))
    with pytest.raises(ValueError, match="black"):
        lambertian_remap(np.zeros((8, 8)), np.ones((8, 8), bool))


def _sphere_face(n: int = 96):
    """A hemisphere's normals (n, n, 3) and its mask: a face-sized convex surface."""
    yy, xx = np.mgrid[:n, :n]
    x, y = (xx - n / 2 + 0.5) / (0.45 * n), -(yy - n / 2 + 0.5) / (0.45 * n)
    mask = x**2 + y**2 < 1.0
    z = np.sqrt(np.clip(1.0 - x**2 - y**2, 0.0, None))
    return np.dstack([x, y, z]) * mask[..., None], mask


def test_the_ratio_scale_recovers_the_exposure_of_an_over_exposed_face():
    """A face twice as bright as its Lambertian shading, a third of it clipped at 1: the peak is
    lost, the median ratio of unclipped lit brightness to the mean face's shading is not. Measured:
    1.95 with the true shape (the unclipped pixels lean to the darker skin), 1.90 with a mean face
    whose normals are 5 deg off pixel by pixel (1.84 at 8 deg)."""
    from shadowflow.nodes.geometry.normals import normalize
    from shadowflow.nodes.method.remap import clipped_pixels, lambertian_remap, ratio_scale

    n, mask = _sphere_face()
    s = light_from_angles(30, 10)
    rng = np.random.default_rng(2)
    albedo = rng.uniform(0.85, 1.15, mask.shape)  # skin's small variation, median 1
    shading = np.clip(n @ s, 0.0, None)
    image = np.clip(2.0 * albedo * shading, 0.0, 1.0)[mask]
    clipped = clipped_pixels(image)
    assert 0.2 < clipped.mean() < 0.8  # over-exposed: much of the face at 1
    assert ratio_scale(image, shading[mask]) == pytest.approx(2.0, rel=0.04)
    other = normalize(n[mask] + rng.normal(0.0, np.radians(5) / np.sqrt(2), (int(mask.sum()), 3)))
    assert ratio_scale(image, np.clip(other @ s, 0.0, None)) == pytest.approx(2.0, rel=0.08)
    # the paper's peak remap has nothing to go by here: its scale is set by the clipped plateau
    _, peak_scale = lambertian_remap(np.where(mask, np.clip(2.0 * albedo * shading, 0, 1), 0), mask)
    assert peak_scale == pytest.approx(1.0)
    # a well-exposed face: its one brightest point at 1 is not over-exposure
    well = np.clip(albedo * shading / (albedo * shading).max(), 0, 1)[mask]
    assert not clipped_pixels(well).any()
    with pytest.raises(ValueError, match="too few"):
        ratio_scale(np.ones(500), np.ones(500))  # everything clipped: nothing to go by
