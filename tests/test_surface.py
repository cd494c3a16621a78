"""Shape extraction: grids, adaptive sampling, closed contours and watertight meshes."""

import math

import numpy as np
import pytest
import torch
import trimesh

from _shapes import Disk
from ginn.extract import (
    Boundary,
    extract_boundary,
    grid_volume,
    label_components,
    make_grid,
    sample_field,
)
from ginn.fields import as_field
from ginn.geometry.base import Box
from ginn.models import Siren

BOX3 = Box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
BOX2 = Box((-1.0, -1.0), (1.0, 1.0))


def sphere(center, r):
    return as_field(Disk(center, r).sdf)


def random_siren(d, seed, w0=3.0):
    torch.manual_seed(seed)
    return Siren(d, [32, 32], w0_first=w0).double().eval()


def random_blobs(d, seed, w0, frac=0.3):
    """A random SIREN shifted so that about ``frac`` of the box is inside: several components."""
    net = random_siren(d, seed, w0)
    x = torch.rand(4096, d, generator=torch.Generator().manual_seed(seed), dtype=torch.float64) * 2 - 1
    with torch.no_grad():
        t = float(torch.quantile(net(x, None), frac))
    return lambda x, z=None: net(x, z) - t


def test_grid_spacing_and_weights():
    g = make_grid(Box((-1.0, -0.5), (1.0, 0.5)), 64)
    assert g.cells == (64, 32)
    np.testing.assert_allclose(g.spacing, [2 / 64, 1 / 32])
    assert g.node_weights().sum(dtype=np.float64) == pytest.approx(2.0, rel=1e-6)
    assert grid_volume(np.ones(g.shape, bool), g) == pytest.approx(2.0, rel=1e-6)
    np.testing.assert_allclose(g.points(np.array([0, g.n_nodes - 1])), [[-1, -0.5], [1, 0.5]])


def test_sphere_mesh_watertight_volume_within_1_percent():
    g = make_grid(BOX3, 64)
    r = 0.6
    b = extract_boundary(sample_field(sphere((0.0, 0.0, 0.0), r), g), g)
    m = trimesh.Trimesh(b.vertices, b.elements, process=False)
    assert m.is_watertight
    exact = 4 / 3 * math.pi * r**3
    assert abs(m.volume - exact) / exact < 0.01
    assert abs(b.signed_volume() - exact) / exact < 0.01
    assert b.on_level_set.all()
    # area: 4 pi r^2 within 1 %
    assert abs(b.measure() - 4 * math.pi * r**2) / (4 * math.pi * r**2) < 0.01


def test_mesh_cut_by_the_box_is_closed_on_the_face():
    g = make_grid(BOX3, 64)
    c, r = 0.9, 0.5  # the sphere pokes 0.4 out of the face x = 1
    b = extract_boundary(sample_field(sphere((c, 0.0, 0.0), r), g), g)
    m = trimesh.Trimesh(b.vertices, b.elements, process=False)
    assert m.is_watertight
    h = c + r - 1.0
    exact = 4 / 3 * math.pi * r**3 - math.pi * h * h * (3 * r - h) / 3
    assert abs(m.volume - exact) / exact < 0.01
    cap = ~b.on_level_set
    assert cap.any()
    np.testing.assert_allclose(b.vertices[cap, 0], 1.0)  # cap vertices lie on the face
    # the flat cap is a disk of radius sqrt(r^2 - (1 - c)^2)
    on_face = np.all(np.isclose(b.vertices[b.elements][..., 0], 1.0), axis=1)
    cap_area = b.element_measures()[on_face].sum()
    assert cap_area == pytest.approx(math.pi * (r * r - (1 - c) ** 2), rel=0.02)


def test_contour_closed_at_domain_boundary_area():
    g = make_grid(BOX2, 128)
    b = extract_boundary(sample_field(sphere((1.0, 0.0), 0.5), g), g)  # half disk inside
    assert b.signed_volume() == pytest.approx(math.pi * 0.25 / 2, rel=2e-3)
    assert b.n_outer_components() == 1


def test_adaptive_sampling_matches_dense_sign_and_exact_near_surface():
    g = make_grid(BOX3, 64)
    for seed in range(3):
        f = random_blobs(3, seed, w0=6.0)
        va = sample_field(f, g)
        vd = sample_field(f, g, adaptive=False)
        assert np.array_equal(va <= 0, vd <= 0)
        # exactly the same mesh
        ba, bd = extract_boundary(va, g), extract_boundary(vd, g)
        np.testing.assert_allclose(ba.vertices, bd.vertices, atol=1e-9)


