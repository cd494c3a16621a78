"""Feasibility: the problem's tolerances applied to the metrics, during training and in ``ginn eval``."""

import functools
import json
import os
import signal

import numpy as np
import pytest
import torch

from ginn import runs
from ginn.config import HELDOUT_LATENTS, build_config
from ginn.constraints import Violation
from ginn.eval.feasibility import FEASIBILITY_METRICS, check_feasibility, format_feasibility, ratios, summarize, violations
from ginn.eval.results import FeasibilitySummary
from ginn.eval.shapes import evaluate_shapes
from ginn.fields import as_field
from ginn.geometry import csg
from ginn.geometry.primitives import AABox, Ball
from ginn.problems import load_spec, validate_spec
from ginn.problems.problem import Tolerances
from ginn.tasks.shape import FeasibilityChecks
from ginn.train.trainer import Trainer
from test_trainer import CircleFit


@pytest.fixture(scope="module")
def obstacle():
    return load_spec("obstacle").build()


def test_violations_name_each_constraint_with_value_and_bound(obstacle):
    ok = {"interface_cd1": 1e-3, "volume_outside": 0.0, "b0_in_design_region": 1, "connected_interfaces_share": 1.0}
    assert violations(ok, obstacle) == {}
    bad = {"interface_cd1": 8e-3, "volume_outside": 0.02, "b0_in_design_region": 2, "connected_interfaces_share": 0.5}
    v = violations(bad, obstacle)
    assert v["interface"] == {"value": 8e-3, "bound": 5e-3}
    assert v["volume_outside"] == {"value": 0.02, "bound": 5e-3}
    assert v["connected"] == {"value": 2, "bound": 1, "interfaces": 0.5}
    empty = dict(ok, interface_cd1=None, b0_in_design_region=0)
    assert violations(empty, obstacle)["interface"]["value"] is None
    # one piece that misses an interface is not connected either
    assert "connected" in violations(dict(ok, connected_interfaces_share=0.5), obstacle)


def test_tolerances_scale_with_unit_scale_and_can_drop_connectedness(obstacle):
    import dataclasses

    p = dataclasses.replace(obstacle, unit_scale=2.0, tolerances=Tolerances(interface=5e-3, volume_outside=0.1, connected=False))
    m = {"interface_cd1": 8e-3, "volume_outside": 0.05, "b0_in_design_region": 3, "connected_interfaces_share": 0.5}
    assert violations(m, p) == {}  # 8e-3 <= 5e-3 * 2, 0.05 <= 0.1, pieces not required
    assert violations(dict(m, interface_cd1=0.011), p)["interface"]["bound"] == pytest.approx(0.01)


def test_spec_tolerances_reach_the_problem():
    spec = validate_spec({"name": "t", "geometry": {"dim": 2, "domain": {"lo": [0, 0], "hi": [1, 1]}, "unit_scale": 0.5},
                          "tolerances": {"interface": 0.01, "volume_outside": 0.002, "connected": False}})
    p = spec.build()
    assert p.tolerances == Tolerances(0.01, 0.002, False) and p.unit_scale == 0.5
    assert validate_spec({"name": "t", "geometry": {"dim": 2, "domain": {"lo": [0, 0], "hi": [1, 1]}}}).build().tolerances \
        == Tolerances(5e-3, 5e-3, True)


def test_spec_topology_reaches_the_problem():
    from ginn.problems.problem import Topology

    def build(dim, topology, **tol):
        lo, hi = [0] * dim, [1] * dim
        return validate_spec({"name": "t", "geometry": {"dim": dim, "domain": {"lo": lo, "hi": hi}},
                              "topology": topology, "tolerances": tol}).build()

    assert build(2, {"holes": 2}).topology == Topology(b1=2) and build(2, {"holes": 2}).topology.targets == {1: 2}
    p3 = build(3, {"tunnels": 1, "cavities": 0})
    assert p3.topology == Topology(b1=1, b2=0) and p3.topology.targets == {1: 1, 2: 0}
    assert build(2, {}).topology.targets == {}
    # components: 1 asks for one piece, whatever tolerances.connected says
    assert build(2, {"components": 1}, connected=False).tolerances.connected


