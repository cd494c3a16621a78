"""Appendix B.1 metrics against exact answers (exact SDFs in float64)."""

import math

import numpy as np
import pytest
import torch

from _shapes import Circle, Disk, Rect, VerticalSegments, union
from ginn.eval.metrics import METRIC_NAMES, diversity_from_matrix, diversity_mean, extract_shape
from ginn.eval.shapes import evaluate_shapes, format_comparison_table, format_table
from ginn.extract.grid import make_grid
from ginn.fields import as_field
from ginn.geometry import csg
from ginn.geometry.base import Box
from ginn.problems.problem import Problem

BOX2 = Box((-1.0, -1.0), (1.0, 1.0))
E2 = Rect((-0.9, -0.9), (0.9, 0.9))  # vol(E) = 3.24


def problem(**kw):
    kw.setdefault("design_region", E2)
    return Problem("test", BOX2, **kw)


def test_disk_inside_design_region():
    r = evaluate_shapes(as_field(Disk((0.1, 0.0), 0.4).sdf), None, problem(), 128).to_json()
    s = r["shapes"][0]
    assert s["b0"] == 1 and s["b0_in_design_region"] == 1
    assert s["volume_outside"] == 0.0
    assert s["boundary_overlap"] == 0.0
    assert s["disconnected_volume"] == 0.0 and s["disconnected_volume_in_design_region"] == 0.0
    assert s["interface_cd1"] is None and s["connected_interfaces_share"] is None
    assert r["n_shapes"] == 1 and r["diversity_mean"] is None
    assert set(s) == set(METRIC_NAMES) and set(r["mean"]) == set(METRIC_NAMES)


def test_two_disks_b0_and_disconnected_volume():
    r1, r2 = 0.3, 0.15
    f = union(Disk((-0.4, 0.0), r1).sdf, Disk((0.5, 0.3), r2).sdf)
    res = 256
    s = evaluate_shapes(f, None, problem(), res).to_json()["shapes"][0]
    assert s["b0"] == 2 and s["b0_in_design_region"] == 2
    exact = math.pi * r2**2 / 3.24
    # Grid tolerance: only nodes whose (h x h) quadrature cell meets the circle can be miscounted,
    # and those cells lie in an annulus of half-width h/sqrt(2) around it: |error| <= 2 pi r2 sqrt(2) h.
    h = 2 / res
    tol = 2 * math.pi * r2 * math.sqrt(2) * h / 3.24
    assert abs(s["disconnected_volume"] - exact) <= tol
    assert abs(s["disconnected_volume"] - exact) / exact < 0.01  # what is actually measured
    assert s["disconnected_volume_in_design_region"] == pytest.approx(s["disconnected_volume"])


def test_volume_outside_of_a_disk_crossing_the_design_region():
    # E = the left half x <= 0; a disk of radius 0.4 at the origin: half of it is outside E.
    P = problem(design_region=Rect((-1.0, -1.0), (0.0, 1.0)))
    s = evaluate_shapes(as_field(Disk((0.0, 0.0), 0.4).sdf), None, P, 256).to_json()["shapes"][0]
    assert s["volume_outside"] == pytest.approx((math.pi * 0.16 / 2) / 2.0, rel=0.01)
    assert s["b0_in_design_region"] == 1


def test_interface_cd1_concentric_circles():
    r1, r2 = 0.5, 0.3
    s = evaluate_shapes(as_field(Disk((0.0, 0.0), r1).sdf), None, problem(interfaces=(Circle(r2),)), 256).to_json()["shapes"][0]
    assert s["interface_cd1"] == pytest.approx(abs(r1 - r2), abs=1e-3)
    s = evaluate_shapes(as_field(Disk((0.0, 0.0), r1).sdf), None, problem(interfaces=(Circle(r1),)), 256).to_json()["shapes"][0]
    assert s["interface_cd1"] < 1e-4