def test_distance_to_boundary_exact_for_circle():
    g = make_grid(BOX2, 128)
    b = extract_boundary(sample_field(sphere((0.0, 0.0), 0.5), g), g)
    q = np.array([[0.0, 0.0], [0.9, 0.0], [0.3, 0.4], [-0.1, 0.2]])
    exact = np.abs(np.linalg.norm(q, axis=1) - 0.5)
    np.testing.assert_allclose(b.distance(q), exact, atol=2e-4)  # chord sagitta h^2/(8r) ~ 6e-5


def test_closest_point_on_triangle_against_dense_barycentric_search():
    from ginn.geometry.mesh import closest_on_triangles as _closest_on_triangles

    rng = np.random.default_rng(0)
    tri = rng.normal(size=(50, 3, 3))
    p = rng.normal(size=(50, 3)) * 2
    c = _closest_on_triangles(p, tri[:, 0], tri[:, 1], tri[:, 2])
    u, w = np.meshgrid(np.linspace(0, 1, 301), np.linspace(0, 1, 301), indexing="ij")
    keep = u + w <= 1
    u, w = u[keep], w[keep]
    dense = tri[:, None, 0] + u[None, :, None] * (tri[:, None, 1] - tri[:, None, 0]) + w[None, :, None] * (
        tri[:, None, 2] - tri[:, None, 0]
    )
    brute = np.linalg.norm(dense - p[:, None], axis=-1).min(axis=1)
    got = np.linalg.norm(c - p, axis=-1)
    assert np.all(got <= brute + 1e-12)
    np.testing.assert_allclose(got, brute, atol=2e-2 * 1 / 300 * 10)


def test_distance_to_mesh_matches_brute_force():
    from ginn.geometry.mesh import closest_on_triangles as _closest_on_triangles

    g = make_grid(BOX3, 24)
    b = extract_boundary(sample_field(random_siren(3, 1), g), g)
    q = np.random.default_rng(0).uniform(-1, 1, (100, 3))
    V, F = b.vertices, b.elements
    c = _closest_on_triangles(np.broadcast_to(q[:, None], (100, F.shape[0], 3)), V[F[:, 0]], V[F[:, 1]], V[F[:, 2]])
    brute = np.linalg.norm(c - q[:, None], axis=-1).min(axis=1)
    np.testing.assert_allclose(b.distance(q), brute, atol=1e-12)


def test_area_uniform_samples_lie_on_boundary():
    g = make_grid(BOX3, 48)
    b = extract_boundary(sample_field(sphere((0.0, 0.0, 0.0), 0.5), g), g)
    x = b.sample(2000, np.random.default_rng(0))
    np.testing.assert_allclose(np.linalg.norm(x, axis=1), 0.5, atol=2e-3)
    assert b.distance(x).max() < 1e-9
    # uniform by area: the mean is near the centre, each octant gets ~1/8
    frac = np.mean(x[:, 0] > 0)
    assert abs(frac - 0.5) < 0.05


@pytest.mark.parametrize("seed", range(4))
def test_b0_grid_agrees_with_contours_2d(seed):
    g = make_grid(BOX2, 128)
    v = sample_field(random_blobs(2, seed, w0=10.0), g)
    _, n = label_components(v <= 0)
    assert extract_boundary(v, g).n_outer_components() == n
    assert n >= 1


@pytest.mark.parametrize("seed", range(4))
def test_b0_grid_agrees_with_mesh_3d(seed):
    g = make_grid(BOX3, 48)
    v = sample_field(random_blobs(3, seed, w0=8.0), g)
    _, n = label_components(v <= 0)
    assert extract_boundary(v, g).n_outer_components() == n


def test_empty_and_full_fields():
    g = make_grid(BOX2, 16)
    empty = extract_boundary(np.ones(g.shape), g)
    assert empty.n_elements == 0 and isinstance(empty, Boundary)
    full = extract_boundary(-np.ones(g.shape), g)  # the whole box, closed by the caps
    assert full.signed_volume() == pytest.approx(4.0)
    assert not full.on_level_set.any()