def _fields(problem):
    """Analytic shapes with known verdicts: E itself (feasible), the whole domain (volume outside E
    = 1, its boundary far from the interfaces), a small disk far from the interfaces (misses them), and thin disks around the two
    interfaces (two pieces)."""
    lo, hi = problem.domain.lo, problem.domain.hi
    whole = AABox([a - 1 for a in lo], [b + 1 for b in hi])
    centres = [itf.sample(1, generator=torch.Generator().manual_seed(0), dtype=torch.float64)[0][0]
               for itf in problem.interfaces]
    disks = csg.Intersection(csg.Union(*[Ball([float(c) for c in x], 0.05) for x in centres]), problem.design_region)
    return {
        "design region": (problem.design_region.sdf, set()),
        "whole domain": (whole.sdf, {"volume_outside", "interface"}),  # no boundary at the interfaces
        "small disk": (Ball([0.0, 0.0], 0.02).sdf, {"interface", "connected"}),
        "two disks": (disks.sdf, {"interface", "connected"}),
    }


def test_check_and_eval_give_the_same_verdicts(obstacle):
    for name, (sdf, expected) in _fields(obstacle).items():
        field = as_field(sdf)
        coarse = check_feasibility(field, None, obstacle, resolution=128)
        fine = evaluate_shapes(field, None, obstacle, resolution=512).feasibility
        assert set(coarse.violations[0]) == expected, (name, coarse)
        assert set(fine.violations[0]) == expected, (name, fine)
        assert coarse.feasible == fine.feasible == (0 if expected else 1)
    empty = check_feasibility(as_field(lambda x: torch.ones_like(x[:, 0])), None, obstacle, resolution=64)
    assert empty.violations[0]["interface"].value is None and "interface_cd1" not in empty.worst


def test_summary_counts_and_worst(obstacle):
    # the verdict bounds the volume outside E beyond the interface tolerance: shape 0 is over the
    # bound only within it (0.01 > 0.005 counted as volume_outside, 0 off the interfaces)
    shapes = [{"interface_cd1": c, "volume_outside": v, "volume_outside_off_interfaces": w, "b0_in_design_region": b,
               "connected_interfaces_share": 1.0}
              for c, v, w, b in [(1e-3, 0.01, 0.0, 1), (9e-3, 1e-3, 1e-3, 1), (2e-3, 0.2, 0.19, 3)]]
    s = summarize(shapes, obstacle)
    assert s.feasible == 1 and s.shapes == 3
    assert s.worst == {"interface_cd1": 9e-3, "volume_outside": 0.19, "b0_in_design_region": 3.0}
    text = format_feasibility(s)
    assert text.splitlines()[0] == "feasible shapes: 1 of 3"
    assert "shape 1: interface 0.009 > 0.005" in text and "shape 2: volume_outside 0.19 > 0.005; connected: 3 pieces" in text
    assert set(FEASIBILITY_METRICS) <= set(shapes[0])
    # metrics without the off-interface volume (older runs) are judged by volume_outside
    old = [{k: v for k, v in m.items() if k != "volume_outside_off_interfaces"} for m in shapes]
    assert summarize(old, obstacle).feasible == 0 and summarize(old, obstacle).worst["volume_outside"] == 0.2