def test_the_worst_met_interface_is_reported_apart():
    """A disk of radius 0.5 with interface circles of 0.5 and 0.4: the first is met, the second is
    0.1 away everywhere. CD1 weighs them by length (5 : 4), sqrt(4/9) 0.1; the worst-met one is 0.1."""
    P = problem(interfaces=(Circle(0.5), Circle(0.4)))
    s = evaluate_shapes(as_field(Disk((0.0, 0.0), 0.5).sdf), None, P, 256).to_json()["shapes"][0]
    assert s["interface_cd1_worst"] == pytest.approx(0.1, abs=1e-3)
    assert s["interface_cd1"] == pytest.approx(math.sqrt(4 / 9) * 0.1, abs=2e-3)


def test_interface_cd1_is_sub_cell_with_the_field():
    # A disk of radius 0.3 on a 16-cell grid (h = 0.125): the contour cuts the circle's arcs, so the
    # contour distance of samples on the circle is ~h^2 / (8 r) ~ 6e-3 on average; Newton
    # projections along the field's gradient land on the circle itself (also for a field that is
    # not an SDF, |x|^2 - r^2), and samples at radius 0.45 lie 0.15 from it. A projection stops
    # after a step shorter than 1 % of a cell, which leaves a residual of the order of that step's
    # square over the radius: (0.01 h)^2 / r ~ 5e-6.
    from ginn.eval.metrics import interface_cd1, projected_distances

    r = 0.3
    grid = make_grid(BOX2, 16)
    settled = (0.01 * 0.125) ** 2 / r
    t = np.linspace(0.0, 2 * np.pi, 400, endpoint=False)
    ring = np.stack([np.cos(t), np.sin(t)], axis=1)
    for f in (as_field(Disk((0.0, 0.0), r).sdf), as_field(lambda x, z=None: (x * x).sum(-1) - r * r)):
        shape = extract_shape(f, None, grid)
        coarse = interface_cd1(shape.boundary, r * ring)
        assert coarse > 1e-3
        assert interface_cd1(shape.boundary, r * ring, f, None, grid) < 1e-6
        assert projected_distances(f, None, 0.45 * ring, grid) == pytest.approx(np.full(400, 0.15), abs=settled)
        assert interface_cd1(shape.boundary, 0.45 * ring, f, None, grid) == pytest.approx(0.15, abs=settled)
    # a field without a zero level set: no projection counts, the contour distance stays
    empty = as_field(lambda x, z=None: (x * x).sum(-1) + 1.0)
    assert np.isinf(projected_distances(empty, None, r * ring, grid)).all()


def test_boundary_overlap_strip_crossing_a_disk_design_region():
    # E = disk of radius R; Omega = the strip |y| <= w: Omega cap dE = two arcs of angle 2 asin(w/R).
    R, w = 0.8, 0.2
    P = Problem("t", BOX2, design_region=Disk((0.0, 0.0), R))
    strip = lambda x, z=None: x[:, 1].abs() - w
    s = evaluate_shapes(strip, None, P, 256).to_json()["shapes"][0]
    exact = 4 * math.asin(w / R) / (2 * math.pi)
    assert s["boundary_overlap"] == pytest.approx(exact, abs=0.01)


def test_boundary_overlap_strip_crossing_a_rectangle_design_region():
    # E = [-0.9, 0.9] x [-0.4, 0.4] (perimeter 5.2); the strip |y| <= 0.1 covers 2 x 0.2 of it.
    P = Problem("t", Box((-1.0, -0.5), (1.0, 0.5)), design_region=Rect((-0.9, -0.4), (0.9, 0.4)))
    strip = lambda x, z=None: x[:, 1].abs() - 0.1
    s = evaluate_shapes(strip, None, P, 256).to_json()["shapes"][0]
    assert s["boundary_overlap"] == pytest.approx(0.4 / 5.2, abs=0.005)
    # and the volume outside: the strip outside E is 2 x (0.1 x 0.2) of vol(X \ E) = 2 - 1.44
    # node counting moves each straight edge of the two 0.1 x 0.2 pieces by at most h / 2
    h = 1 / 128
    assert s["volume_outside"] == pytest.approx(0.04 / 0.56, abs=2 * 0.6 * (h / 2) / 0.56)


