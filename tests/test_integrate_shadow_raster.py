import numpy as np
import pytest
from shadowflow.nodes.geometry.integrate import frankot_chellappa, harmonic_fill, masked_least_squares
from shadowflow.nodes.geometry.normals import normals_from_depth
from shadowflow.nodes.geometry.raster import grid_mesh, grid_row_edges, rasterize, rasterize_row_edges
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.method.shadow import cast_shadow, confirm_with_image, shadow_maps


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


@pytest.mark.parametrize("elev_deg", [30.0, 45.0, 60.0])
def test_shadow_of_a_step_has_the_right_length(elev_deg):
    # a wall of height 10 px at columns 20..21; light from the image's left, elev_deg above the ground plane
    z = np.zeros((20, 80))
    z[:, 20:22] = 10.0
    az = 90.0 - elev_deg  # angle from the view axis
    s = light_from_angles(az)  # toward the image's left: shadows fall to the right
    cast = cast_shadow(z, s)
    length = 10.0 / np.tan(np.radians(elev_deg))
    row = cast[10]
    shadowed = np.flatnonzero(row)
    assert shadowed.min() == 22  # starts right behind the wall
    # heights are bilinear between pixel centres, so the wall top is at column 21 and the
    # shadow reaches up to (not including) column 21 + length
    assert length - 1.0 - 1e-9 <= shadowed.max() - 21 < length
    assert np.array_equal(shadowed, np.arange(22, shadowed.max() + 1))  # one solid run
    assert not row[:20].any()  # nothing on the lit side


def test_frontal_light_casts_no_shadow_and_attached_is_n_dot_s():
    z, mask = _bump()
    n = normals_from_depth(z)
    maps = shadow_maps(z, n, np.array([0, 0, 1.0]))
    assert not maps.cast.any() and not maps.attached.any()
    s = light_from_angles(80)
    maps = shadow_maps(z, n, s)
    facing = np.einsum("hwc,c->hw", np.nan_to_num(n), s)
    assert np.array_equal(maps.attached, mask & (facing <= 0))
    assert not (maps.cast & maps.attached).any()


def test_confirmation_removes_lit_pixels_and_grows_into_connected_dark_ones():
    from shadowflow.nodes.method.shadow import ShadowMaps

    traced = np.zeros((10, 10), bool)
    traced[2:5, 2:5] = True
    image = np.ones((10, 10))
    image[2:6, 2:6] = 0.0  # the real shadow is a little larger
    image[2, 2] = 0.5  # ...and this pixel is visibly lit
    image[8, 8] = 0.0  # dark albedo far from any shadow
    out = confirm_with_image(ShadowMaps(traced, np.zeros_like(traced)), image, 0.02)
    expect = image <= 0.02
    expect[8, 8] = False
    assert np.array_equal(out.cast, expect)


def test_rasterize_plane_and_zbuffer():
    verts = np.array([[0, 0, 0], [30, 0, 30], [0, 30, 0], [30, 30, 30]], float)  # z = x
    tris = np.array([[0, 1, 2], [1, 3, 2]])
    depth, attr = rasterize(verts, tris, (32, 32), attributes=verts[:, :1] * 2)
    inside = np.isfinite(depth)
    assert inside[:31, :31].all() and not inside[31:, :].any()
    cols = np.broadcast_to(np.arange(32.0), (32, 32))
    np.testing.assert_allclose(depth[inside], cols[inside], atol=1e-9)
    np.testing.assert_allclose(attr[..., 0][inside], 2 * cols[inside], atol=1e-9)
    # a nearer triangle in front wins wherever it covers
    front = np.array([[5, 5, 100], [20, 5, 100], [5, 20, 100]], float)
    d2, _ = rasterize(np.vstack([verts, front]), np.vstack([tris, [[4, 5, 6]]]), (32, 32))
    assert d2[8, 8] == 100 and d2[25, 25] == pytest.approx(25)


def test_grid_mesh_covers_the_mask():
    mask = np.zeros((6, 6), bool)
    mask[1:5, 1:4] = True
    pix, tris = grid_mesh(mask)
    assert len(pix) == 12 and len(tris) == 2 * 3 * 2
    # counter-clockwise seen from +z (x = col, y = -row)
    v = np.column_stack([pix % 6, -(pix // 6)]).astype(float)
    a, b, c = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    assert np.all(cross > 0)


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


def test_row_edge_rasterizer_matches_the_general_one_on_a_turned_face():
    """The novel view's fast path: a grid mesh turned about the vertical axis, rendered by 1-D
    interpolation along its horizontal edges, equals the general triangle rasterizer."""
    from shadowflow.nodes.model.sources import procedural

    depths, albedos = procedural(2, seed=5)
    for d, albedo in zip(depths, albedos):
        h, w = d.shape
        pix, tris = grid_mesh(np.isfinite(d))
        rows, cols = np.divmod(pix, w)
        z = d.flat[pix]
        a = np.radians(40.0)
        x_turned = cols.mean() + np.cos(a) * (cols - cols.mean()) + np.sin(a) * (z - z.mean())
        z_turned = z.mean() - np.sin(a) * (cols - cols.mean()) + np.cos(a) * (z - z.mean())
        verts = np.column_stack([x_turned, rows, z_turned])
        attrs = np.nan_to_num(albedo.ravel()[pix])[:, None]
        d1, a1 = rasterize(verts, tris, (h, w), attributes=attrs)
        d2, a2 = rasterize_row_edges(verts, grid_row_edges(np.isfinite(d)), (h, w), attributes=attrs)
        assert np.isfinite(d1).sum() > 3000
        np.testing.assert_array_equal(np.isfinite(d1), np.isfinite(d2))
        np.testing.assert_allclose(d2, d1, atol=1e-9)
        np.testing.assert_allclose(a2, a1, atol=1e-9)
    with pytest.raises(ValueError, match="pixel row"):
        rasterize_row_edges(verts + [0.0, 0.5, 0.0], grid_row_edges(np.isfinite(d)), (h, w))
