"""Exact SDFs of the primitives against closed forms, |grad| = 1, CSG volumes by Monte Carlo."""

import math

import pytest
import torch

from ginn.fields import as_field, evaluate
from ginn.geometry import (
    AABox,
    Ball,
    Box,
    Cuboid,
    Cylinder,
    Difference,
    Disk,
    Extrusion,
    HalfSpace,
    Intersection,
    Polygon,
    Rectangle,
    Sphere,
    Transformed,
    Union,
    rotation_matrix,
    sample_box,
)

F64 = torch.float64


def pts(gen, n, lo, hi):
    lo, hi = torch.tensor(lo, dtype=F64), torch.tensor(hi, dtype=F64)
    return lo + torch.rand(n, len(lo), generator=gen, dtype=F64) * (hi - lo)


def box_reference(x, lo, hi):
    """Distance to an axis-aligned box by cases (outside: to the clamped point; inside: nearest face)."""
    lo, hi = torch.tensor(lo, dtype=F64), torch.tensor(hi, dtype=F64)
    inside = ((x >= lo) & (x <= hi)).all(-1)
    out = (x - torch.minimum(torch.maximum(x, lo), hi)).norm(dim=-1)
    depth = torch.minimum(x - lo, hi - x).min(dim=-1).values
    return torch.where(inside, -depth, out)


def grad_norm(region, x):
    v = evaluate(as_field(region.sdf), x, create_graph=False)
    return v.grad.norm(dim=-1)


def test_box_2d_3d_exact(gen):
    for lo, hi in [([-0.9, -0.4], [0.9, 0.4]), ([-1.0, 0.0, 0.5], [0.5, 2.0, 1.0])]:
        d = len(lo)
        x = pts(gen, 4000, [-2.0] * d, [2.5] * d)
        r = Rectangle(lo, hi) if d == 2 else Cuboid(lo, hi)
        torch.testing.assert_close(r.sdf(x), box_reference(x, lo, hi), atol=1e-12, rtol=0)
        # |grad| = 1 outside (no medial axis) and inside away from the diagonals
        s = r.sdf(x)
        lo_t, hi_t = torch.tensor(lo, dtype=F64), torch.tensor(hi, dtype=F64)
        faces = torch.cat([x - lo_t, hi_t - x], dim=-1).sort(dim=-1).values
        ok = (s > 1e-3) | ((s < -1e-3) & (faces[:, 1] - faces[:, 0] > 1e-3))
        assert ok.sum() > 1000
        torch.testing.assert_close(grad_norm(r, x[ok]), torch.ones(int(ok.sum()), dtype=F64), atol=1e-9, rtol=0)


def test_ball_disk_sphere_exact(gen):
    for cls, c in [(Disk, [0.2, -0.1]), (Sphere, [0.1, 0.2, -0.3])]:
        x = pts(gen, 3000, [-1.5] * len(c), [1.5] * len(c))
        b = cls(c, 0.4)
        ref = (x - torch.tensor(c, dtype=F64)).norm(dim=-1) - 0.4
        torch.testing.assert_close(b.sdf(x), ref, atol=1e-12, rtol=0)
        far = (x - torch.tensor(c, dtype=F64)).norm(dim=-1) > 1e-2
        torch.testing.assert_close(grad_norm(b, x[far]), torch.ones(int(far.sum()), dtype=F64), atol=1e-9, rtol=0)
    assert Ball([0, 0, 0, 0], 1.0).volume() == pytest.approx(math.pi**2 / 2)
    with pytest.raises(ValueError):
        Disk([0, 0], -1.0)


def test_halfspace_exact(gen):
    h = HalfSpace([0.1, 0.2, 0.3], [1.0, 2.0, 2.0])
    x = pts(gen, 1000, [-1] * 3, [1] * 3)
    ref = ((x - torch.tensor([0.1, 0.2, 0.3], dtype=F64)) @ torch.tensor([1.0, 2.0, 2.0], dtype=F64)) / 3.0
    torch.testing.assert_close(h.sdf(x), ref, atol=1e-12, rtol=0)
    torch.testing.assert_close(grad_norm(h, x), torch.ones(1000, dtype=F64), atol=1e-12, rtol=0)