def test_boundary_overlap_counts_a_shape_boundary_coinciding_with_dE():
    # Omega = [-0.9, 0.9] x [-0.1, 0.1] ends exactly on the sides x = +-0.9 of E (perimeter 5.2).
    P = Problem("t", Box((-1.0, -0.5), (1.0, 0.5)), design_region=Rect((-0.9, -0.4), (0.9, 0.4)))
    bar = as_field(Rect((-0.9, -0.1), (0.9, 0.1)).sdf)
    res = 256
    h = 2 / res
    s = evaluate_shapes(bar, None, P, res).to_json()["shapes"][0]
    # the tolerance of one spacing can add h at each of the 4 ends of the two covered pieces
    assert 0.4 / 5.2 - 0.003 <= s["boundary_overlap"] <= (0.4 + 4 * h) / 5.2 + 0.003
    assert s["volume_outside"] == 0.0


def test_boundary_overlap_independent_of_where_dE_lies_between_nodes():
    # h = 1/128; the sides x = +-a lie on grid nodes, the sides y = +-b halfway between nodes:
    # the hat weights give both the same weight per length (a hard band |sdf| < h would not).
    from ginn.eval.metrics import boundary_overlap, extract_shape, prepare_context

    a, b = 1 - 12 / 128, 1 - 51.5 / 128
    P = Problem("t", BOX2, design_region=Rect((-a, -b), (a, b)))
    strip = lambda x, z=None: x[:, 1].abs() - 0.2  # covers 2 x 0.4 of the sides x = +-a
    ctx = prepare_context(P, 256)
    sh = extract_shape(strip, None, ctx.grid)
    h, perimeter = 1 / 128, 4 * (a + b)
    got = boundary_overlap(sh.values, ctx.grid, ctx.design_boundary_points, weights=ctx.design_boundary_weights)
    assert 0.8 / perimeter - 0.003 <= got <= (0.8 + 4 * h) / perimeter + 0.003
    unweighted = boundary_overlap(sh.values, ctx.grid, ctx.design_boundary_points)
    assert abs(unweighted - 0.8 / perimeter) > 0.02  # what the weights correct


def test_connected_interfaces_share():
    itf = VerticalSegments([-0.5, 0.5], 0.2)
    P = problem(interfaces=(itf,))
    bar = as_field(Rect((-0.5, -0.3), (0.5, 0.3)).sdf)  # both segments on its boundary
    s = evaluate_shapes(bar, None, P, 128).to_json()["shapes"][0]
    assert s["connected_interfaces_share"] == 1.0
    assert s["interface_cd1"] < 1e-3
    two = union(Disk((-0.5, 0.0), 0.3).sdf, Disk((0.55, 0.0), 0.1).sdf)  # one interface each
    s = evaluate_shapes(two, None, P, 128).to_json()["shapes"][0]
    assert s["b0"] == 2 and s["connected_interfaces_share"] == 0.5
    # a segment within eps = 0.01 of a component counts; one 0.05 away does not
    near = union(Rect((-0.505, -0.3), (0.495, 0.3)).sdf)
    assert evaluate_shapes(near, None, P, 256).to_json()["shapes"][0]["connected_interfaces_share"] == 1.0
    far = union(Rect((-0.5, -0.3), (0.45, 0.3)).sdf)
    assert evaluate_shapes(far, None, P, 256).to_json()["shapes"][0]["connected_interfaces_share"] == 0.5


def test_surface_strain_sphere_and_circle():
    r = 0.5
    P3 = Problem("t", Box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)))
    s = evaluate_shapes(as_field(Disk((0.0, 0.0, 0.0), r).sdf), None, P3, 32).to_json()["shapes"][0]
    assert s["surface_strain"] == pytest.approx(2 / r**2, rel=1e-6)
    assert s["b0"] == 1 and s["volume_outside"] == 0.0
    s = evaluate_shapes(as_field(Disk((0.0, 0.0), 0.25).sdf), None, problem(), 64).to_json()["shapes"][0]
    assert s["surface_strain"] == pytest.approx(1 / 0.25**2, rel=1e-6)
    # tiny circles are clipped at 1000
    s = evaluate_shapes(as_field(Disk((0.0, 0.0), 0.02).sdf), None, problem(), 256).to_json()["shapes"][0]
    assert s["surface_strain"] == 1000.0


