"""Integrating normals to depth, and hole filling."""
import numpy as np
from shadowflow.nodes.geometry.integrate import frankot_chellappa, harmonic_fill, masked_least_squares
from shadowflow.nodes.geometry.normals import normals_from_depth


def _bump(h=96, w=96):
    rows, cols = np.mgrid[0:h, 0:w].astype(float)
    x, y = cols - w / 2, rows - h / 2
    z = 20 * np.exp(-(x**2 + y**2) / (2 * 14**2)) + 0.1 * x
    mask = (x / 40) ** 2 + (y / 30) ** 2 < 1
    return np.where(mask, z, np.nan), mask


def _rmse_up_to_offset(a, b, mask):
    d = (a - b)[mask]
    return float(np.sqrt(np.mean((d - d.mean()) ** 2)))


def test_masked_least_squares_recovers_analytic_surface():
    z, mask = _bump()
    n = normals_from_depth(z)
    rec = masked_least_squares(n, mask)
    assert np.all(np.isnan(rec[~mask])) and np.nanmin(rec) == 0.0
    assert _rmse_up_to_offset(rec, z, mask) < 0.05  # pixels; relief is 20


def test_frankot_chellappa_is_biased_at_the_mask_edge():
    z, mask = _bump()
    n = normals_from_depth(z)
    fc = frankot_chellappa(n, mask)
    lsq = masked_least_squares(n, mask)
    e_fc, e_lsq = _rmse_up_to_offset(fc, z, mask), _rmse_up_to_offset(lsq, z, mask)
    assert e_fc > 5 * e_lsq  # periodic boundary + zero gradients outside the face
    assert e_fc < 5.0  # but still a surface of the right kind


def test_harmonic_fill_is_exact_for_linear_fields():
    rows, cols = np.mgrid[0:40, 0:50].astype(float)
    f = 2.0 * cols - 0.5 * rows + 3
    holes = np.zeros_like(f, bool)
    holes[10:25, 12:30] = True
    g = np.where(holes, np.nan, f)
    np.testing.assert_allclose(harmonic_fill(g, holes), f, atol=1e-8)