def test_polygon_square_equals_box_and_orientation(gen):
    x = pts(gen, 3000, [-2, -2], [2, 2])
    ccw = Polygon([[-1, -0.5], [1, -0.5], [1, 0.5], [-1, 0.5]])
    cw = Polygon([[-1, -0.5], [-1, 0.5], [1, 0.5], [1, -0.5]])
    ref = box_reference(x, [-1, -0.5], [1, 0.5])
    torch.testing.assert_close(ccw.sdf(x), ref, atol=1e-12, rtol=0)
    torch.testing.assert_close(cw.sdf(x), ref, atol=1e-12, rtol=0)
    assert ccw.area() == pytest.approx(2.0)


def test_polygon_triangle_incenter_and_nonconvex(gen):
    # right triangle 3-4-5: inradius (a + b - c) / 2 = 1 at the incenter (1, 1)
    tri = Polygon([[0, 0], [3, 0], [0, 4]])
    assert float(tri.sdf(torch.tensor([[1.0, 1.0]], dtype=F64))) == pytest.approx(-1.0, abs=1e-12)
    # outside: distance to the nearest vertex / edge
    q = torch.tensor([[-1.0, -1.0], [5.0, 0.0], [1.0, -2.0]], dtype=F64)
    torch.testing.assert_close(tri.sdf(q), torch.tensor([math.sqrt(2), 2.0, 2.0], dtype=F64), atol=1e-12, rtol=0)
    # L shape = union of two rectangles; the union's SDF is exact outside
    L = Polygon([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]])
    A, B = Rectangle([0, 0], [2, 1]), Rectangle([0, 0], [1, 2])
    x = pts(gen, 4000, [-1, -1], [3, 3])
    s = L.sdf(x)
    outside = torch.minimum(A.sdf(x), B.sdf(x)) > 0
    torch.testing.assert_close(s[outside], torch.minimum(A.sdf(x), B.sdf(x))[outside], atol=1e-12, rtol=0)
    assert ((s <= 0) == (A.contains(x) | B.contains(x))).all()
    # inside points by hand: (0.5, 0.5) is 0.5 from the edges x=0, y=0; (1.5, 0.8) is 0.2 from y=1
    q = torch.tensor([[0.5, 0.5], [1.5, 0.8], [0.9, 0.9]], dtype=F64)
    torch.testing.assert_close(L.sdf(q), torch.tensor([-0.5, -0.2, -math.sqrt(0.02)], dtype=F64), atol=1e-12, rtol=0)
    far = s.abs() > 1e-3
    g = grad_norm(L, x[far & (s > 0)])
    torch.testing.assert_close(g, torch.ones_like(g), atol=1e-9, rtol=0)


def cylinder_reference(x, c, a, r, length):
    """Capped cylinder distance by cases in (rho, t) coordinates."""
    c, a = torch.tensor(c, dtype=F64), torch.tensor(a, dtype=F64)
    a = a / a.norm()
    p = x - c
    t = p @ a
    rho = (p - t[:, None] * a).norm(dim=-1)
    h = length / 2
    at = t.abs()
    out = torch.empty_like(t)
    m1 = (rho <= r) & (at <= h)
    out[m1] = -torch.minimum(r - rho[m1], h - at[m1])
    m2 = (rho <= r) & (at > h)
    out[m2] = at[m2] - h
    m3 = (rho > r) & (at <= h)
    out[m3] = rho[m3] - r
    m4 = (rho > r) & (at > h)
    out[m4] = torch.sqrt((rho[m4] - r) ** 2 + (at[m4] - h) ** 2)
    return out


