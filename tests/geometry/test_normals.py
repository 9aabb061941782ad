import numpy as np
import pytest
from conftest import random_unit
from shadowflow.nodes.geometry.normals import aep_forward, aep_inverse, angle_deg, normals_from_depth, tangent_basis


def test_tangent_basis_is_orthonormal_and_frontal_is_image_axes():
    rng = np.random.default_rng(0)
    m = np.vstack([[0, 0, 1.0], random_unit(500, rng, min_z=-0.9)])
    e1, e2 = tangent_basis(m)
    for a, b in ((e1, e1), (e2, e2)):
        np.testing.assert_allclose(np.sum(a * b, 1), 1.0, atol=1e-12)
    for a, b in ((e1, e2), (e1, m), (e2, m)):
        np.testing.assert_allclose(np.sum(a * b, 1), 0.0, atol=1e-12)
    np.testing.assert_allclose(e1[0], [1, 0, 0])
    np.testing.assert_allclose(e2[0], [0, 1, 0])
    # right-handed: e1 x e2 = m
    np.testing.assert_allclose(np.cross(e1, e2), m, atol=1e-12)


@pytest.mark.parametrize("spread", [0.0, 1e-9, 0.3, 1.2, 2.5])
def test_aep_round_trip(spread):
    rng = np.random.default_rng(1)
    m = random_unit(2000, rng)
    e1, e2 = tangent_basis(m)
    # normals at a controlled geodesic distance from m, in random directions
    ang = rng.uniform(0, spread, len(m))
    phi = rng.uniform(0, 2 * np.pi, len(m))
    n = np.cos(ang)[:, None] * m + np.sin(ang)[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    v = aep_forward(n, m, e1, e2)
    # equidistant: the point's distance from the origin is the geodesic angle
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), ang, atol=1e-7)
    back = aep_inverse(v, m, e1, e2)
    assert np.max(angle_deg(back, n)) < 1e-5


def test_aep_of_reference_is_origin_and_frontal_is_exact():
    m = np.array([[0.0, 0.0, 1.0]])
    e1, e2 = tangent_basis(m)
    np.testing.assert_allclose(aep_forward(m, m, e1, e2), 0.0, atol=1e-12)
    n = np.array([[np.sin(0.5), 0.0, np.cos(0.5)]])  # tilted toward +x by 0.5 rad
    np.testing.assert_allclose(aep_forward(n, m, e1, e2), [[0.5, 0.0]], atol=1e-12)


def test_normals_from_depth_of_plane_and_sphere():
    rows, cols = np.mgrid[0:64, 0:64].astype(float)
    plane = 0.5 * cols - 0.25 * rows  # dz/dx = 0.5, dz/dy = +0.25 (y up)
    n = normals_from_depth(plane)
    expect = np.array([-0.5, -0.25, 1.0]) / np.linalg.norm([-0.5, -0.25, 1.0])  # n = (-dz/dx, -dz/dy, 1)
    np.testing.assert_allclose(n.reshape(-1, 3), np.broadcast_to(expect, (64 * 64, 3)), atol=1e-6)
    r = 25.0
    x, y = cols - 32, -(rows - 32)
    inside = x**2 + y**2 < (0.8 * r) ** 2
    sphere = np.where(inside, np.sqrt(np.clip(r**2 - x**2 - y**2, 0, None)), np.nan)
    ns = normals_from_depth(sphere)
    truth = np.stack([x, y, sphere], -1) / r
    err = angle_deg(ns[inside], truth[inside])
    assert np.median(err) < 0.2 and np.max(err) < 4.0
    assert np.all(np.isnan(ns[~inside]))
