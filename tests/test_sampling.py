"""Samplers: exact counts, inside/outside, points on interfaces with the right unit normals."""

import math

import pytest
import torch

from ginn.geometry import (
    Annulus,
    Box,
    Circle,
    CylinderWall,
    Difference,
    Disk,
    InterfaceUnion,
    Polyline,
    Rectangle,
    Segment,
    Sphere,
    TransformedInterface,
    interface_corners,
    rotation_matrix,
    sample_band,
    sample_box,
    sample_inside,
    sample_interfaces,
    sample_interfaces_with_components,
    sample_outside,
)
from ginn.geometry.base import nearest_interface_points

F64 = torch.float64


def test_sample_box_counts_bounds_dtype_and_reproducible():
    box = Box((-1.0, -0.5, 0.0), (1.0, 0.5, 2.0))
    x = sample_box(box, 1234, torch.Generator().manual_seed(3), dtype=F64)
    assert x.shape == (1234, 3) and x.dtype == F64
    assert box.contains(x).all()
    y = sample_box(box, 1234, torch.Generator().manual_seed(3), dtype=F64)
    assert torch.equal(x, y)
    # uniform: the mean is the box centre within 4 standard errors
    sd = torch.tensor([2.0, 1.0, 2.0], dtype=F64) / math.sqrt(12 * 1234)
    assert ((x.mean(0) - torch.tensor([0.0, 0.0, 1.0], dtype=F64)).abs() < 4 * sd).all()
    assert sample_box(box, 10, torch.Generator(), dtype=torch.float32).dtype == torch.float32


@pytest.mark.parametrize("n", [1, 17, 1000, 5001])
def test_inside_outside_exact_counts(gen, n):
    box = Box((-1.0, -0.5), (1.0, 0.5))
    E = Difference(Rectangle([-0.9, -0.4], [0.9, 0.4]), Disk([0, 0], 0.1))
    xi = sample_inside(E, box, n, gen, dtype=F64)
    xo = sample_outside(E, box, n, gen, dtype=F64)
    assert xi.shape == (n, 2) and xo.shape == (n, 2)
    assert E.contains(xi).all() and not E.contains(xo).any()
    assert box.contains(xi).all() and box.contains(xo).all()


def test_inside_small_region_and_empty_region(gen):
    box = Box((-1.0,) * 3, (1.0,) * 3)
    tiny = Sphere([0.5, 0.5, 0.5], 0.05)  # acceptance ~6e-5
    x = sample_inside(tiny, box, 300, gen, dtype=F64)
    assert x.shape == (300, 3) and tiny.contains(x).all()
    # uniform inside: the mean distance to the centre of a ball is 3r/4
    assert (x - torch.tensor([0.5] * 3, dtype=F64)).norm(dim=-1).mean().item() == pytest.approx(0.0375, rel=0.05)
    with pytest.raises(ValueError):
        sample_inside(Sphere([5.0, 5.0, 5.0], 0.1), box, 10, gen, max_rounds=4)


def obstacle_interfaces():
    return (
        Segment([-0.9, -0.4], [-0.9, 0.4], normal=[-1.0, 0.0]),
        Segment([0.9, -0.4], [0.9, 0.4], normal=[1.0, 0.0]),
    )


def test_obstacle_segments_points_and_normals(gen):
    ifs = obstacle_interfaces()
    x, nrm = sample_interfaces(ifs, 1001, gen, dtype=F64)
    assert x.shape == (1001, 2) and nrm.shape == (1001, 2)
    assert (x[:, 0].abs() - 0.9).abs().max() < 1e-12 and (x[:, 1].abs() <= 0.4 + 1e-12).all()
    expected = torch.stack([torch.sign(x[:, 0]), torch.zeros(1001, dtype=F64)], -1)
    torch.testing.assert_close(nrm, expected, atol=1e-12, rtol=0)
    # split by measure: equal lengths -> 501 / 500
    left = (x[:, 0] < 0).sum().item()
    assert left in (500, 501)
    x2, n2, comp = sample_interfaces_with_components(ifs, 200, gen, dtype=F64)
    assert torch.equal(comp, (x2[:, 0] > 0).long())


