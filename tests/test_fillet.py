"""The smallest radius of curvature: curvatures of known level sets, the share of a rounded
rectangle's boundary sharper than a radius, the loss on a disk, the spec and the verdict."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from _shapes import DiskField
from ginn.constraints import MinRadius, MinRadiusVerdict
from ginn.errors import SpecError
from ginn.extract.boundary import extract_boundary
from ginn.extract.curvature import boundary_curvatures, largest_curvature
from ginn.extract.grid import Grid
from ginn.fields import as_field, evaluate
from ginn.problems import CurvatureBound, validate_spec
from ginn.tasks import make_task


def _disk(r, c=(0.0, 0.0)):
    return as_field(lambda x: (x - torch.tensor(c, dtype=x.dtype)).norm(dim=-1) - r)


def _rounded_rectangle(a, b, rho):
    """The SDF of the rectangle [-a, a] x [-b, b] with corners rounded to radius rho."""
    def f(x):
        q = x.abs() - torch.tensor([a - rho, b - rho], dtype=x.dtype)
        return q.clamp_min(0).norm(dim=-1) + q.max(-1).values.clamp_max(0) - rho
    return as_field(f)


def _boundary(field, d, cells):
    g = Grid(np.full(d, -1.0), np.full(d, 1.0), (cells,) * d)
    x = torch.as_tensor(g.points(), dtype=torch.float64)
    return extract_boundary(field(x).reshape(g.shape).numpy().astype(np.float32), g), g


def test_a_circle_a_sphere_and_a_cylinder_have_curvature_one_over_their_radius():
    x2 = torch.tensor([[0.3, 0.0], [0.0, -0.3], [0.2121320343, 0.2121320343]], dtype=torch.float64)
    v = evaluate(_disk(0.3), x2, hessian_at=True, create_graph=False)
    assert largest_curvature(v.hessian_grad, v.hessian).tolist() == pytest.approx([1 / 0.3] * 3, rel=1e-9)
    sphere = as_field(lambda x: x.norm(dim=-1) - 0.5)
    x3 = torch.tensor([[0.5, 0.0, 0.0], [0.0, 0.3, 0.4]], dtype=torch.float64)
    v = evaluate(sphere, x3, hessian_at=True, create_graph=False)
    assert largest_curvature(v.hessian_grad, v.hessian).tolist() == pytest.approx([2.0, 2.0], rel=1e-6)
    cylinder = as_field(lambda x: x[:, :2].norm(dim=-1) - 0.25)  # curvatures 0 and 1 / 0.25
    v = evaluate(cylinder, torch.tensor([[0.25, 0.0, 0.7]], dtype=torch.float64), hessian_at=True, create_graph=False)
    assert float(largest_curvature(v.hessian_grad, v.hessian)[0]) == pytest.approx(4.0, rel=1e-6)


def test_points_on_an_extracted_circle_read_its_curvature():
    b, g = _boundary(_disk(0.4), 2, 256)
    x, k = boundary_curvatures(_disk(0.4), None, b, 512, np.random.default_rng(0), step_cap=float(g.spacing.max()))
    assert x.shape == (512, 2) and np.abs(np.linalg.norm(x, axis=1) - 0.4).max() < 1e-6
    assert k == pytest.approx(np.full(512, 2.5), rel=1e-6)


SPEC = {"name": "plate", "geometry": {
    "dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
    "interfaces": [{"type": "segment", "a": [-0.95, 0.9], "b": [-0.9, 0.9], "normal": [0, 1]}]}}


def _problem(min_radius):
    return validate_spec({**SPEC, "tolerances": {"min_radius": min_radius}})


@pytest.mark.parametrize("radius", [0.05, 0.2])
def test_share_of_a_rounded_rectangle_sharper_than_a_radius_is_its_corner_arcs(radius):
    """Corners rounded to 0.1: all four arcs (curvature 10) are too sharp for a radius 0.2, none
    for 0.05; the sides are straight."""
    a, b, rho = 0.6, 0.4, 0.1
    field = _rounded_rectangle(a, b, rho)
    bd, g = _boundary(field, 2, 400)
    v = MinRadiusVerdict(_problem(radius).build())
    m = v.measure(SimpleNamespace(boundary=bd), SimpleNamespace(grid=g), field, None)
    arcs = 2 * math.pi * rho / (4 * (a + b) - 8 * rho + 2 * math.pi * rho)
    expected = arcs if radius > rho else 0.0
    assert m["sharp_share"] == pytest.approx(expected, abs=0.02)
    assert m["curvature_max"] == pytest.approx(1 / rho, rel=0.05)
    assert (v.violation(m) is not None) == (radius > rho)


def test_spec_reads_a_number_as_the_radius():
    assert _problem(0.02).build().tolerances.min_radius == CurvatureBound(0.02, 0.01)
    assert _problem({"radius": 0.02, "share": 0.05}).build().tolerances.min_radius.share == 0.05
    for bad in (-0.1, {"radius": 0.1, "share": 1.5}, {"share": 0.1}):
        with pytest.raises(SpecError, match="tolerances.min_radius"):
            _problem(bad)


@pytest.mark.parametrize("radius, expected", [(0.2, 1.0), (0.05, 0.0)])
def test_loss_is_the_curvature_beyond_the_bound_in_units_of_it(radius, expected):
    """A disk of radius 0.1 (curvature 10): kappa r - 1 = 1 for r = 0.2, nothing for 0.05."""
    spec = _problem(radius)
    task = make_task(spec, spec.config(None, {"sampling": {"n_domain": 2048, "n_boundary": 64}}))
    assert [c for c in task.constraints if isinstance(c, MinRadius)]
    terms = task.loss_terms(DiskField(0.1), 0, {"fillet", "eikonal"}, torch.Generator().manual_seed(0))
    assert float(terms["fillet"].detach()) == pytest.approx(expected, abs=1e-4)


def test_the_verdict_leaves_out_the_edges_an_interface_prescribes():
    """The rounded rectangle of the test above (corners of radius 0.1) with an interface along its
    right side, from corner to corner: its end points are rims, so the right-hand arcs and the
    boundary within 0.005 + 0.2 of them are left out, and the share is the two left-hand arcs'
    over what is left (the right side lies on the interface)."""
    a, b, rho, radius = 0.6, 0.4, 0.1, 0.2
    field = _rounded_rectangle(a, b, rho)
    bd, g = _boundary(field, 2, 400)
    spec = validate_spec({**SPEC, "geometry": {**SPEC["geometry"], "interfaces": [
        {"type": "segment", "a": [a, -b], "b": [a, b]}]}, "tolerances": {"min_radius": radius, "interface": 0.005}})
    m = MinRadiusVerdict(spec.build()).measure(SimpleNamespace(boundary=bd), SimpleNamespace(grid=g), field, None)
    arc = math.pi * rho / 2
    total = 4 * (a + b) - 8 * rho + 4 * arc
    left = 2 * arc + 2 * (b - rho) + 2 * (0.205 - rho)  # the right arcs and side, the top and bottom near them
    assert m["sharp_share"] == pytest.approx(2 * arc / (total - left), abs=0.02)
    assert 2 * arc / (total - left) < 4 * arc / (total - 2 * (b - rho)) - 0.07  # what the interface band alone left
