"""Volume bounds (``tolerances.volume_fraction``): the metric against exact volumes, the verdict,
the spec, and the training term's estimate and penalty."""

import math
from types import SimpleNamespace

import pytest
import torch

from _shapes import Disk, Rect
from ginn import runs
from ginn.constraints import VolumeFraction, VolumeFractionVerdict, shape_constraints
from ginn.constraints.base import Setting
from ginn.errors import SpecError
from ginn.eval.shapes import evaluate_shapes
from ginn.fields import as_field
from ginn.geometry.base import Box
from ginn.problems import parse_spec
from ginn.problems.problem import Problem, Tolerances, VolumeBounds

BOX2 = Box((-1.0, -1.0), (1.0, 1.0))
E2 = Rect((-0.9, -0.9), (0.9, 0.9))  # vol(E) = 3.24


class Ball:
    def __init__(self, r):
        self.r = r

    def sdf(self, x):
        return x.norm(dim=-1) - self.r


def test_volume_fraction_of_a_disk_in_a_square_design_region():
    exact = math.pi * 0.4**2 / 3.24
    s = evaluate_shapes(as_field(Disk((0.1, 0.0), 0.4).sdf), None, Problem("t", BOX2, design_region=E2), 256).to_json()["shapes"][0]
    assert s["volume_fraction"] == pytest.approx(exact, rel=5e-3)
    # a disk reaching out of E counts its part inside E only: the half-disk beyond x = 0.9 is cut off
    s = evaluate_shapes(as_field(Disk((0.9, 0.0), 0.05).sdf), None, Problem("t", BOX2, design_region=E2), 512).to_json()["shapes"][0]
    assert s["volume_fraction"] == pytest.approx(0.5 * math.pi * 0.05**2 / 3.24, rel=0.05)


def test_volume_fraction_of_a_ball_in_a_cube_without_design_region():
    cube = Box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
    s = evaluate_shapes(as_field(Ball(0.5).sdf), None, Problem("t", cube), 64).to_json()["shapes"][0]
    assert s["volume_fraction"] == pytest.approx(4 / 3 * math.pi * 0.125 / 8, rel=0.02)


@pytest.mark.parametrize("bounds, feasible, text, ratio", [
    (VolumeBounds(max=0.1), False, "volume_fraction {v:.3g} > 0.1", 1.5514),
    (VolumeBounds(min=0.2), False, "volume_fraction {v:.3g} < 0.2", 1.2891),
    (VolumeBounds(min=0.15, max=0.16), True, None, 0.9696),
])
def test_the_verdict_bounds_the_fraction_from_either_side(bounds, feasible, text, ratio):
    P = Problem("t", BOX2, design_region=E2, tolerances=Tolerances(connected=False, volume_fraction=bounds))
    ev = evaluate_shapes(as_field(Disk((0.1, 0.0), 0.4).sdf), None, P, 256)
    v = VolumeFractionVerdict(P)
    assert v.ratio(ev.shapes[0]) == pytest.approx(ratio, rel=5e-3)
    assert ev.feasibility.feasible == int(feasible)
    if text:
        assert text.format(v=ev.shapes[0].volume_fraction) in ev.text()


def test_a_problem_without_bounds_has_no_volume_term_nor_verdict():
    spec, cfg = runs.resolve("obstacle", None)
    setting = Setting(spec.build(), cfg, torch.device("cpu"), torch.float32)
    assert "volume" not in [c.name for c in shape_constraints(setting)]


SPEC = """
name: slab
geometry:
  dim: 2
  domain: {lo: [-1, -1], hi: [1, 1]}
  design_region: {type: rectangle, lo: [-0.9, -0.9], hi: [0.9, 0.9]}
  interfaces:
    - {type: segment, a: [-0.9, -0.5], b: [-0.9, 0.5], normal: [-1, 0]}
tolerances:
  volume_fraction: VF
"""


@pytest.mark.parametrize("value, bounds", [("0.3", VolumeBounds(None, 0.3)), ("{min: 0.1}", VolumeBounds(0.1, None)),
                                           ("{min: 0.1, max: 0.2}", VolumeBounds(0.1, 0.2))])
def test_spec_states_the_bounds(value, bounds):
    assert parse_spec(SPEC.replace("VF", value)).build().tolerances.volume_fraction == bounds


@pytest.mark.parametrize("value, needle", [("{min: 0.3, max: 0.2}", "min 0.3 is above max 0.2"), ("{}", "state min, max"),
                                           ("1.5", "must be <= 1"), ("yes", "tolerances.volume_fraction"),
                                           ("{max: on}", "YAML read it as True")])
def test_spec_refuses_bad_bounds_with_one_line(value, needle):
    with pytest.raises(SpecError) as e:
        parse_spec(SPEC.replace("VF", value))
    assert needle in str(e.value) and "\n" not in str(e.value)


