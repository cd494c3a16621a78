"""Constraints as objects: a new kind of constraint is one class, defined here and trained with no
other file edited; the built-in ones report their targets, verdicts and stages."""

import json
import math

import pytest
import torch

from ginn import runs
from ginn.config import LossTerm
from ginn.constraints import Constraint, SampleSet, Stage, Verdict, Violation, shape_constraints
from ginn.tasks.shape import ShapeTask
from ginn.train.trainer import Trainer

P = torch.tensor([0.5, 0.25])  # the point the toy constraint wants inside the shape
R = 0.05


class AroundP(SampleSet):
    """Points uniform in the disk of radius R round P (values only)."""

    name, grad = "around_p", False

    def draw(self, setting, S, gen):
        n = 32 * S
        r = R * torch.rand(n, 1, generator=gen, dtype=setting.dtype).sqrt()
        a = 2 * math.pi * torch.rand(n, 1, generator=gen, dtype=setting.dtype)
        x = P.to(setting.dtype) + r * torch.cat([a.cos(), a.sin()], dim=1)
        return x.reshape(S, -1, 2), {}


class CoversP(Verdict):
    """P lies inside the shape: the field's value there, measured by the verdict itself."""

    name = "covers"

    def __init__(self, problem):
        super().__init__(problem)
        self.metrics = ("value_at_p",)

    def measure(self, shape, context, field, z):
        with torch.no_grad():
            zz = None if z is None else z.reshape(1, -1)
            return {"value_at_p": float(field(P[None].to(torch.float32 if z is None else z.dtype), zz))}

    def violation(self, metrics):
        v = metrics.get("value_at_p")
        return None if v is not None and v <= 0 else Violation(v, 0.0)

    def ratio(self, metrics):
        v = metrics.get("value_at_p")
        return math.inf if v is None else 1.0 + max(v, 0.0)


class Covers(Constraint):
    """The disk round P inside the shape: ``mean relu(f + R)`` over its samples."""

    name = "covers"
    samples = (AroundP(),)

    def __init__(self, setting):
        super().__init__(setting)
        self._verdict = CoversP(setting.problem)
        self.calls = 0

    @property
    def verdict(self):
        return self._verdict

    def term(self, cfg):
        return LossTerm(weight=3000.0)

    def loss(self, batch):
        self.calls += 1
        return torch.relu(batch.f["around_p"] + R).mean()

    def state_dict(self):
        return {"calls": self.calls}

    def load_state_dict(self, state):
        self.calls = int(state["calls"])


SMALL = {"training": {"iterations": 60, "lr": 5e-3, "log_every": 1, "feasibility_checks": 2, "checkpoint_every": 30,
                      "compile": False, "threads": 1},
         "latents": {"n_shapes": 1}, "model": {"hidden": [16, 16]},
         "sampling": {"n_domain": 128, "n_interface": 32, "n_outside": 64, "n_boundary": 32},
         "losses": {"connectedness": {"weight": 0}}}


def _task(cfg, spec, extra=(Covers,)):
    return ShapeTask(spec.build(), cfg, cfg.device, cfg.torch_dtype, extra=extra)


def test_a_toy_constraint_defined_here_trains_checks_and_resumes(tmp_path):
    spec, cfg = runs.resolve("obstacle", None, SMALL)
    task = _task(cfg, spec)
    assert [c.name for c in task.constraints][-1] == "covers" and task.terms()["covers"].weight == 3000.0
    tr = Trainer(task, cfg, tmp_path / "run", progress=False)
    tr.train()
    lines = [json.loads(x) for x in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()]
    steps = [r["covers"] for r in lines if "event" not in r]
    assert len(steps) == 60 and steps[0] > 0.05 and steps[-1] < 1e-3  # the term trained
    with torch.no_grad():
        assert float(tr.model(P[None], None)) < -0.03  # P is inside the shape, with room
    # the checks during training and ginn eval judge the toy's verdict with its own metric
    checks = [r for r in lines if r.get("event") == "feasibility"]
    assert checks and all("covers" in r["ratios"] for r in checks) and checks[-1]["ratios"]["covers"] == 1.0
    ev = task.results.evaluate(tr.model, resolution=64)
    assert ev.shapes[0].get("value_at_p") < 0 and "covers" not in ev.feasibility.violations[0]
    assert ev.to_json()["shapes"][0]["value_at_p"] == ev.shapes[0].get("value_at_p")
    # its state is in the checkpoint, under its name, and comes back on resume
    more = runs.resolve("obstacle", None, SMALL, {"training": {"iterations": 80}})[1]
    again = Trainer(_task(more, spec), more, tmp_path / "run", progress=False)
    assert again.resume() and again.task.constraints[-1].calls == 60
    again.train()
    assert again.task.constraints[-1].calls == 80


def test_without_the_toy_the_task_is_the_problems_own():
    spec, cfg = runs.resolve("obstacle", None, SMALL)
    assert [c.name for c in _task(cfg, spec, ()).constraints] == [
        "eikonal", "design_region", "obstacle", "interface", "normal", "mean_curvature", "strain", "connectedness"]


def test_built_in_constraints_state_their_stage_targets_and_verdicts():
    spec, cfg = runs.resolve("obstacle", None)  # the derived settings, 16 shapes
    task = ShapeTask(spec.build(), cfg, "cpu", torch.float32)
    by = {c.name: c for c in task.constraints}
    assert [c.name for c in task.constraints if c.stage == Stage.FIELD] == ["design_region", "connectedness"]
    assert {c.name for c in task.constraints if c.stage == Stage.SURFACE} == {"mean_curvature", "strain", "diversity"}
    d = 0.5 * 5e-3  # half the interface tolerance
    b = task.balance()
    assert b.targets["interface"] == pytest.approx(d * d)
    assert b.targets["design_region"] == b.targets["obstacle"] == pytest.approx(5e-3 * d)  # power 1 (derived)
    assert b.targets["normal"] == pytest.approx(2 * (1 - math.cos(math.radians(task.problem.tolerances.normal_angle))))
    assert b.targets["connectedness"] == 0.0 and "diversity" not in b.targets
    assert b.groups == {"volume_outside": ("design_region", "obstacle"), "interface": ("interface",),
                        "connected": ("connectedness",)}
    assert by["diversity"].verdict is None
    assert [v.name for v in task.verdicts()] == ["interface", "volume_outside", "connected"]


def test_sample_sets_are_drawn_only_for_active_constraints():
    spec, cfg = runs.resolve("obstacle", None, SMALL)
    setting_task = _task(cfg, spec)
    gen = torch.Generator().manual_seed(0)
    only_covers = setting_task.draw_batch(1, {"covers"}, gen)
    assert set(only_covers.x) == {"domain", "around_p"}  # the domain samples are drawn at every step
    assert only_covers.x["around_p"].shape == (1, 32, 2)
    assert ((only_covers.x["around_p"][0] - P).norm(dim=-1) <= R + 1e-6).all()
    every = setting_task.draw_batch(2, {c.name for c in setting_task.constraints}, gen)
    assert set(every.x) == {"domain", "outside", "obstacle", "interface", "around_p"}
    assert every.attrs["normals"].shape == every.x["interface"].shape == (2, 32, 2)


def test_shape_constraints_follow_the_geometry():
    spec, cfg = runs.resolve("plateau", None)
    task = ShapeTask(spec.build(), cfg, "cpu", torch.float32)
    names = [c.name for c in shape_constraints(task.setting)]
    assert "design_region" not in names and "obstacle" not in names and "diversity" not in names
    assert "interface" in names and "mean_curvature" in names