def test_ratios_are_values_over_bounds(obstacle):
    m = {"interface_cd1": 8e-3, "volume_outside": 0.02, "volume_outside_off_interfaces": 1e-3, "b0_in_design_region": 2,
         "connected_interfaces_share": 1.0}
    assert ratios(m, obstacle) == pytest.approx({"interface": 1.6, "volume_outside": 0.2, "connected": 2.0})
    # one piece reaching one of two interface components: as bad as two pieces
    assert ratios(dict(m, b0_in_design_region=1, connected_interfaces_share=0.5), obstacle)["connected"] == 2.0
    assert ratios(dict(m, b0_in_design_region=1), obstacle)["connected"] == 1.0
    empty = ratios(dict(m, interface_cd1=None, b0_in_design_region=0), obstacle)
    assert empty["interface"] == float("inf") and empty["connected"] == float("inf")
    shapes = [m, dict(m, interface_cd1=2e-3, volume_outside_off_interfaces=0.015, b0_in_design_region=1),
              dict(m, interface_cd1=None)]
    # the summary holds the largest ratio of each constraint, undefined ones as None (strict JSON)
    assert summarize(shapes, obstacle).ratios == {"interface": None, "volume_outside": pytest.approx(3.0),
                                                     "connected": 2.0}
    assert summarize(shapes[:2], obstacle).ratios["interface"] == pytest.approx(1.6)


def test_topology_targets_enter_the_verdict(obstacle):
    import dataclasses

    from ginn.eval.feasibility import feasibility_metrics, shape_violations, verdict_text
    from ginn.problems.problem import Topology

    p = dataclasses.replace(obstacle, topology=Topology(b1=2))
    m = {"interface_cd1": 1e-3, "volume_outside": 0.0, "b0_in_design_region": 1, "connected_interfaces_share": 1.0,
         "b1_in_design_region": 3, "b2_in_design_region": None}
    v = violations(m, p)
    assert v == {"topology": {"value": {"holes": 3}, "bound": {"holes": 2}}}
    assert verdict_text(shape_violations(m, p)) == "topology: 3 holes (want 2)"
    assert verdict_text(shape_violations(dict(m, b1_in_design_region=1), p)) == "topology: 1 hole (want 2)"
    assert ratios(m, p)["topology"] == 2.0 and ratios(dict(m, b1_in_design_region=0), p)["topology"] == 3.0
    assert violations(dict(m, b1_in_design_region=2), p) == {} and ratios(dict(m, b1_in_design_region=2), p)["topology"] == 1.0
    assert "b1_in_design_region" in feasibility_metrics(p) and "b1_in_design_region" not in feasibility_metrics(obstacle)
    assert "topology" not in ratios(m, obstacle)  # no targets: no constraint
    # the check and ginn eval count the same holes: E itself has one, round the obstacle's disk
    field = as_field(p.design_region.sdf)
    assert check_feasibility(field, None, dataclasses.replace(obstacle, topology=Topology(b1=1)), 128).feasible == 1
    coarse = check_feasibility(field, None, p, 128)
    fine = evaluate_shapes(field, None, p, resolution=512).feasibility
    assert coarse.violations[0]["topology"].to_json() == fine.violations[0]["topology"].to_json() == \
        {"value": {"holes": 1}, "bound": {"holes": 2}}


def test_checks_raise_the_multipliers_they_log(tmp_path, few_heldout_checks):
    """``balancing.method: feasibility``: every logged multiplier is its weight times the factors
    the checks logged for its constraint."""
    over = {"training": {"iterations": 48, "log_every": 1, "feasibility_checks": 8},
            "latents": {"n_shapes": 2}, "model": {"hidden": [16, 16]}, "sampling": {"n_domain": 128, "n_interface": 64},
            "balancing": {"method": "feasibility"}}
    spec, cfg = runs.resolve("obstacle", "demo", over)
    runs.train(spec, cfg, tmp_path / "a", progress=False, results=False)
    events = [json.loads(x) for x in (tmp_path / "a" / "metrics.jsonl").read_text().splitlines()]
    groups = {"interface": ["interface"], "volume_outside": ["design_region", "obstacle"], "connected": ["connectedness"]}
    factor = {t: 1.0 for ts in groups.values() for t in ts}
    raised = 0
    for e in events:
        if e.get("event") == "feasibility":
            assert set(e["ratios"]) == set(groups)
            for c, f in e.get("raised", {}).items():
                assert 1.0 < f <= 2.0 and f == pytest.approx(min(2.0, e["ratios"][c] ** 2 if e["ratios"][c] else 2.0), rel=1e-3)
                raised += 1
                for t in groups[c]:
                    factor[t] *= f
        elif "multipliers" in e:
            for t, w in e["multipliers"].items():
                assert w == pytest.approx(getattr(cfg.losses, t).weight * factor.get(t, 1.0), rel=1e-4), (e["step"], t)
    assert raised >= 2  # early checks find the untrained shapes violated and stalled