def test_cylinder_arbitrary_axis_exact(gen):
    c, a, r, length = [0.1, -0.2, 0.3], [1.0, 2.0, -0.5], 0.3, 0.8
    cyl = Cylinder(c, a, r, length)
    x = pts(gen, 5000, [-1] * 3, [1.2] * 3)
    torch.testing.assert_close(cyl.sdf(x), cylinder_reference(x, c, a, r, length), atol=1e-12, rtol=0)
    s = cyl.sdf(x)
    g = grad_norm(cyl, x[s > 1e-3])
    torch.testing.assert_close(g, torch.ones_like(g), atol=1e-9, rtol=0)
    lo, hi = cyl.bounds()
    assert cyl.contains(x).sum() > 0 and ((x[cyl.contains(x)] >= lo) & (x[cyl.contains(x)] <= hi)).all()


def test_extrusion_exact(gen):
    sq = Extrusion([[-1, -0.5], [1, -0.5], [1, 0.5], [-1, 0.5]], -0.2, 0.6)
    x = pts(gen, 4000, [-2] * 3, [2] * 3)
    torch.testing.assert_close(sq.sdf(x), box_reference(x, [-1, -0.5, -0.2], [1, 0.5, 0.6]), atol=1e-12, rtol=0)
    tri = Extrusion([[0, 0], [3, 0], [0, 4]], 0.0, 10.0)
    # incenter of the triangle at mid-height: 1 from the three side walls, 5 from the caps
    assert float(tri.sdf(torch.tensor([[1.0, 1.0, 5.0]], dtype=F64))) == pytest.approx(-1.0, abs=1e-12)
    # above the cap, over the interior: distance to the cap
    assert float(tri.sdf(torch.tensor([[1.0, 1.0, 12.0]], dtype=F64))) == pytest.approx(2.0, abs=1e-12)
    assert tri.volume() == pytest.approx(60.0)


def test_rigid_transform_exact(gen):
    R = rotation_matrix(2, 30.0)
    t = torch.tensor([0.3, -0.2], dtype=F64)
    r = Transformed(Rectangle([-0.5, -0.25], [0.5, 0.25]), R, t)
    x = pts(gen, 3000, [-1.5, -1.5], [1.5, 1.5])
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    d = x - t
    local = torch.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], dim=-1)
    torch.testing.assert_close(r.sdf(x), box_reference(local, [-0.5, -0.25], [0.5, 0.25]), atol=1e-12, rtol=0)
    # 3D: rotating a cylinder along z to lie along x equals the cylinder along x
    R3 = rotation_matrix(3, 90.0, [0, 1, 0])
    torch.testing.assert_close(R3 @ torch.tensor([0.0, 0.0, 1.0], dtype=F64), torch.tensor([1.0, 0.0, 0.0], dtype=F64), atol=1e-12, rtol=0)
    a = Transformed(Cylinder([0, 0, 0], [0, 0, 1], 0.3, 1.0), R3, [0.1, 0.2, 0.3])
    b = Cylinder([0.1, 0.2, 0.3], [1, 0, 0], 0.3, 1.0)
    x3 = pts(gen, 2000, [-1] * 3, [1] * 3)
    torch.testing.assert_close(a.sdf(x3), b.sdf(x3), atol=1e-12, rtol=0)
    with pytest.raises(ValueError):
        Transformed(Rectangle([0, 0], [1, 1]), torch.tensor([[1.0, 0.0], [0.0, -1.0]]))  # a reflection


def mc_volume(region, box, n, gen):
    x = sample_box(box, n, gen, dtype=F64)
    return region.contains(x).double().mean().item() * box.volume()


