"""Rasterising meshes and the surface's grid mesh."""
import numpy as np
import pytest
from shadowflow.nodes.geometry.raster import grid_mesh, grid_row_edges, rasterize, rasterize_row_edges


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
