"""The discrete minimal-surface reference against surfaces with closed forms."""

import numpy as np
import pytest

from ginn.eval.reference.minimal_surface import (
    PLATEAU_AREA_ESTIMATE,
    annulus_minimal_surface,
    catenoid_area,
    circle_curve,
    cotangent_laplacian,
    disk_minimal_surface,
    mesh_area,
    plateau_polygon,
    polygon_curve,
    unit_disk_mesh,
)


def test_cotangent_laplacian_is_dirichlet_energy():
    P, F, _ = unit_disk_mesh(6)
    V = np.concatenate([P, np.zeros((len(P), 1))], axis=1)
    L = cotangent_laplacian(V, F)
    one = np.ones(len(V))
    assert np.abs(L @ one).max() <= 1e-12
    x = V[:, 0]
    # a linear function has |grad|^2 = 1: energy x^T L x / 2 = area / 2
    assert abs(x @ (L @ x) / 2 - mesh_area(V, F) / 2) <= 1e-12
    # linear functions are discrete-harmonic at interior vertices
    boundary = np.linalg.norm(P, axis=1) > 1 - 1e-12
    assert np.abs((L @ x)[~boundary]).max() <= 1e-12


@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (0.2, -0.3, 1.0)])
def test_planar_circle_gives_flat_disk(normal):
    c, r = np.array([0.1, -0.2, 0.3]), 0.7
    s = disk_minimal_surface(circle_curve(c, r, normal), rings=16)
    n = np.asarray(normal) / np.linalg.norm(normal)
    assert np.abs((s.V - c) @ n).max() <= 1e-3
    assert abs(s.area / (np.pi * r * r) - 1) <= 0.01
    # inscribed 96-gon: the discrete area is the polygon's, (m/2) r^2 sin(2 pi / m)
    m = 96
    assert abs(s.area - 0.5 * m * r * r * np.sin(2 * np.pi / m)) <= 1e-12


def test_catenoid_closed_form():
    A, a = catenoid_area(1.0, 0.5)
    assert abs(a * np.cosh(0.5 / a) - 1.0) <= 1e-12
    z = np.linspace(-0.5, 0.5, 20001)
    r = a * np.cosh(z / a)
    rp = np.sinh(z / a)
    f = 2 * np.pi * r * np.sqrt(1 + rp**2)
    assert abs(A - np.sum((f[1:] + f[:-1]) / 2 * np.diff(z))) <= 1e-7
    with pytest.raises(ValueError):
        catenoid_area(1.0, 0.7)  # the circles are too far apart


def test_catenoid_between_two_circles():
    A, a = catenoid_area(1.0, 0.5)
    s = annulus_minimal_surface(circle_curve((0, 0, -0.5)), circle_curve((0, 0, 0.5)), 32, 8, max_iter=150)
    assert abs(s.area / A - 1) <= 2e-3
    r, z = np.linalg.norm(s.V[:, :2], axis=1), s.V[:, 2]
    assert np.abs(r - a * np.cosh(z / a)).max() <= 3e-3


def _helicoid_polygon(p=0.5, th=np.pi / 2, m=24):
    v = np.linspace(0, th, m + 1)
    h1 = np.stack([np.cos(v), np.sin(v), p * v], 1)
    h2 = np.stack([-np.cos(v), -np.sin(v), p * v], 1)[::-1]
    exact = th * (np.sqrt(1 + p * p) + p * p * np.arcsinh(1 / p))
    return np.concatenate([h1, h2]), exact


def test_helicoid_patch_area_and_shape():
    G, exact = _helicoid_polygon()
    s = disk_minimal_surface(polygon_curve(G), rings=12, max_iter=30)
    assert abs(s.area / exact - 1) <= 3e-3
    x, y, z = s.V.T
    assert np.abs(x * np.sin(z / 0.5) - y * np.cos(z / 0.5)).max() <= 3e-3


def test_plateau_polygon_reference():
    G = plateau_polygon()
    assert np.allclose(np.linalg.norm(np.roll(G, -1, 0) - G, axis=1), 1.0)
    s = disk_minimal_surface(polygon_curve(G), rings=12, max_iter=30)
    # corners are vertices, the surface lies in the convex hull (the unit cube), below the area 3 of
    # three cube faces spanning the same polygon, and it is close to the extrapolated area
    assert np.all(s.V >= -1e-12) and np.all(s.V <= 1 + 1e-12)
    assert all(np.min(np.linalg.norm(s.V - g, axis=1)) <= 1e-12 for g in G)
    assert abs(s.area / PLATEAU_AREA_ESTIMATE - 1) <= 3e-3
    assert np.median(s.interior_mean_curvature()) <= 1e-2  # discrete |H| (0 for the continuum surface)