def test_training_logs_the_checks_and_leaves_the_weights_alone(tmp_path):
    over = {"training": {"iterations": 40, "log_every": 10, "feasibility_checks": 4, "keep_most_feasible": False},
            "latents": {"n_shapes": 2},
            "model": {"hidden": [16, 16]}, "sampling": {"n_domain": 128, "n_interface": 64},
            "losses": {"connectedness": {"weight": 0}}, "balancing": {"method": "weighted"}}
    spec, cfg = runs.resolve("obstacle", "demo", over)
    out = runs.train(spec, cfg, tmp_path / "a", progress=False, results=False)
    events = [json.loads(x) for x in (tmp_path / "a" / "metrics.jsonl").read_text().splitlines()]
    checks = [e for e in events if e.get("event") == "feasibility"]
    assert [e["step"] for e in checks] == [10, 20, 30, 40]  # events: completed iterations
    assert all(e["shapes"] == 2 and 0 <= e["feasible"] <= 2 for e in checks)
    # the held-out codes of the latent set are judged too, and the worst of them named
    held = HELDOUT_LATENTS["check"][2]
    assert all(e["heldout"]["shapes"] == held and 0 <= e["heldout"]["feasible"] <= held for e in checks)
    assert all(-1 <= e["heldout"]["worst_latent"][0] <= 1 for e in checks)
    json.dumps(checks, allow_nan=False)  # strict JSON, also for empty shapes
    spec, off = runs.resolve("obstacle", "demo", {**over, "training": {**over["training"], "feasibility_checks": 0}})
    ref = runs.train(spec, off, tmp_path / "b", progress=False, results=False)
    for p, q in zip(out.model.parameters(), ref.model.parameters()):
        assert torch.equal(p, q)


class Judged(CircleFit):
    """A toy task with a verdict: it contributes the feasibility checks of shape tasks, judged by
    its own ``feasibility``."""

    def callbacks(self, dist=None):
        return [FeasibilityChecks(self.feasibility, self.cfg.training)]


class AlwaysFeasible(Judged):
    def feasibility(self, model):
        return FeasibilitySummary(1, 1, [{}])


def test_stop_when_feasible_waits_for_steady_objectives(tmp_path):
    def cfg(stop):
        return build_config({"seed": 0, "training": {"iterations": 1000, "lr": 1e-2, "lr_decay_every": 200,
                                                     "feasibility_checks": 10, "stop_when_feasible": stop},
                             "balancing": {"objectives": ["fit"]}})
    res = Trainer(AlwaysFeasible(cfg(True)), cfg(True), tmp_path / "a", progress=False).train()
    # the learning rate halves every 200 iterations, so the fit settles well before the end
    assert res.status == "completed" and 200 <= res.step < 1000 and res.step % 100 == 0
    assert "objectives steady" in res.reason
    # without the flag the run goes to the end; without a verdict (no tolerances) nothing stops
    assert Trainer(AlwaysFeasible(cfg(False)), cfg(False), None, progress=False).train().step == 1000
    assert Trainer(CircleFit(cfg(True)), cfg(True), None, progress=False).train().step == 1000