def test_csg_areas_and_volumes_by_monte_carlo(gen):
    # obstacle design region: rectangle minus disk
    E = Difference(Rectangle([-0.9, -0.4], [0.9, 0.4]), Disk([0, 0], 0.1))
    area = 1.8 * 0.8 - math.pi * 0.01
    assert mc_volume(E, Box((-1, -0.5), (1, 0.5)), 400_000, gen) == pytest.approx(area, rel=0.01)
    # union of two overlapping unit-radius spheres at distance 1: 2 * (4/3 pi) - lens (5/12 pi)
    U = Union(Sphere([0, 0, 0], 1.0), Sphere([1, 0, 0], 1.0))
    vol = 2 * 4 / 3 * math.pi - 5 * math.pi / 12
    assert mc_volume(U, Box((-1, -1, -1), (2, 1, 1)), 300_000, gen) == pytest.approx(vol, rel=0.01)
    # Steinmetz solid: two perpendicular cylinders of radius 0.5 (long enough), 16 r^3 / 3
    S = Intersection(Cylinder([0, 0, 0], [1, 0, 0], 0.5, 2.0), Cylinder([0, 0, 0], [0, 1, 0], 0.5, 2.0))
    assert mc_volume(S, Box((-0.5,) * 3, (0.5,) * 3), 300_000, gen) == pytest.approx(16 * 0.125 / 3, rel=0.01)
    # box minus a sphere inside it
    Dd = Difference(Cuboid([-1, -1, -1], [1, 1, 1]), Sphere([0, 0, 0], 0.8))
    assert mc_volume(Dd, Box((-1,) * 3, (1,) * 3), 300_000, gen) == pytest.approx(8 - 4 / 3 * math.pi * 0.512, rel=0.01)


def test_csg_sign_exact_and_magnitude_a_bound(gen):
    """CSG keeps the sign exact and |sdf| <= the true distance (checked against dense boundary samples)."""
    E = Difference(Rectangle([-0.9, -0.4], [0.9, 0.4]), Disk([0, 0], 0.1))
    x = pts(gen, 500, [-1, -0.5], [1, 0.5])
    # dense boundary of E: rectangle edges and the circle
    t = torch.linspace(0, 1, 20001, dtype=F64)
    rect = torch.cat([
        torch.stack([-0.9 + 1.8 * t, torch.full_like(t, -0.4)], -1), torch.stack([-0.9 + 1.8 * t, torch.full_like(t, 0.4)], -1),
        torch.stack([torch.full_like(t, -0.9), -0.4 + 0.8 * t], -1), torch.stack([torch.full_like(t, 0.9), -0.4 + 0.8 * t], -1),
        0.1 * torch.stack([torch.cos(2 * math.pi * t), torch.sin(2 * math.pi * t)], -1),
    ])
    true = torch.cdist(x, rect).min(dim=-1).values
    s = E.sdf(x)
    inside = (box_reference(x, [-0.9, -0.4], [0.9, 0.4]) <= 0) & (x.norm(dim=-1) > 0.1)
    assert ((s <= 0) == inside).all()
    assert (s.abs() <= true + 1e-4).all()
    # here the difference is exact: max(rect, -disk) with disjoint features
    torch.testing.assert_close(s.abs(), true, atol=2e-4, rtol=0)


def test_bounds_contain_the_region(gen):
    shapes = [
        (Union(Disk([0.5, 0], 0.2), Rectangle([-0.5, -0.1], [0, 0.3])), Box((-1, -1), (1, 1))),
        (Transformed(Cuboid([-0.2, -0.1, -0.3], [0.2, 0.1, 0.3]), rotation_matrix(3, 40, [1, 1, 0]), [0.1, 0, 0]), Box((-1,) * 3, (1,) * 3)),
        (Extrusion([[0, 0], [0.5, 0], [0, 0.5]], -0.2, 0.1), Box((-1,) * 3, (1,) * 3)),
    ]
    for region, box in shapes:
        x = sample_box(box, 20000, gen, dtype=F64)
        inside = x[region.contains(x)]
        lo, hi = region.bounds()
        assert inside.shape[0] > 50
        assert ((inside >= lo - 1e-12) & (inside <= hi + 1e-12)).all()


def test_aabox_validation():
    with pytest.raises(ValueError):
        AABox([0, 0], [0, 1])
    with pytest.raises(ValueError):
        Polygon([[0, 0], [1, 1], [2, 2]])  # zero area