def test_circle_cylinder_annulus_points_and_normals(gen):
    c = Circle([0.2, -0.1], 0.3, normals="inward")
    x, nrm = c.sample(500, gen, dtype=F64)
    assert c.distance(x).max() < 1e-12
    radial = (x - torch.tensor([0.2, -0.1], dtype=F64)) / 0.3
    torch.testing.assert_close(nrm, -radial, atol=1e-12, rtol=0)
    assert c.measure() == pytest.approx(2 * math.pi * 0.3)

    axis = torch.tensor([1.0, 2.0, 2.0], dtype=F64) / 3
    w = CylinderWall([0.1, 0.0, -0.2], axis, 0.25, 0.6, normals="inward")
    x, nrm = w.sample(800, gen, dtype=F64)
    p = x - torch.tensor([0.1, 0.0, -0.2], dtype=F64)
    t = p @ axis
    radial = p - t[:, None] * axis
    assert (radial.norm(dim=-1) - 0.25).abs().max() < 1e-12 and (t.abs() <= 0.3 + 1e-12).all()
    assert w.distance(x).max() < 1e-12
    torch.testing.assert_close(nrm, -radial / radial.norm(dim=-1, keepdim=True), atol=1e-12, rtol=0)  # toward the axis
    # uniform along the axis: mean t ~ 0, var ~ L^2 / 12
    assert t.var().item() == pytest.approx(0.36 / 12, rel=0.15)

    a = Annulus([0.0, 0.1, 0.2], [0, 0, 1], 0.05, 0.09)
    x, nrm = a.sample(600, gen, dtype=F64)
    r = (x[:, :2] - torch.tensor([0.0, 0.1], dtype=F64)).norm(dim=-1)
    assert (x[:, 2] - 0.2).abs().max() < 1e-12 and (r >= 0.05 - 1e-12).all() and (r <= 0.09 + 1e-12).all()
    torch.testing.assert_close(nrm, torch.tensor([[0.0, 0.0, 1.0]], dtype=F64).expand(600, 3), atol=0, rtol=0)
    assert a.distance(x).max() < 1e-12
    # area-uniform: P(r < r_mid) = (r_mid^2 - r_in^2) / (r_out^2 - r_in^2)
    rm = 0.07
    assert (r < rm).double().mean().item() == pytest.approx((rm**2 - 0.05**2) / (0.09**2 - 0.05**2), abs=0.06)


def test_distances_closed_forms():
    w = CylinderWall([0, 0, 0], [0, 0, 1], 1.0, 2.0)
    q = torch.tensor([[0.0, 0.0, 0.0], [2.0, 0.0, 0.5], [2.0, 0.0, 3.0]], dtype=F64)
    torch.testing.assert_close(w.distance(q), torch.tensor([1.0, 1.0, math.sqrt(5.0)], dtype=F64), atol=1e-12, rtol=0)
    a = Annulus([0, 0, 0], [0, 0, 1], 1.0, 2.0)
    q = torch.tensor([[0.0, 0.0, 1.0], [1.5, 0.0, 0.5], [3.0, 0.0, 0.0]], dtype=F64)
    torch.testing.assert_close(a.distance(q), torch.tensor([math.sqrt(2.0), 0.5, 1.0], dtype=F64), atol=1e-12, rtol=0)


