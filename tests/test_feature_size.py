"""Least feature sizes: the opening and closing on a grid against closed forms, the normal segment
loss on fields whose values along the segments are known, the spec and the verdicts."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from ginn.config import CELLS_PER_LENGTH, RESOLUTION
from ginn.constraints import MinGap, MinGapVerdict, MinThickness, MinThicknessVerdict
from ginn.errors import SpecError
from ginn.eval.feasibility import check_resolution
from ginn.extract.grid import Grid
from ginn.extract.morphology import closing_added, opening, opening_removed
from ginn.problems import FeatureSize, validate_spec
from ginn.tasks import make_task


def _grid(lo=(-1.2, -0.5), hi=(1.2, 0.5), cells=(1200, 500)):
    g = Grid(np.array(lo, dtype=float), np.array(hi, dtype=float), cells)
    return g, g.points().reshape(*g.shape, 2), g.node_weights()


def test_a_bar_thinner_than_the_ball_is_removed_whole_and_a_thick_one_loses_its_corners():
    g, x, w = _grid()
    thin = (np.abs(x[..., 0]) <= 1.0) & (np.abs(x[..., 1]) <= 0.025)  # 0.05 thick
    assert opening_removed(thin, g.spacing, 0.1, w) == 1.0
    thick = (np.abs(x[..., 0]) <= 1.0) & (np.abs(x[..., 1]) <= 0.2)  # 0.4 thick, 2 long
    r = 0.15  # a ball of diameter 0.3: each right-angled corner loses (1 - pi / 4) r^2
    expected = (4 - math.pi) * r * r / (2.0 * 0.4)
    assert opening_removed(thick, g.spacing, 2 * r, w) == pytest.approx(expected, rel=0.1)
    assert opening_removed(thick, g.spacing, 0.1, w) < 0.01  # 0.2 thick and more: within 1 %


def test_a_disk_wider_than_the_ball_is_kept():
    g, x, w = _grid()
    disk = np.hypot(x[..., 0], x[..., 1]) <= 0.3
    assert opening_removed(disk, g.spacing, 0.2, w) < 1e-3
    assert opening(disk, g.spacing, 0.7).sum() == 0  # a ball wider than the disk fits nowhere


def test_a_face_of_the_domain_cuts_without_thinning():
    """A bar that runs out through the domain's face keeps its corners there: only the two far
    corners are rounded."""
    g, x, w = _grid()
    bar = (x[..., 0] >= 0.0) & (np.abs(x[..., 1]) <= 0.2)
    r = 0.15
    expected = (2 - math.pi / 2) * r * r / (1.2 * 0.4)
    assert opening_removed(bar, g.spacing, 2 * r, w) == pytest.approx(expected, rel=0.1)


def test_the_closing_fills_a_slot_narrower_than_the_ball_only():
    g, x, w = _grid()
    slot = (np.abs(x[..., 1]) <= 0.02) & (x[..., 0] > 0)
    disk = (np.hypot(x[..., 0], x[..., 1]) <= 0.4) & ~slot
    area = math.pi * 0.4**2 - 0.04 * 0.4
    assert closing_added(disk, g.spacing, 0.1, w) == pytest.approx(0.04 * 0.4 / area, rel=0.1)
    assert closing_added(disk, g.spacing, 0.03, w) < 1e-3


def test_the_opening_is_the_same_with_unequal_spacing():
    """The ball is a ball in world units on a grid with other spacings along the axes."""
    g1, x1, w1 = _grid(cells=(1200, 500))
    g2, x2, w2 = _grid(cells=(600, 500))
    v = [opening_removed((np.abs(x[..., 0]) <= 1.0) & (np.abs(x[..., 1]) <= 0.2), g.spacing, 0.3, w)
         for g, x, w in ((g1, x1, w1), (g2, x2, w2))]
    assert v[0] == pytest.approx(v[1], rel=0.15)


def test_a_ball_under_two_cells_opens_nothing_and_one_over_the_checks_cells_removes_a_thin_bar():
    """Every node inside lies at least a cell from a node outside, so a ball of radius under a
    cell erodes nothing: the opening cannot see a bar thinner than the ball. With the ball
    ``CELLS_PER_LENGTH`` cells wide it removes the bar whole."""
    ball = 0.09
    for cells, removed in ((round(2.4 / (ball / 1.8)), 0.0), (round(2.4 / (ball / CELLS_PER_LENGTH)), 1.0)):
        g, x, w = _grid(cells=(cells, round(cells / 2.4)))
        bar = (np.abs(x[..., 0]) <= 1.0) & (np.abs(x[..., 1]) <= 0.0225)  # half the ball thick
        assert bar.any()
        assert opening_removed(bar, g.spacing, ball, w) == removed


# --- spec ----------------------------------------------------------------------------------------

SPEC = {"name": "slab", "geometry": {
    "dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
    "interfaces": [{"type": "segment", "a": [-0.9, -0.01], "b": [-0.9, 0.01], "normal": [-1, 0]}]}}


def _spec(**tol):
    return validate_spec({**SPEC, "tolerances": tol})


def test_spec_reads_a_number_as_the_size_and_checks_the_share():
    t = _spec(min_thickness=0.1, min_gap={"size": 0.05, "removed": 0.02}).build().tolerances
    assert t.min_thickness == FeatureSize(0.1, 0.01) and t.min_gap == FeatureSize(0.05, 0.02)
    for bad, field in (({"min_thickness": -0.1}, "min_thickness"), ({"min_gap": {"size": 0.1, "removed": 1.0}}, "min_gap"),
                       ({"min_thickness": {"removed": 0.1}}, "min_thickness"), ({"min_gap": True}, "min_gap")):
        with pytest.raises(SpecError, match=field):
            _spec(**bad)


def test_verdicts_compare_the_share_with_its_bound():
    p = _spec(min_thickness=0.1, min_gap={"size": 0.05, "removed": 0.02}).build()
    vt, vg = MinThicknessVerdict(p), MinGapVerdict(p)
    assert vt.violation({"thickness_removed": 0.005}) is None
    bad = vt.violation({"thickness_removed": 0.03})
    assert (bad.value, bad.bound) == (0.03, 0.01) and vt.ratio({"thickness_removed": 0.03}) == pytest.approx(3.0)
    assert vg.violation({"gap_filled": 0.03}).bound == 0.02 and vg.ratio({"gap_filled": 0.01}) == pytest.approx(0.5)
    assert "min_thickness" in MinThicknessVerdict.describe(bad)


def _measure_with(interfaces, inside, size):
    """``thickness_removed`` of the node mask ``inside`` on ``_grid()`` for a problem on that grid's
    box with ``interfaces`` (tolerance 0.005) and a least thickness ``size``."""
    spec = validate_spec({"name": "rims", "geometry": {"dim": 2, "domain": {"lo": [-1.2, -0.5], "hi": [1.2, 0.5]},
                                                      "interfaces": interfaces, "unit_scale": 1.0},
                          "tolerances": {"interface": 0.005, "min_thickness": size}})
    g, _, w = _grid()
    return MinThicknessVerdict(spec.build()).measure(SimpleNamespace(inside=inside), SimpleNamespace(grid=g, weights=w),
                                                     None, None)["thickness_removed"]


def test_the_verdict_leaves_the_rims_an_interface_prescribes_and_counts_a_thin_wall_along_it():
    """The bar |x| <= 1, |y| <= 0.2 with an interface along its top and right side: the three right
    angles the interface prescribes (its vertices) are left out, the fourth corner still loses
    (1 - pi / 4) r^2. A bar 0.05 thick under an interface along its middle half is removed but for
    the half disks of radius 0.005 + 0.05 round the interface's ends (9.2 % of its area)."""
    _, x, _ = _grid()
    bar = (np.abs(x[..., 0]) <= 1.0) & (np.abs(x[..., 1]) <= 0.2)
    r = 0.15
    corner = {"type": "polyline", "points": [[-1, 0.2], [1, 0.2], [1, -0.2]]}
    assert _measure_with([corner], bar, 2 * r) == pytest.approx((1 - math.pi / 4) * r * r / 0.8, rel=0.1)
    thin = (np.abs(x[..., 0]) <= 1.0) & (np.abs(x[..., 1]) <= 0.025)
    R, d = 0.055, 0.05  # the left-out disk round each end, and the bar's thickness below its centre
    cap = R * R * math.acos(d / R) - d * math.sqrt(R * R - d * d)
    kept = 2 * (math.pi * R * R / 2 - cap) / (2.0 * 0.05)
    assert _measure_with([{"type": "segment", "a": [-0.5, 0.025], "b": [0.5, 0.025]}], thin, 0.1) == pytest.approx(1 - kept, rel=0.02)
    assert _measure_with([{"type": "circle", "center": [0, 0], "radius": 0.3}], bar, 2 * r) == pytest.approx(
        4 * (1 - math.pi / 4) * r * r / 0.8, rel=0.1)  # a circle has no rim