def test_shape_pictures_show_the_problem_and_the_verdict(tmp_path):
    """A 2D run's per-shape PNG draws the obstacles (grey fill) and E's outline under the shape,
    and its name and verdict match the check."""
    import matplotlib.image

    from ginn.tasks import make_task
    from ginn.viz.plot import save_shape_figure

    spec, cfg = runs.resolve("obstacle", "demo", {"latents": {"n_shapes": 2}, "model": {"hidden": [16, 16]}})
    task = make_task(spec, cfg)
    model = task.build_model().double()
    task.Z = task.Z.double()
    paths = task.results.export(model, None, tmp_path, 64)
    pngs = sorted(p for p in paths if p.suffix == ".png")
    assert [p.name[:9] for p in pngs] == ["shape_000", "shape_001"]
    assert {p.suffix for p in paths} == {".png", ".json", ".csv", ".npz", ".svg"}
    # an empty shape over the obstacle problem: the obstacle's grey (217, 217, 217) is drawn
    empty = save_shape_figure([], task.problem, tmp_path / "empty.png", "feasible")
    rgb = (matplotlib.image.imread(empty)[..., :3] * 255).round()
    assert (np.abs(rgb - 217).max(axis=-1) < 2).sum() > 100


class ScriptedVerdicts(Judged):
    """Feasible counts from a script, one per check; records the weights at each check."""

    def __init__(self, cfg, script):
        super().__init__(cfg)
        self.script, self.seen = list(script), []

    def feasibility(self, model):
        k = self.script[len(self.seen)]
        self.seen.append(torch.cat([p.detach().flatten().clone() for p in model.parameters()]))
        return FeasibilitySummary(k, 4, [{}] * k + [{"interface": Violation(1.0, 0.5)}] * (4 - k))


def _flat(model) -> torch.Tensor:
    return torch.cat([p.detach().flatten().clone() for p in model.parameters()])


