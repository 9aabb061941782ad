"""Albedo: the smooth skin albedo of the fit's albedo rounds and the output map."""
import numpy as np


def _dome(axis_col: float):
    """An 80 x 80 hemisphere, symmetric about column ``axis_col``: rows, columns, x, y (unit radius), its
    mask and normals (80, 80, 3)."""
    yy, xx = np.mgrid[:80, :80]
    x, y = (xx - axis_col) / 36.0, -(yy - 39.5) / 36.0
    mask = x**2 + y**2 < 1.0
    z = np.sqrt(np.clip(1.0 - x**2 - y**2, 0.0, None))
    return yy, xx, x, y, mask, np.dstack([x, y, z]) * mask[..., None]


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


def test_estimated_albedo_is_measured_where_lit_mirrored_in_shadow_and_filled_beyond():
    """A symmetric face-like surface with a symmetric albedo (darker 'brows'), lit from the side:
    lit pixels give ``I / n.s`` exactly; the shadowed side takes its mirror pixel's value, which
    is the truth again; pixels with neither (a shadow on both sides) are filled smoothly between
    their neighbours. Source codes say which is which. (The paper's fill: ``fill_ceiling=None``.)"""
    from shadowflow.nodes.method.albedo import MIN_SHADING, estimate_albedo

    yy, xx, x, y, mask, n = _dome(39.5)
    truth = np.where(np.abs(y - 0.4) < 0.08, 0.45, 0.8) - 0.1 * y**2 - 0.2 * x**2  # symmetric about column 39.5
    s = np.array([-0.6, 0.0, 0.8])  # toward the image's left: the right half is dark
    shading = n @ s
    lit = mask & (shading > 0)
    lit[60:66, :] = False  # a cast shadow across both halves
    image = np.where(lit, truth * np.clip(shading, 0, None), 0.0)
    albedo, source = estimate_albedo(image, n, s, lit, mask, axis_col=39.5, fill_ceiling=None)
    measured, mirrored, filled = source == 1, source == 2, source == 3
    assert measured.sum() > 0.3 * mask.sum() and mirrored.sum() > 0.2 * mask.sum() and filled.any()
    assert (source[~mask] == 0).all() and np.isnan(albedo[~mask]).all()
    assert (shading[measured] >= MIN_SHADING).all()
    np.testing.assert_allclose(albedo[measured], truth[measured], rtol=1e-5)
    np.testing.assert_allclose(albedo[mirrored], truth[mirrored], rtol=1e-5)
    # the shadow band across the face: filled between the rows above and below, no value off range
    band = filled & (yy >= 60) & (yy < 66)
    assert band.any() and np.all((albedo[band] > 0.6) & (albedo[band] < 0.85))


def test_filled_albedo_is_never_brighter_than_typical_skin_but_keeps_dark_features():
    """The default fill (``FILL_CEILING``): a speck of shine on the lit side (``I / n.s`` far above
    the skin's) is not carried to the shadowed side as bright skin; the dark 'brows' are; measured
    pixels keep their values, shine included."""
    from shadowflow.nodes.method.albedo import FILL_CEILING, estimate_albedo

    h = w = 80
    yy, xx = np.mgrid[:h, :w]
    x, y = (xx - 39.5) / 36.0, -(yy - 39.5) / 36.0
    mask = x**2 + y**2 < 1.0
    n = np.dstack([x, y, np.sqrt(np.clip(1.0 - x**2 - y**2, 0.0, None))]) * mask[..., None]
    skin = np.where(np.abs(y - 0.4) < 0.08, 0.45, 0.8)  # uniform skin, darker brows
    s = np.array([-0.6, 0.0, 0.8])
    shading = n @ s
    lit = mask & (shading > 0)
    shine = mask & (np.hypot(xx - 15, yy - 50) < 3)  # on the lit side
    image = np.where(lit, skin * np.clip(shading, 0, None), 0.0)
    image[shine] *= 2.5
    albedo, source = estimate_albedo(image, n, s, lit, mask, axis_col=39.5)
    paper, _ = estimate_albedo(image, n, s, lit, mask, axis_col=39.5, fill_ceiling=None)
    mirror_of_shine = np.zeros_like(shine)
    mirror_of_shine[:, ::-1] = shine
    mirrored = (source == 2) & mirror_of_shine
    assert mirrored.sum() > 10
    assert np.all(paper[mirrored] > 1.9)  # the paper's fill copies the shine
    np.testing.assert_allclose(albedo[mirrored], FILL_CEILING * 0.8, rtol=1e-6)  # the skin's median
    brows = (source == 2) & (skin < 0.5)
    np.testing.assert_allclose(albedo[brows], 0.45, rtol=1e-5)
    measured = source == 1
    np.testing.assert_allclose(albedo[measured], paper[measured])
    assert np.all(albedo[measured & shine] > 1.9)


def test_a_mirror_map_fills_the_shadowed_side_from_the_pixels_it_names():
    """A turned face's mirror pixels come as an index map (``ShapeModel.mirror``): the same face as above,
    its mirror map the column flip, gives the column flip's albedo exactly; a map that names other pixels
    takes their values, and -1 leaves a pixel to the smooth fill."""
    from shadowflow.nodes.method.albedo import estimate_albedo

    yy, xx, x, y, mask, n = _dome(40.0)
    truth = 0.8 - 0.2 * x**2 + 0.1 * (xx % 7 == 0)
    s = np.array([-0.6, 0.0, 0.8])
    lit = mask & (n @ s > 0)
    image = np.where(lit, truth * np.clip(n @ s, 0, None), 0.0)
    index = np.full(mask.shape, -1)
    index[mask] = np.arange(mask.sum())
    rows, cols = np.nonzero(mask)
    flip = index[rows, np.clip(80 - cols, 0, 79)]  # the column mirror about column 40
    by_column = estimate_albedo(image, n, s, lit, mask, axis_col=40.0, fill_ceiling=None)
    by_map = estimate_albedo(image, n, s, lit, mask, axis_col=flip, fill_ceiling=None)
    np.testing.assert_array_equal(by_map[1], by_column[1])
    np.testing.assert_array_equal(by_map[0], by_column[0])
    assert (by_map[1] == 2).sum() > 0.2 * mask.sum()
    none = np.full(mask.sum(), -1)  # no mirror anywhere: what the light does not reach is filled smoothly
    alone = estimate_albedo(image, n, s, lit, mask, axis_col=none, fill_ceiling=None)[1]
    assert not (alone == 2).any() and (alone == 3).sum() == (by_map[1] >= 2).sum()