# --- the normal segment loss ---------------------------------------------------------------------


class _Slab(torch.nn.Module):
    """The signed distance of the slab |y| <= w / 2 (``sign`` -1: of its complement)."""

    def __init__(self, w, sign=1.0):
        super().__init__()
        self.w, self.sign = w, sign
        self.p = torch.nn.Parameter(torch.zeros(()))

    def forward(self, x, z=None):
        return self.sign * (x[:, 1].abs() - 0.5 * self.w) + 0 * self.p


def _loss(task, model, name):
    terms = task.loss_terms(model, 0, {name, "eikonal"}, torch.Generator().manual_seed(0))
    return float(terms[name].detach())


@pytest.mark.parametrize("w, expected", [(0.04, (0.0 + 0.01 + 0.035 + 0.06) / 4), (0.2, 0.0)])
def test_segments_leave_a_thinner_solid_by_known_depths(w, expected):
    """Slab of width w, ball of diameter 0.1: the inner segment of each surface point reads the
    field at depths s = 0.025 ... 0.1, where it is |w / 2 - s| - w / 2."""
    spec = _spec(min_thickness=0.1, min_gap=0.1)
    cfg = spec.config(None, {"sampling": {"n_domain": 2048, "n_boundary": 64}})
    task = make_task(spec, cfg)
    assert [c for c in task.constraints if isinstance(c, MinThickness)]
    assert _loss(task, _Slab(w), "thickness") == pytest.approx(expected, abs=1e-5)
    # the void between two half-planes, |y| >= w / 2 solid: the same numbers outward
    assert [c for c in task.constraints if isinstance(c, MinGap)]
    assert _loss(task, _Slab(w, -1.0), "gap") == pytest.approx(expected, abs=1e-5)
    assert _loss(task, _Slab(w, -1.0), "thickness") == pytest.approx(0.0, abs=1e-7)  # the solid is wide