@pytest.mark.parametrize("keep", [True, False])
def test_run_ends_with_the_weights_of_the_most_feasible_check(tmp_path, keep):
    """Each check judges the iterate, then the mean of the weights since the previous check; the run
    ends with the best candidate, the latest of equals (iteration 30's mean: 3, as iteration 20's
    iterate), which is the mean of the ten iterates before it (to rounding: a running mean)."""
    c = build_config({"seed": 0, "training": {"iterations": 50, "lr": 1e-2, "feasibility_checks": 5,
                                              "keep_most_feasible": keep}})
    # (iterate, mean) per check; without keep_most_feasible only the iterates are judged
    script = [1, 0, 3, 2, 2, 3, 2, 1, 1, 1] if keep else [1, 3, 2, 2, 1]
    task = ScriptedVerdicts(c, script)
    after = []  # the weights after each iteration
    tr = Trainer(task, c, tmp_path, progress=False, hooks=[lambda t, step, v: after.append(_flat(t.model))])
    tr.train()
    final = _flat(tr.model)
    events = [json.loads(x) for x in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    restored = [e for e in events if e.get("event") == "restored"]
    checks = [e for e in events if e.get("event") == "feasibility"]
    if keep:
        assert torch.equal(final, task.seen[5]) and tr.callbacks[-1].last.feasible == 3
        torch.testing.assert_close(final, torch.stack(after[20:30]).mean(0), rtol=0, atol=1e-6)
        assert restored == [{"step": 50, "event": "restored", "from_step": 30, "mean": True, "mean_iterations": 10,
                             "feasible": 3, "shapes": 4, "instead_of": 1}]
        assert [e["mean"]["feasible"] for e in checks] == [0, 2, 3, 1, 1]
        assert all(e["mean"]["iterations"] == 10 for e in checks)
    else:
        assert torch.equal(final, task.seen[4]) and not restored and all("mean" not in e for e in checks)
    # nothing to restore when the last check's iterate is the best
    c2 = build_config({"seed": 0, "training": {"iterations": 20, "lr": 1e-2, "feasibility_checks": 2}})
    t2 = ScriptedVerdicts(c2, [1, 0, 2, 1])
    tr2 = Trainer(t2, c2, None, progress=False)
    tr2.train()
    assert torch.equal(_flat(tr2.model), t2.seen[2])
    assert tr2.callbacks[-1].restored is None


class ObjectiveFit(Judged):
    """Every check finds its 4 shapes feasible; the objective is a fixed linear function of the
    weights, so a mean candidate's is the mean of its iterates' (to rounding), at one volume."""

    def __init__(self, cfg):
        super().__init__(cfg)
        self.direction = None

    def feasibility(self, model):
        return FeasibilitySummary(4, 4, [{}] * 4)

    def objective(self, model):
        w = _flat(model).double()
        if self.direction is None:
            self.direction = -torch.randn(w.shape, generator=torch.Generator().manual_seed(3), dtype=torch.float64)
        return float(w @ self.direction), 0.5, False

    def callbacks(self, dist=None):
        return [FeasibilityChecks(self.feasibility, self.cfg.training, objective=self.objective)]


def test_between_feasible_candidates_the_lower_objective_is_kept(tmp_path):
    """Every candidate feasible at one volume: the run ends with the one of the lowest objective
    among the iterates and interval means of its checks, and the checks log what they measured."""
    c = build_config({"seed": 0, "training": {"iterations": 50, "lr": 1e-2, "feasibility_checks": 5}})
    task = ObjectiveFit(c)
    after = []
    tr = Trainer(task, c, tmp_path, progress=False, hooks=[lambda t, step, v: after.append(_flat(t.model))])
    tr.train()
    steps = (10, 20, 30, 40, 50)
    candidates = [after[s - 1] for s in steps] + [torch.stack(after[s - 10:s]).mean(0) for s in steps]
    values = [float(w.double() @ task.direction) for w in candidates]
    assert max(values) - min(values) > 1e-3  # the candidates differ
    assert min(values) < min(values[4], values[9]) - 1e-6  # and the last check's are not the best
    torch.testing.assert_close(_flat(tr.model).double() @ task.direction, torch.tensor(min(values), dtype=torch.float64),
                               rtol=0, atol=1e-6)
    checks = [json.loads(x) for x in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    checks = [e for e in checks if e.get("event") == "feasibility"]
    # each check measures both of its candidates, to compare them with each other
    logged = [e["objective"] for e in checks] + [e["mean"]["objective"] for e in checks]
    assert [o for o, _, _ in logged] == pytest.approx(values, abs=1e-6) and {v for _, v, _ in logged} == {0.5}


def test_a_resumed_run_keeps_what_the_uninterrupted_one_keeps(tmp_path):
    """The kept candidate's measured objective travels in the checkpoint: a run interrupted after
    its third check and resumed ends with the weights of the run that went through."""
    c = build_config({"seed": 0, "training": {"iterations": 50, "lr": 1e-2, "feasibility_checks": 5}})
    whole = Trainer(ObjectiveFit(c), c, tmp_path / "a", progress=False)
    whole.train()

    def interrupt(trainer, step, values):
        if trainer.step == 30:
            os.kill(os.getpid(), signal.SIGINT)

    first = Trainer(ObjectiveFit(c), c, tmp_path / "b", progress=False, hooks=[interrupt])
    assert first.train().status == "interrupted" and first.step == 30
    assert first.callbacks[-1].best["objective"] is not None
    again = Trainer(ObjectiveFit(c), c, tmp_path / "b", progress=False)
    assert again.resume() and again.step == 30
    assert again.callbacks[-1].best["objective"] == first.callbacks[-1].best["objective"]
    again.train()
    assert torch.equal(_flat(again.model), _flat(whole.model))
    assert again.callbacks[-1].best["objective"] == whole.callbacks[-1].best["objective"]


def test_an_earlier_candidate_is_kept_only_stiffer_and_no_heavier_or_clear_of_the_bound():
    """A higher rank wins whatever its objective; on an equal rank the later candidate (the first
    argument) is kept unless both are feasible throughout and the other is better by the objective
    while no heavier or clear of the volume bound; without an objective the later one."""
    def cand(k, objective, volume=0.5, inside=False):
        return {"summary": FeasibilitySummary(k, 4, [{}] * k + [{"interface": Violation(1.0, 0.5)}] * (4 - k)),
                "model": None, "objective": [objective, volume, inside]}

    def measured(model):
        raise AssertionError("the candidates carry their objectives")

    checks = FeasibilityChecks(lambda m: None, build_config({}).training, objective=measured)
    kept = functools.partial(checks._at_least, None)
    assert kept(cand(4, 10.0), cand(3, 1.0)) and not kept(cand(3, 1.0), cand(4, 10.0))
    assert kept(cand(4, 1.0), cand(4, 2.0)) and not kept(cand(4, 2.0), cand(4, 1.0))
    assert kept(cand(4, 1.0), cand(4, 1.0))
    assert not kept(cand(4, 2.0, 0.49), cand(4, 1.0, 0.48))  # stiffer and lighter
    assert kept(cand(4, 2.0, 0.48), cand(4, 1.0, 0.49))  # stiffer by its weight, at the bound
    assert not kept(cand(4, 2.0, 0.48), cand(4, 1.0, 0.49, inside=True))  # stiffer, clear of the bound
    assert kept(cand(3, 2.0), cand(3, 1.0)) and kept(cand(3, 1.0), cand(3, 2.0))  # not feasible throughout
    plain = FeasibilityChecks(lambda m: None, build_config({}).training)
    assert plain._at_least(None, cand(4, 2.0), cand(4, 1.0))

    class OtherRank:  # a data-parallel rank other than 0 takes rank 0's measure
        is_main = False

        def broadcast_object(self, value):
            assert value is None
            return (3.0, 0.4, True)

    ranked = FeasibilityChecks(lambda m: None, build_config({}).training, dist=OtherRank(), objective=measured)
    fresh = {**cand(4, 0.0), "objective": None}
    assert ranked._objective(None, fresh) == (3.0, 0.4, True) and fresh["objective"] == [3.0, 0.4, True]


def test_the_kept_candidate_meets_the_sets_bounds_among_equals():
    """Candidates rank by feasible shapes, then by the set's bounds (a least diversity), then by
    feasible held-out codes."""
    short = {"diversity": Violation(0.046, 0.05)}

    def summary(k, set_violations=None, heldout=0):
        return FeasibilitySummary(k, 4, [{}] * k + [{"interface": Violation(1.0, 0.5)}] * (4 - k),
                                  set_violations=set_violations or {}, heldout=FeasibilitySummary(heldout, 8, [{}] * 8))

    ranked = [summary(4, short, heldout=8), summary(4, heldout=2), summary(3, heldout=8), summary(3, short, heldout=8),
              summary(4, heldout=3)]
    best = sorted(ranked, key=lambda c: c.rank(), reverse=True)
    assert [(c.feasible, bool(c.set_violations), c.heldout.feasible) for c in best] == [
        (4, False, 3), (4, False, 2), (4, True, 8), (3, False, 8), (3, True, 8)]


def test_a_least_diversity_is_a_bound_on_the_set():
    # two concentric circles r and r + 0.1: each side of the chamfer discrepancy is 0.1, so
    # CD2 = 0.1 sqrt(2) and for two shapes diversity_mean = CD2
    from dataclasses import replace

    from ginn.geometry.base import Box
    from ginn.geometry.interfaces import Circle
    from ginn.problems.problem import Problem

    P = Problem("t", Box((-1.0, -1.0), (1.0, 1.0)), interfaces=(Circle((0.0, 0.0), 0.35),),
                tolerances=Tolerances(interface=0.2, connected=False, diversity=0.2))
    def rings(x, z):
        return x.norm(dim=-1) - (0.3 + z[..., 0])

    Z = torch.tensor([[0.0], [0.1]], dtype=torch.float64)
    s = check_feasibility(rings, Z, P, 256)
    assert s.feasible == 2
    d = s.set_violations["diversity"]
    assert d.bound == pytest.approx(0.2) and d.value == pytest.approx(0.1 * np.sqrt(2), rel=0.01)
    assert s.ratios["diversity"] == pytest.approx(0.2 / d.value)
    assert "the set: diversity 0.14" in format_feasibility(s)
    met = check_feasibility(rings, Z, replace(P, tolerances=Tolerances(interface=0.2, connected=False, diversity=0.1)), 256)
    assert met.set_violations == {} and met.ratios["diversity"] == pytest.approx(0.1 / (0.1 * np.sqrt(2)), rel=0.01)
    # ginn eval reports the same bound; without a stated least diversity there is none
    assert evaluate_shapes(rings, Z, P, 256).feasibility.set_violations["diversity"].value == pytest.approx(
        0.1 * np.sqrt(2), rel=0.01)
    assert "diversity" not in check_feasibility(rings, Z, replace(P, tolerances=Tolerances(interface=0.2, connected=False)), 256).ratios


def test_the_run_records_the_spec_it_trained(tmp_path):
    """A spec changed in memory (a topology target added) is what ``problem.yaml`` holds and what
    ``ginn eval`` judges; an unchanged spec's file is copied as it is."""
    from ginn.problems import load_spec
    from ginn.problems.spec import TopologySpec

    over = {"training": {"iterations": 2, "feasibility_checks": 0}, "latents": {"n_shapes": 1},
            "model": {"hidden": [8, 8]}, "sampling": {"n_domain": 64, "n_interface": 16}}
    spec, cfg = runs.resolve("obstacle", "demo", over)
    plain = runs.train(spec, cfg, tmp_path / "plain", progress=False, results=False).run_dir
    assert (plain / "problem.yaml").read_bytes() == open(spec.source, "rb").read()
    holes = spec.model_copy(update={"topology": TopologySpec.model_validate({"holes": 2}, context={"dim": 2})})
    run = runs.train(holes, cfg, tmp_path / "holes", progress=False, results=False).run_dir
    assert load_spec(run / "problem.yaml").build().topology.targets == {1: 2}
    verdict = runs.evaluate(run, resolution=64)["feasibility"]["violations"][0]
    assert verdict["topology"]["bound"] == {"holes": 2}


def test_typed_results_round_trip_through_their_json(obstacle):
    """A summary and the metrics of a shape are objects in the code and the same JSON on disk."""
    from ginn.eval.results import ShapeMetrics

    shapes = [ShapeMetrics(interface_cd1=9e-3, volume_outside=0.02, volume_outside_off_interfaces=0.01,
                           b0_in_design_region=2, connected_interfaces_share=0.5, extra={"thickness": 0.1}),
              ShapeMetrics(interface_cd1=float("inf"), volume_outside=0.0, b0_in_design_region=1,
                           connected_interfaces_share=1.0)]
    data = [m.to_json() for m in shapes]
    assert data[1]["interface_cd1"] is None and data[0]["thickness"] == 0.1  # strict JSON; extras kept
    back = [ShapeMetrics.from_json(d) for d in data]
    assert back[0] == shapes[0] and back[1] == shapes[1].finite() and back[0].get("thickness") == 0.1
    s = summarize(back, obstacle, diversity=0.3)  # as the check and ginn eval judge: undefined values as None
    js = json.loads(json.dumps(s.to_json(), allow_nan=False))
    assert FeasibilitySummary.from_json(js) == s and s.to_json() == js
    assert js["violations"][0]["connected"] == {"value": 2, "bound": 1, "interfaces": 0.5}
    assert s.violated_counts() == {"interface": 2, "volume_outside": 1, "connected": 1} and not s.all_feasible