def test_nearest_points_closed_forms_and_projections():
    """The nearest point: closed forms on a cylinder wall (its rim beyond the end) and an annulus
    (its inner circle); on every kind, a point of the interface at the stated distance."""
    w = CylinderWall([0, 0, 0], [0, 0, 1], 1.0, 2.0)
    d, q = w.nearest(torch.tensor([[2.0, 0.0, 0.5], [0.0, 2.0, 3.0]], dtype=F64))
    torch.testing.assert_close(q, torch.tensor([[1.0, 0.0, 0.5], [0.0, 1.0, 1.0]], dtype=F64), atol=1e-12, rtol=0)
    torch.testing.assert_close(d, torch.tensor([1.0, math.sqrt(5.0)], dtype=F64), atol=1e-12, rtol=0)
    a = Annulus([0, 0, 0], [0, 0, 1], 1.0, 2.0)
    d, q = a.nearest(torch.tensor([[0.5, 0.0, 1.0]], dtype=F64))
    torch.testing.assert_close(q, torch.tensor([[1.0, 0.0, 0.0]], dtype=F64), atol=1e-12, rtol=0)
    g = torch.Generator().manual_seed(3)
    x3, x2 = torch.randn(300, 3, generator=g, dtype=F64), torch.randn(300, 2, generator=g, dtype=F64)
    kinds = [(w, x3), (a, x3), (Circle([0.1, 0], 0.5), x2), (Polyline([[0, 0], [1, 0], [1, 1]]), x2),
             (InterfaceUnion([w, a], merge=True), x3),
             (TransformedInterface(w, rotation_matrix(3, 30.0, [1, 0, 0]), [0.1, 0.2, 0.3]), x3)]
    for itf, x in kinds:
        d, q = itf.nearest(x)
        torch.testing.assert_close(d, itf.distance(x), atol=1e-12, rtol=0)
        torch.testing.assert_close((x - q).norm(dim=-1), d, atol=1e-12, rtol=0)
        assert itf.distance(q).max() < 1e-12, type(itf).__name__
    d, q = nearest_interface_points([Circle([0, 0], 0.5), Circle([2, 0], 0.5)], torch.tensor([[1.8, 0.0], [0.1, 0.0]], dtype=F64))
    torch.testing.assert_close(q, torch.tensor([[1.5, 0.0], [0.5, 0.0]], dtype=F64), atol=1e-12, rtol=0)
    torch.testing.assert_close(d, torch.tensor([0.3, 0.4], dtype=F64), atol=1e-12, rtol=0)


def test_rims_closed_forms():
    """The rim: a cylinder wall's end circles, an annulus's two circles, a polyline's vertices, a
    bolt hole's group (the wall's top circle is the ring's inner one); a circle has none."""
    w = CylinderWall([0, 0, 0], [0, 0, 1], 1.0, 2.0)
    q = torch.tensor([[0.0, 0.0, 0.0], [2.0, 0.0, 0.5], [1.0, 0.0, 1.0]], dtype=F64)
    torch.testing.assert_close(w.rim_distance(q), torch.tensor([math.sqrt(2.0), math.sqrt(1.25), 0.0], dtype=F64))
    a = Annulus([0, 0, 1], [0, 0, 1], 1.0, 2.0)
    q = torch.tensor([[1.4, 0.0, 1.0], [1.5, 0.0, 1.5], [0.0, 0.0, 1.0]], dtype=F64)
    torch.testing.assert_close(a.rim_distance(q), torch.tensor([0.4, math.sqrt(0.5), 1.0], dtype=F64))
    p = Polyline([[0, 0], [1, 0], [1, 1]])
    torch.testing.assert_close(p.rim_distance(torch.tensor([[0.5, 0.0], [1.0, 0.6]], dtype=F64)),
                               torch.tensor([0.5, 0.4], dtype=F64))
    assert torch.isinf(Circle([0, 0], 1.0).rim_distance(torch.zeros(3, 2, dtype=F64))).all()
    g = InterfaceUnion([w, a], merge=True)
    torch.testing.assert_close(g.rim_distance(torch.tensor([[1.0, 0.0, 1.0], [1.5, 0.0, 1.0]], dtype=F64)),
                               torch.tensor([0.0, 0.5], dtype=F64))


def test_bolt_hole_group_is_one_component(gen):
    wall = CylinderWall([0.4, 0.8, -0.3], [0, 0, 1], 0.057, 0.087)
    ring = Annulus([0.4, 0.8, -0.2565], [0, 0, 1], 0.057, 0.0888)
    hole = InterfaceUnion([wall, ring], merge=True)
    other = InterfaceUnion([CylinderWall([-0.4, 0.8, -0.3], [0, 0, 1], 0.057, 0.087)], merge=True)
    assert hole.n_components == 1
    both = [hole, other]
    x, nrm, comp = sample_interfaces_with_components(both, 3000, gen, dtype=F64)
    assert x.shape == (3000, 3)
    assert torch.equal(comp, (x[:, 0] < 0).long())
    # counts follow the measures exactly (largest remainder)
    m = torch.tensor([hole.measure(), other.measure()])
    assert abs((comp == 0).sum().item() - 3000 * float(m[0] / m.sum())) <= 1
    d = torch.minimum(hole.distance(x), other.distance(x))
    assert d.max() < 1e-12
    torch.testing.assert_close(nrm.norm(dim=-1), torch.ones(3000, dtype=F64), atol=1e-12, rtol=0)