def test_the_checks_judge_a_ball_under_enough_of_their_cells_on_the_evaluation_grid():
    """The checks' default grid where the ball spans ``CELLS_PER_LENGTH`` of its cells (a domain 2
    long), ``ginn eval``'s grid where it does not."""
    h = 2.0 / RESOLUTION["check"][2]
    assert check_resolution(_spec().build()) == RESOLUTION["check"][2]
    assert check_resolution(_spec(min_thickness=CELLS_PER_LENGTH * h).build()) == RESOLUTION["check"][2]
    assert check_resolution(_spec(min_gap=0.99 * CELLS_PER_LENGTH * h).build()) == RESOLUTION["eval"][2]
    assert check_resolution(_spec(min_thickness=0.1, min_gap=0.001).build()) == RESOLUTION["eval"][2]
    solid = {**SPEC, "geometry": {"dim": 3, "domain": {"lo": [-1, -1, -0.5], "hi": [1, 1, 0.5]}, "interfaces": [
        {"type": "annulus", "center": [-0.9, 0, 0], "normal": [-1, 0, 0], "r_inner": 0.02, "r_outer": 0.05}]}}
    p = validate_spec({**solid, "tolerances": {"min_thickness": 0.05}}).build()
    assert check_resolution(p) == RESOLUTION["eval"][3]  # 1.6 cells of the checks' 64
    task = make_task(_spec(min_gap=0.02), _spec(min_gap=0.02).config(None, {}))
    assert task.checker().resolution == RESOLUTION["eval"][2]