def radial_family(radii):
    """Concentric circles: shape i is the disk of radius radii[i] (latent z = i)."""
    rr = torch.tensor(radii, dtype=torch.float64)

    def f(x, z):
        return x.norm(dim=-1) - rr[z[:, 0].round().long()]

    return f


def test_diversity_identical_shapes_is_zero():
    f = radial_family([0.4, 0.4, 0.4])
    Z = torch.arange(3, dtype=torch.float64)[:, None]
    r = evaluate_shapes(f, Z, problem(), 128).to_json()
    assert r["n_shapes"] == 3 and len(r["shapes"]) == 3
    assert r["diversity_mean"] == pytest.approx(0.0, abs=1e-9)


def test_diversity_concentric_circles_closed_form():
    radii = [0.2, 0.35, 0.6]
    f = radial_family(radii)
    Z = torch.arange(3, dtype=torch.float64)[:, None]
    r = evaluate_shapes(f, Z, problem(), 256).to_json()
    # CD1 between concentric circles is |ri - rj| both ways, so CD2 = sqrt(2) |ri - rj|.
    D = np.sqrt(2) * np.abs(np.subtract.outer(radii, radii))
    exact = np.mean(np.sqrt(D.sum(1) / 2)) ** 2
    assert r["diversity_mean"] == pytest.approx(exact, abs=1e-3)
    assert diversity_from_matrix(D) == pytest.approx(exact)
    # two shapes: delta = CD2
    assert diversity_from_matrix(D[:2, :2]) == pytest.approx(np.sqrt(2) * 0.15)
    # the per-shape means are averages of the per-shape values
    assert r["mean"]["surface_strain"] == pytest.approx(np.mean([1 / q**2 for q in radii]), rel=1e-6)


def test_diversity_mean_function_and_single_shape():
    g = make_grid(BOX2, 64)
    b1 = extract_shape(as_field(Disk((0.0, 0.0), 0.3).sdf), None, g).boundary
    b2 = extract_shape(as_field(Disk((0.0, 0.0), 0.5).sdf), None, g).boundary
    assert diversity_mean([b1]) is None
    assert diversity_mean([b1, b2]) == pytest.approx(np.sqrt(2) * 0.2, abs=2e-3)


def test_tables():
    ev = evaluate_shapes(as_field(Disk((0.0, 0.0), 0.4).sdf), None, problem(interfaces=(Circle(0.4),)), 64)
    r, t = ev.to_json(), ev.text()
    assert format_table(r, ev.feasibility.text()) == t
    assert "CD1" in t and t.count("\n") == 3 + len(METRIC_NAMES) + 1 + 2
    assert t.splitlines()[-1] == "feasible shapes: 1 of 1"  # the disk through its own interface
    c = format_comparison_table([r, r], ["a", "b"])
    assert c.splitlines()[0] == "| metric | a | b |"
    assert len(c.splitlines()) == 3 + len(METRIC_NAMES) + 1
    with pytest.raises(ValueError):
        format_comparison_table([r], ["a", "b"])


def test_empty_shape_gives_strict_json():
    import json

    f = lambda x, z: x.norm(dim=-1) - z[:, 0]  # radius z; z = -1: empty
    Z = torch.tensor([[-1.0], [0.3], [0.5]], dtype=torch.float64)
    r = evaluate_shapes(f, Z, problem(interfaces=(Circle(0.3),)), 64).to_json()
    s0 = r["shapes"][0]
    assert s0["b0"] == 0 and s0["interface_cd1"] is None and s0["surface_strain"] is None
    json.dumps(r, allow_nan=False)
    assert r["mean"]["b0"] == pytest.approx(2 / 3)
    assert r["diversity_mean"] == pytest.approx(np.sqrt(2) * 0.2, abs=2e-3)  # over the two disks


class RectMinusDisk(Rect):
    """[-0.9, 0.9] x [-0.4, 0.4] minus the disk of radius 0.1 at the origin (the obstacle's E)."""

    def __init__(self):
        super().__init__((-0.9, -0.4), (0.9, 0.4))

    def sdf(self, x):
        return torch.maximum(super().sdf(x), 0.1 - x.norm(dim=-1))