def test_plateau_polygon_no_normals_and_corners(gen):
    pts = [[0, 0, 0], [1, 0, 0], [1, 0, 1], [1, 1, 1], [1, 1, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]]
    g = Polyline(pts, closed=True)
    assert not g.has_normals and g.measure() == pytest.approx(8.0)
    x, nrm = sample_interfaces([g], 4000, gen, dtype=F64)
    assert g.distance(x).max() < 1e-12 and (nrm == 0).all()
    # every point lies on one of the 8 unit edges: two coordinates in {0, 1}
    onb = ((x == 0) | (x == 1)).sum(-1)
    assert (onb >= 2).all()
    torch.testing.assert_close(interface_corners([g], dtype=F64), torch.tensor(pts, dtype=F64))
    # open polylines expose their end points: the obstacle's two segments give their 4 ends
    ends = interface_corners(obstacle_interfaces(), dtype=F64)
    torch.testing.assert_close(ends, torch.tensor([[-0.9, -0.4], [-0.9, 0.4], [0.9, -0.4], [0.9, 0.4]], dtype=F64))


def test_polyline_left_right_normals(gen):
    sq = Polyline([[0, 0], [1, 0], [1, 1], [0, 1]], closed=True, normal="right")  # ccw: right = outward
    x, nrm = sq.sample(400, gen, dtype=F64)
    expected = torch.where(x[:, 1:2] == 0, torch.tensor([0.0, -1.0], dtype=F64), torch.zeros(2, dtype=F64))
    m = x[:, 1] == 0
    torch.testing.assert_close(nrm[m], expected[m])
    m = x[:, 0] == 1
    torch.testing.assert_close(nrm[m], torch.tensor([[1.0, 0.0]], dtype=F64).expand(int(m.sum()), 2))


def test_transformed_interface(gen):
    seg = Segment([0, -0.5], [0, 0.5], normal=[1.0, 0.0])
    t = TransformedInterface(seg, rotation_matrix(2, 90.0), [1.0, 0.0])
    x, nrm = t.sample(100, gen, dtype=F64)
    assert (x[:, 1].abs() < 1e-12).all() and ((x[:, 0] - 1).abs() <= 0.5 + 1e-12).all()
    torch.testing.assert_close(nrm, torch.tensor([[0.0, 1.0]], dtype=F64).expand(100, 2), atol=1e-12, rtol=0)
    assert t.distance(x).max() < 1e-12


def test_band_near_interfaces_and_inside_box(gen):
    box = Box((-1.0, -0.5), (1.0, 0.5))
    ifs = obstacle_interfaces()
    x = sample_band(ifs, 2000, 0.05, gen, dtype=F64, box=box)
    assert x.shape == (2000, 2) and box.contains(x).all()
    d = torch.minimum(ifs[0].distance(x), ifs[1].distance(x))
    assert (d <= 0.05 + 1e-12).all()
    # denser near the interface than a uniform band: mean distance 0.05 / 3 for a 2D ball offset
    assert d.mean().item() < 0.05 / 2


def test_generator_device_and_dtype(gen):
    box = Box((0.0, 0.0), (1.0, 1.0))
    x = sample_inside(Disk([0.5, 0.5], 0.3), box, 64, gen, device="cpu", dtype=torch.float32)
    assert x.dtype == torch.float32 and x.device.type == "cpu"
    x, nrm = sample_interfaces(obstacle_interfaces(), 10, gen, dtype=torch.float32)
    assert x.dtype == nrm.dtype == torch.float32


@pytest.mark.cuda
def test_cuda_samples(gen):
    box = Box((0.0, 0.0), (1.0, 1.0))
    x = sample_inside(Disk([0.5, 0.5], 0.3), box, 64, gen, device="cuda")
    assert x.device.type == "cuda"
    y, n = sample_interfaces(obstacle_interfaces(), 10, gen, device="cuda")
    assert y.device.type == "cuda" and n.device.type == "cuda"