def test_eval_says_when_its_grid_cannot_see_the_ball():
    """On 64 cells of a domain 2 long (0.03125 a cell) a ball of 0.05 spans 1.6 cells and removes
    nothing from a bar 0.02 thick: the evaluation names it with the grid that resolves it; the
    gap of 0.1 (3.2 cells) it measures. The note survives metrics.json."""
    from ginn.eval.results import ShapeEvaluation
    from ginn.eval.shapes import evaluate_shapes
    from ginn.fields import as_field

    p = _spec(min_thickness=0.05, min_gap=0.1).build()
    verdicts = [MinThicknessVerdict(p), MinGapVerdict(p)]
    bar = as_field(lambda x: torch.maximum(x[:, 0].abs() - 0.95, x[:, 1].abs() - 0.01))
    ev = evaluate_shapes(bar, None, p, resolution=64, verdicts=verdicts)
    assert ev.shapes[0].get("thickness_removed") == 0.0
    assert list(ev.unresolved) == ["min_thickness"]
    u = ev.unresolved["min_thickness"]
    assert u["cells"] == pytest.approx(1.6) and u["resolution"] == 120
    assert "min_thickness: the ball of diameter 0.05 spans 1.6 cells" in ev.text() and "--resolution 120" in ev.text()
    assert ShapeEvaluation.from_json(ev.to_json()).unresolved == ev.unresolved
    fine = evaluate_shapes(bar, None, p, resolution=120, verdicts=verdicts)
    # the bar is removed whole but within 0.005 + 0.025 of the interface's end points (its rim),
    # across the bar round x = -0.9: 0.02 x 0.0589 of its area 0.038
    assert fine.unresolved == {} and fine.shapes[0].get("thickness_removed") == pytest.approx(1 - 0.02 * 0.0589 / 0.038, abs=0.01)


class _Disk(torch.nn.Module):
    """The signed distance of the disk (sphere) of radius R at the origin (``sign`` -1: of its
    complement, a round hole)."""

    def __init__(self, R, sign=1.0):
        super().__init__()
        self.R, self.sign = R, sign
        self.p = torch.nn.Parameter(torch.zeros(()))

    def forward(self, x, z=None):
        return self.sign * (x.norm(dim=-1) - self.R) + 0 * self.p


def test_signed_curvature_is_one_over_the_radius_on_the_convex_side_only():
    from ginn.constraints.feature_size import signed_curvature
    from ginn.fields import evaluate

    for d in (2, 3):
        x = torch.nn.functional.normalize(torch.randn(64, d, dtype=torch.float64), dim=-1) * 0.4
        for sign in (1.0, -1.0):
            v = evaluate(_Disk(0.4, sign).double(), x, None, grad=False, hessian_at=torch.ones(64, dtype=torch.bool))
            convex, concave = (signed_curvature(v.hessian_grad, v.hessian, c) for c in (True, False))
            assert torch.allclose(convex, torch.full_like(convex, sign / 0.4), atol=1e-6)
            assert torch.allclose(concave, torch.full_like(concave, -sign / 0.4), atol=1e-6)


@pytest.mark.parametrize("R, expected", [(0.025, 1.0), (0.3, 0.0)])
def test_edges_terms_hold_the_curvature_under_two_over_the_size(R, expected):
    """Ball of diameter 0.1 (r = 0.05): a disk of radius R has the term relu(r / R - 1) on its
    edge, its complement (a hole of radius R) the same on the gap's."""
    spec = _spec(min_thickness=0.1, min_gap=0.1)
    task = make_task(spec, spec.config(None, {"sampling": {"n_domain": 4096, "n_boundary": 64}}))
    assert _loss(task, _Disk(R), "thickness_edges") == pytest.approx(expected, rel=1e-4, abs=1e-6)
    assert _loss(task, _Disk(R, -1.0), "gap_edges") == pytest.approx(expected, rel=1e-4, abs=1e-6)
    assert _loss(task, _Disk(R, -1.0), "thickness_edges") == 0.0  # a round hole has no convex edge
