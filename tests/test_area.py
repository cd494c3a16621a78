"""Area bounds: the boundary's measure on extracted shapes against closed forms, the coarea
estimate of training against the same (whatever the field's slope), the loss, the spec and the
verdict."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from _shapes import DiskField
from ginn.constraints import Area, AreaVerdict
from ginn.constraints.area import coarea_estimate
from ginn.errors import SpecError
from ginn.extract.boundary import extract_boundary
from ginn.extract.grid import Grid
from ginn.problems import Bounds, validate_spec
from ginn.tasks import make_task


def _measured(fn, d, cells):
    g = Grid(np.full(d, -1.0), np.full(d, 1.0), (cells,) * d)
    b = extract_boundary(fn(g.points()).reshape(g.shape).astype(np.float32), g)
    return AreaVerdict(_spec({"max": 100.0}).build()).measure(SimpleNamespace(boundary=b), None, None, None)["boundary_area"]


def test_a_circle_a_sphere_and_a_cut_bar_measure_their_closed_forms():
    assert _measured(lambda x: np.linalg.norm(x, axis=1) - 0.4, 2, 512) == pytest.approx(2 * math.pi * 0.4, rel=1e-3)
    assert _measured(lambda x: np.linalg.norm(x, axis=1) - 0.5, 3, 96) == pytest.approx(4 * math.pi * 0.25, rel=5e-3)
    # a bar running out through the domain's right face: its two sides and its left end, no cap
    bar = lambda x: np.maximum(np.abs(x[:, 1]) - 0.1, -0.5 - x[:, 0])  # noqa: E731
    assert _measured(bar, 2, 400) == pytest.approx(2 * 1.5 + 0.2, rel=2e-3)


@pytest.mark.parametrize("slope", [1.0, 3.0])
def test_the_coarea_estimate_reads_the_length_whatever_the_slope(slope):
    g = torch.Generator().manual_seed(0)
    x = (2 * torch.rand(1, 200_000, 2, generator=g, dtype=torch.float64) - 1).requires_grad_(True)
    f = slope * (x.norm(dim=-1) - 0.4)
    grad = torch.autograd.grad(f.sum(), x, create_graph=True)[0]
    A, err = coarea_estimate(f, grad, width=0.01, volume=4.0)
    A, err = float(A[0].detach()), float(err[0])
    assert A == pytest.approx(2 * math.pi * 0.4, abs=3 * err) and 0 < err < 0.05 * A


SPEC = {"name": "ring", "geometry": {
    "dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
    "interfaces": [{"type": "segment", "a": [-0.95, 0.9], "b": [-0.9, 0.9], "normal": [0, 1]}]}}


def _spec(area):
    return validate_spec({**SPEC, "tolerances": {"area": area}})


def test_spec_and_verdict():
    assert _spec(2.0).build().tolerances.area == Bounds(None, 2.0)
    p = _spec({"min": 1.0, "max": 2.0}).build()
    v = AreaVerdict(p)
    assert v.violation({"boundary_area": 1.5}) is None
    assert v.violation({"boundary_area": 2.5}).bound == 2.0 and v.violation({"boundary_area": 0.5}).bound == 1.0
    assert v.ratio({"boundary_area": 0.5}) == pytest.approx(2.0) and v.ratio({"boundary_area": 3.0}) == pytest.approx(1.5)
    assert AreaVerdict.describe(v.violation({"boundary_area": 2.5})) == "area 2.5 > 2"
    for bad in ({"min": 3, "max": 2}, {"max": 0}, {}):
        with pytest.raises(SpecError, match="tolerances.area"):
            _spec(bad)


def test_loss_is_the_excess_over_the_bound_relative_to_it():
    """A circle of length 2 pi 0.4 against at most half of it: 1 plus the standard error relative to
    the bound (about 0.06 with 65536 samples), within three standard errors."""
    spec = _spec(math.pi * 0.4)
    task = make_task(spec, spec.config(None, {"sampling": {"n_domain": 65536}}))
    assert [c for c in task.constraints if isinstance(c, Area)]
    terms = task.loss_terms(DiskField(0.4), 0, {"area", "eikonal"}, torch.Generator().manual_seed(0))
    assert float(terms["area"].detach()) == pytest.approx(1.06, abs=0.2)
    assert float(task.loss_terms(DiskField(0.1), 0, {"area", "eikonal"}, torch.Generator().manual_seed(0))["area"].detach()) == 0