def test_components_in_design_region_split_by_an_obstacle():
    P = Problem("t", Box((-1.0, -0.5), (1.0, 0.5)), design_region=RectMinusDisk())
    strip = as_field(Rect((-0.9, -0.08), (0.9, 0.08)).sdf)  # runs through the obstacle
    s = evaluate_shapes(strip, None, P, 512).to_json()["shapes"][0]
    assert s["b0"] == 1 and s["b0_in_design_region"] == 2
    assert s["disconnected_volume"] == 0.0
    cut = 2 * (0.08 * 0.06 + 0.01 * math.asin(0.8))  # strip cap disk
    vol_E = 1.44 - math.pi * 0.01
    assert s["disconnected_volume_in_design_region"] == pytest.approx((0.288 - cut) / 2 / vol_E, rel=0.02)
    assert s["volume_outside"] == pytest.approx(cut / (2.0 - vol_E), rel=0.03)


@pytest.mark.parametrize("res", [256, 512, 1024])
def test_volume_outside_off_interfaces_ignores_the_interface_tolerance(res):
    # The obstacle's layout: interfaces x = +-0.9 (|y| <= 0.4) on dE, tolerance h = 0.005. The bar
    # overshoots both interfaces by 0.003 < h, and a 0.2 x 0.05 bump leaves E at the top.
    X = Box((-1.0, -0.5), (1.0, 0.5))
    P = Problem("t", X, design_region=Rect((-0.9, -0.4), (0.9, 0.4)), interfaces=(VerticalSegments([-0.9, 0.9], 0.4),))
    f = union(Rect((-0.903, -0.2), (0.903, 0.2)).sdf, Rect((-0.1, 0.3), (0.1, 0.45)).sdf)
    s = evaluate_shapes(f, None, P, res).to_json()["shapes"][0]
    vol_out = 2.0 - 1.44
    h = 2.0 / res
    # node counting moves each of the bump's three outside edges by at most h / 2
    assert s["volume_outside_off_interfaces"] == pytest.approx(0.01 / vol_out, abs=0.3 * h / vol_out)
    # volume_outside also counts the node columns between x = 0.9 and 0.903: none at 256 cells
    # (nodes at 0.8984, 0.9062), one at 512 (0.9023), two at 1024 (0.9004, 0.9023)
    columns = {256: 0, 512: 1, 1024: 2}[res]
    sliver = s["volume_outside"] - s["volume_outside_off_interfaces"]
    assert sliver == pytest.approx(2 * columns * 0.4 * h / vol_out, rel=0.05, abs=1e-12)


def test_holes_of_the_shape_inside_the_design_region():
    # E = the square minus a central disk (an obstacle); an annulus around it has one hole there,
    # the same annulus with a gap none; a disk with two holes of its own has two
    hole = Disk((0.0, 0.0), 0.2)
    P = problem(design_region=csg.Difference(E2, hole))
    ring = lambda x, z=None: torch.maximum(x.norm(dim=1) - 0.6, 0.1 - x.norm(dim=1))
    s = evaluate_shapes(ring, None, P, 128).to_json()["shapes"][0]
    assert (s["b0_in_design_region"], s["b1_in_design_region"], s["b2_in_design_region"]) == (1, 1, None)
    cut = lambda x, z=None: torch.maximum(ring(x), torch.minimum(0.05 - x[:, 1].abs(), x[:, 0]))  # open on the right
    s = evaluate_shapes(cut, None, P, 128).to_json()["shapes"][0]
    assert (s["b0_in_design_region"], s["b1_in_design_region"]) == (1, 0)
    two = lambda x, z=None: torch.maximum(torch.maximum(x.norm(dim=1) - 0.8, 0.1 - (x - torch.tensor([0.5, 0.0], dtype=x.dtype)).norm(dim=1)),
                                          0.1 - (x + torch.tensor([0.5, 0.0], dtype=x.dtype)).norm(dim=1))
    s = evaluate_shapes(two, None, problem(), 128).to_json()["shapes"][0]
    assert (s["b0_in_design_region"], s["b1_in_design_region"]) == (1, 2)