def _term(bounds: VolumeBounds, n_domain: int = 4096) -> VolumeFraction:
    spec = parse_spec(SPEC.replace("VF", "0.5"))
    P = spec.build()
    P = Problem(P.name, P.domain, design_region=P.design_region, interfaces=P.interfaces,
                tolerances=Tolerances(volume_fraction=bounds))
    cfg = runs.resolve("obstacle", None, {"sampling": {"n_domain": n_domain}})[1]
    return VolumeFraction(Setting(P, cfg, torch.device("cpu"), torch.float64))


def test_the_estimate_is_the_share_of_samples_and_its_step_follows_the_samples():
    term = _term(VolumeBounds(max=0.1))
    assert term.width == pytest.approx(0.5 * math.sqrt(4.0 / 4096))
    gen = torch.Generator().manual_seed(0)
    x = 2 * torch.rand(4, 50_000, 2, generator=gen, dtype=torch.float64) - 1
    radii = torch.tensor([0.2, 0.4, 0.6, 0.8], dtype=torch.float64)
    f = x.norm(dim=-1) - radii[:, None]
    batch = SimpleNamespace(f={"domain": f}, x={"domain": x}, d=2)
    v, err = term.fractions(batch)
    inE = (x.abs() <= 0.9).all(dim=-1)
    assert torch.equal(v, ((f <= 0) & inE).sum(1).double() / inE.sum(1))  # the value: the share, unbiased
    exact = math.pi * radii**2 / 3.24
    m = 50_000 * 3.24 / 4  # samples in E
    assert torch.allclose(err, (v * (1 - v) / m).sqrt(), rtol=0.02)
    assert torch.all((v - exact).abs() < 4 * err + 1e-3)
    # the exact penalty of the estimate moved towards the bound by its standard error
    assert float(term.loss(batch)) == pytest.approx(float(torch.relu(v + err - 0.1).mean()), rel=1e-12)
    low = _term(VolumeBounds(min=0.3))
    assert float(low.loss(batch)) == pytest.approx(float(torch.relu(0.3 - v + err).mean()), rel=1e-12)


def test_the_value_does_not_depend_on_how_steep_the_field_is():
    """A band 0.1 thick whose field is shallow inside (a third of a distance), as trained fields
    can be: the share of samples counts it in full, a smoothed count would not."""
    term = _term(VolumeBounds(max=0.01))
    gen = torch.Generator().manual_seed(2)
    x = 2 * torch.rand(1, 100_000, 2, generator=gen, dtype=torch.float64) - 1
    d = x[..., 1].abs() - 0.05
    f = torch.where(d < 0, d / 3, d)
    v, err = term.fractions(SimpleNamespace(f={"domain": f}, x={"domain": x}, d=2))
    assert float(v) == pytest.approx(0.1 * 1.8 / 3.24, abs=4 * float(err))
    inE = (x.abs() <= 0.9).all(-1)
    smooth = (torch.sigmoid(-f / term.width) * inE).sum() / inE.sum()
    assert float(smooth) < 0.9 * float(v)


def test_the_penalty_pushes_the_boundary_in_when_over_and_out_when_under():
    gen = torch.Generator().manual_seed(1)
    x = 2 * torch.rand(1, 20_000, 2, generator=gen, dtype=torch.float64) - 1
    for bounds, sign in ((VolumeBounds(max=0.05), 1.0), (VolumeBounds(min=0.5), -1.0)):
        r = torch.tensor(0.4, dtype=torch.float64, requires_grad=True)
        batch = SimpleNamespace(f={"domain": x.norm(dim=-1) - r}, x={"domain": x}, d=2)
        _term(bounds).loss(batch).backward()
        assert sign * float(r.grad) > 0  # descent shrinks the disk over a max, grows it under a min


@pytest.mark.parametrize("name, bound", [("obstacle-35", 0.35), ("obstacle-50", 0.5)])
def test_the_benchmark_specs_are_the_obstacle_with_a_bound(name, bound):
    from pathlib import Path

    from ginn.problems import load_spec

    spec = load_spec(Path(__file__).resolve().parents[1] / "benchmarks" / "volume" / f"{name}.yaml")
    assert spec.build().tolerances.volume_fraction == VolumeBounds(None, bound)
    assert spec.geometry == load_spec("obstacle").geometry
    assert spec.defaults == {"latents": {"n_shapes": 4, "dim": 1, "low": -1.0, "high": 1.0}}


def test_the_explorer_shows_the_fraction_beside_the_verdict():
    from ginn.eval.results import ShapeMetrics
    from ginn.viz.explorer import _verdict

    P = Problem("t", BOX2, design_region=E2, tolerances=Tolerances(connected=False, volume_fraction=VolumeBounds(max=0.25)))
    over = _verdict(ShapeMetrics(volume_fraction=0.3, volume_outside=0.0), P)
    assert over.startswith("volume_fraction 0.3 &gt; 0.25") or over.startswith("volume_fraction 0.3 > 0.25")
    assert "volume fraction of E 0.300 (bounds 0 to 0.25)" in over
    assert "volume fraction" not in _verdict(ShapeMetrics(volume_fraction=0.3), Problem("t", BOX2, design_region=E2))
