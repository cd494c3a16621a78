"""Mesh-backed regions and interfaces on tiny meshes made with trimesh."""

import numpy as np
import pytest
import torch
import trimesh

from ginn.geometry import Box, MeshInterface, MeshRegion, load_mesh, sample_inside, sample_interfaces
from ginn.geometry.mesh import closest_points_on_triangles

F64 = torch.float64


def brute_distance(mesh, x):
    tri = np.asarray(mesh.vertices)[np.asarray(mesh.faces)]
    q = x.numpy()
    n, f = len(q), len(tri)
    qq = np.repeat(q, f, axis=0)
    t = np.tile(tri, (n, 1, 1))
    cp = closest_points_on_triangles(qq, t[:, 0], t[:, 1], t[:, 2])
    return np.linalg.norm(qq - cp, axis=1).reshape(n, f).min(1)


def test_closest_point_on_triangle_regions():
    a, b, c = np.array([[0.0, 0, 0]]), np.array([[1.0, 0, 0]]), np.array([[0.0, 1, 0]])
    cases = {
        (0.2, 0.2, 1.0): (0.2, 0.2, 0.0),  # face
        (-1.0, -1.0, 0.0): (0.0, 0.0, 0.0),  # vertex a
        (2.0, -0.5, 0.0): (1.0, 0.0, 0.0),  # vertex b
        (0.5, -1.0, 0.3): (0.5, 0.0, 0.0),  # edge ab
        (1.0, 1.0, 0.0): (0.5, 0.5, 0.0),  # edge bc
        (-0.5, 0.5, 0.0): (0.0, 0.5, 0.0),  # edge ca
    }
    for p, q in cases.items():
        got = closest_points_on_triangles(np.array([p]), a, b, c)[0]
        np.testing.assert_allclose(got, q, atol=1e-12)


def test_sphere_mesh_region_contains_and_sdf(gen):
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    R = MeshRegion(mesh)
    x = -0.8 + 1.6 * torch.rand(3000, 3, generator=gen, dtype=F64)
    r = x.norm(dim=-1)
    inside = R.contains(x)
    # the mesh is inscribed in the sphere: points clearly inside/outside agree
    clear = (r - 0.5).abs() > 0.01
    assert torch.equal(inside[clear], (r < 0.5)[clear])
    s = R.sdf(x)
    assert (s[:300].abs() - torch.from_numpy(brute_distance(mesh, x[:300]))).abs().max() < 1e-12  # exact nearest triangle
    assert (s - (r - 0.5)).abs().max() < 0.01  # faceting error of the icosphere
    assert ((s <= 0) == inside).all()
    # grid-aligned points through vertices and edges of the mesh are handled consistently
    g = torch.linspace(-0.5, 0.5, 11, dtype=F64)
    grid = torch.cartesian_prod(g, g, g)
    rg = grid.norm(dim=-1)
    clear = (rg - 0.5).abs() > 0.01
    assert torch.equal(R.contains(grid)[clear], (rg < 0.5)[clear])
    assert R.volume() == pytest.approx(mesh.volume)


def test_box_mesh_grid_points():
    mesh = trimesh.creation.box(extents=[1.0, 2.0, 0.5])
    R = MeshRegion(mesh)
    g = torch.linspace(-1.0, 1.0, 21, dtype=F64)
    grid = torch.cartesian_prod(g, g, g)
    lim = torch.tensor([0.5, 1.0, 0.25], dtype=F64)
    strictly = (grid.abs() < lim - 1e-9).all(-1)
    outside = (grid.abs() > lim + 1e-9).any(-1)
    c = R.contains(grid)
    assert c[strictly].all() and not c[outside].any()


def test_sample_inside_mesh_region(gen):
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    R = MeshRegion(mesh)
    x = sample_inside(R, Box((-0.5,) * 3, (0.5,) * 3), 500, gen, dtype=F64)
    assert x.shape == (500, 3) and R.contains(x).all() and (x.norm(dim=-1) <= 0.4 + 1e-12).all()


def test_mesh_interface_components_normals_and_area(gen):
    a = trimesh.creation.box(extents=[0.2, 0.2, 0.2])
    a.apply_translation([-0.5, 0, 0])
    b = trimesh.creation.box(extents=[0.4, 0.4, 0.4])
    b.apply_translation([0.5, 0, 0])
    mesh = trimesh.util.concatenate([a, b])
    I = MeshInterface(mesh)
    assert I.n_components == 2
    assert I.measure() == pytest.approx(6 * 0.04 + 6 * 0.16)
    x, nrm = sample_interfaces([I], 4000, gen, dtype=F64)
    assert I.distance(x).max() < 1e-12
    y = x + 0.05 * torch.randn(x.shape, generator=gen, dtype=F64)
    assert torch.isinf(I.rim_distance(y)).all()  # closed boxes: no open edge
    open_box = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    open_box.update_faces(open_box.face_normals[:, 2] < 0.5)  # without its top: the rim is the square z = 0.5
    rim = MeshInterface(open_box).rim_distance(torch.tensor([[0.0, 0.0, 0.5], [0.5, 0.5, 1.0], [0.3, 0.0, 0.5]], dtype=F64))
    torch.testing.assert_close(rim, torch.tensor([0.5, 0.5, 0.2], dtype=F64))
    d, q = I.nearest(y)  # the nearest point on the mesh, at the stated distance
    torch.testing.assert_close((y - q).norm(dim=-1), d, atol=1e-12, rtol=0)
    assert I.distance(q).max() < 1e-12
    comp = I.component_of(x)
    assert torch.equal(comp, (x[:, 0] > 0).long()) or torch.equal(comp, (x[:, 0] < 0).long())
    # area-uniform: the big box holds 0.96 / 1.2 = 80 % of the area
    assert (x[:, 0] > 0).double().mean().item() == pytest.approx(0.8, abs=0.03)
    # outward face normals: the axis with the largest |offset from the box centre| (scaled)
    centre = torch.where(x[:, 0:1] > 0, torch.tensor([0.5, 0, 0], dtype=F64), torch.tensor([-0.5, 0, 0], dtype=F64))
    half = torch.where(x[:, 0:1] > 0, torch.tensor(0.2, dtype=F64), torch.tensor(0.1, dtype=F64))
    rel = (x - centre) / half
    ax = rel.abs().argmax(-1)
    expected = torch.zeros_like(x)
    expected[torch.arange(len(x)), ax] = torch.sign(rel[torch.arange(len(x)), ax])
    torch.testing.assert_close(nrm, expected, atol=1e-12, rtol=0)
    flipped = MeshInterface(mesh, normals="flipped")
    _, n2 = flipped.sample(10, gen, dtype=F64)
    torch.testing.assert_close(n2.norm(dim=-1), torch.ones(10, dtype=F64))


def test_load_mesh_errors_and_normalisation(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_mesh(tmp_path / "missing.stl")
    bad = tmp_path / "bad.stl"
    bad.write_text("this is not a mesh\n")
    with pytest.raises(ValueError):
        load_mesh(bad)
    m = trimesh.creation.box(extents=[2.0, 2.0, 2.0])
    m.apply_translation([10.0, 0.0, 0.0])
    p = tmp_path / "box.stl"
    m.export(p)
    n = load_mesh(p, center=[10.0, 0.0, 0.0], scale=2.0)
    np.testing.assert_allclose(n.bounds, [[-0.5] * 3, [0.5] * 3], atol=1e-12)
    open_mesh = trimesh.Trimesh(vertices=m.vertices, faces=m.faces[:-2])
    with pytest.raises(ValueError, match="watertight"):
        MeshRegion(open_mesh)
