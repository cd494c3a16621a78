"""The generic trainer: schedule, skipping non-finite steps, rollback, resume, signals, safe checkpoints."""

import os
import pickle
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import torch

from ginn.config import LossTerm, build_config
from ginn.models import MLP
from ginn.train.callbacks import Hook, LBFGSPhase
from ginn.train.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from ginn.train.task import Task
from ginn.train.trainer import Trainer


class CircleFit(Task):
    """Fit f(x) = |x| - 0.5 on fresh samples; optionally return NaN at chosen steps."""

    kind = "toy"

    def __init__(self, cfg, device="cpu", dtype=torch.float32, nan_steps=()):
        super().__init__(cfg, device, dtype)
        self.nan_steps = set(nan_steps)

    def build_model(self):
        return MLP(2, [16, 16])

    def terms(self):
        return {"fit": LossTerm(weight=1.0), "late": LossTerm(weight=0.5, start=5)}

    def loss_terms(self, model, step, active, gen):
        x = torch.rand(64, 2, generator=gen, dtype=self.dtype) * 2 - 1
        r = model(x) - (x.norm(dim=-1) - 0.5)
        out = {"fit": r.pow(2).mean()}
        if "late" in active:
            out["late"] = r.abs().mean()
        if step in self.nan_steps:
            self.nan_steps.discard(step)  # fail once at this step
            out["fit"] = out["fit"] * float("nan")
        return out


def cfg(**training):
    t = {"iterations": 30, "lr": 1e-2, "log_every": 1, "checkpoint_every": 10}
    t.update(training)
    return build_config({"training": t, "seed": 3})


def weights(model):
    return torch.cat([p.detach().flatten() for p in model.parameters()])


def test_lr_schedule_halves_every_k():
    c = cfg(iterations=20, lr_decay_every=10, lr_decay=0.5)
    tr = Trainer(CircleFit(c), c, None, progress=False)
    tr.train()
    assert tr.optimizer.param_groups[0]["lr"] == pytest.approx(1e-2 * 0.25, rel=1e-9)


def test_lr_restart_jumps_to_lr_restart_and_decays_from_there():
    """lr 1e-2 halved every 10; at iteration 15 it restarts at 4e-3: lr(14) = 1e-2 * 0.5^1.4,
    lr(15) = 4e-3, lr(25) = 2e-3."""
    c = cfg(iterations=26, lr_decay_every=10, lr_decay=0.5, lr_restart_at=15, lr_restart=4e-3)
    tr = Trainer(CircleFit(c), c, None, progress=False)
    seen = {}
    step = tr.scheduler.step

    def record():
        step()
        seen[tr.scheduler.last_epoch] = tr.optimizer.param_groups[0]["lr"]

    tr.scheduler.step = record
    tr.train()
    assert seen[14] == pytest.approx(1e-2 * 0.5**1.4, rel=1e-9)
    assert seen[15] == pytest.approx(4e-3, rel=1e-9)
    assert seen[25] == pytest.approx(2e-3, rel=1e-9)


def test_start_iteration_switches_term_on(tmp_path):
    c = cfg(iterations=8)
    tr = Trainer(CircleFit(c), c, tmp_path, progress=False)
    tr.train()
    import json

    recs = [json.loads(line) for line in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    steps = {r["step"]: r for r in recs if "fit" in r}
    assert "late" not in steps[4] and "late" in steps[5]


def test_non_finite_step_is_skipped(tmp_path):
    c = cfg(iterations=10)
    task = CircleFit(c, nan_steps={4})
    tr = Trainer(task, c, tmp_path, progress=False)
    seen = []
    tr.callbacks.insert(0, Hook(lambda t, step, v: seen.append(torch.isfinite(weights(t.model)).all().item())))
    res = tr.train()
    assert all(seen) and torch.isfinite(weights(res.model)).all()
    log = (tmp_path / "metrics.jsonl").read_text()
    assert "skipped_non_finite" in log
    assert res.step == 10


def test_repeated_failures_roll_back_with_lower_lr(tmp_path):
    c = cfg(iterations=25, max_bad_steps=3, checkpoint_every=5)
    task = CircleFit(c)
    tr = Trainer(task, c, tmp_path, progress=False)
    # step 12 fails three times in a row, then the rollback to step 10 recovers
    calls = {"n": 0}
    orig = task.loss_terms

    def flaky(model, step, active, gen):
        out = orig(model, step, active, gen)
        if step == 12 and calls["n"] < 3:
            calls["n"] += 1
            out["fit"] = out["fit"] * float("inf")
        return out

    task.loss_terms = flaky
    res = tr.train()
    assert tr.rollbacks == 1 and tr.lr_scale == pytest.approx(0.5)
    assert "rollback" in (tmp_path / "metrics.jsonl").read_text()
    assert res.step == 25 and torch.isfinite(weights(res.model)).all()


def test_persistent_failure_gives_up_with_error(tmp_path):
    from ginn.train.trainer import TrainingDiverged

    c = cfg(iterations=25, max_bad_steps=2, checkpoint_every=5, max_rollbacks=2)
    task = CircleFit(c)
    orig = task.loss_terms

    def always_bad(model, step, active, gen):
        out = orig(model, step, active, gen)
        if step >= 7:
            out["fit"] = out["fit"] * float("nan")
        return out

    task.loss_terms = always_bad
    tr = Trainer(task, c, tmp_path, progress=False)
    with pytest.raises(TrainingDiverged):
        tr.train()
    assert tr.rollbacks == 2 and torch.isfinite(weights(tr.model)).all()


def test_resume_is_bitwise_identical(tmp_path):
    c = cfg(iterations=30, checkpoint_every=10)
    full = Trainer(CircleFit(c), c, tmp_path / "a", progress=False).train()
    # interrupted run: stop after 17 iterations (last checkpoint at 10), then resume in a new trainer
    c17 = cfg(iterations=17, checkpoint_every=10)
    part = Trainer(CircleFit(c17), c17, tmp_path / "b", progress=False)
    part.train()
    # simulate a kill: the checkpoint on disk is the one from the end of the partial run (step 17)
    resumed = Trainer(CircleFit(c), c, tmp_path / "b", progress=False)
    assert resumed.resume() and resumed.step == 17
    out = resumed.train()
    assert torch.equal(weights(full.model), weights(out.model))


def test_atomic_checkpoint_and_malicious_pickle_refused(tmp_path):
    p = tmp_path / "ck.pt"
    save_checkpoint(p, {"model": {"w": torch.ones(3)}, "step": 4})
    assert load_checkpoint(p)["step"] == 4
    assert not list(tmp_path.glob("*.tmp"))
    marker = tmp_path / "pwned"

    class Evil:
        def __reduce__(self):
            return (os.system, (f"touch {marker}",))

    bad = tmp_path / "evil.pt"
    with open(bad, "wb") as fh:
        pickle.dump({"model": Evil()}, fh)
    with pytest.raises(CheckpointError, match="refusing"):
        load_checkpoint(bad)
    assert not marker.exists()
    torch.save({"model": Evil()}, tmp_path / "evil2.pt")
    assert not marker.exists()  # saving does not run it; loading must not either
    with pytest.raises(CheckpointError):
        load_checkpoint(tmp_path / "evil2.pt")
    assert not marker.exists()


SCRIPT = textwrap.dedent(
    """
    import sys, time, torch
    sys.path.insert(0, {tests!r})
    from test_trainer import CircleFit, cfg
    from ginn.train.callbacks import Hook
    from ginn.train.trainer import Trainer
    c = cfg(iterations=100000, checkpoint_every=1000000)
    task = CircleFit(c)
    tr = Trainer(task, c, {run!r}, progress=False)
    tr.callbacks.insert(0, Hook(lambda t, s, v: (print("step", s, flush=True), time.sleep(0.01))))
    res = tr.train()
    print("status", res.status, res.step, flush=True)
    """
)


@pytest.mark.long
def test_sigterm_writes_checkpoint_and_exits_cleanly(tmp_path):
    run = tmp_path / "run"
    code = SCRIPT.format(tests=str(Path(__file__).parent), run=str(run))
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    for line in proc.stdout:
        if line.startswith("step 5"):
            break
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 0
    assert "status interrupted" in out
    ck = load_checkpoint(run / "checkpoints" / "last.pt")
    assert ck["step"] >= 6


def test_plain_progress_for_a_log_file():
    """Outside a terminal, progress is one plain line per tenth of the run (no carriage returns)."""
    import io

    from ginn.train.callbacks import PlainProgress

    out = io.StringIO()
    p = PlainProgress(100, initial=0, seconds=1e9, stream=out)
    for i in range(100):
        p.set_postfix({"total": f"{1.0 / (i + 1):.2e}"})
        p.update(1)
    lines = out.getvalue().splitlines()
    assert len(lines) == 10 and "\r" not in out.getvalue()
    assert lines[0].startswith("iteration 10/100 (10 %") and lines[-1].startswith("iteration 100/100 (100 %")
    assert lines[-1].endswith("total 1.00e-02")


class PolynomialFit(Task):
    """Least squares: f(x) = w . (1, x, y, x^2, x y, y^2) fitted to a known member of that span,
    so the minimum is 0 at the known coefficients. Records the points of every evaluation."""

    kind = "toy"
    TRUE = torch.tensor([0.3, -1.0, 0.5, 2.0, -0.7, 1.2], dtype=torch.float64)

    def __init__(self, cfg, device="cpu", dtype=torch.float64):
        super().__init__(cfg, device, dtype)
        self.seen: list[tuple[int, float]] = []

    def build_model(self):
        return torch.nn.Linear(6, 1, bias=False)

    def terms(self):
        return {"fit": LossTerm(weight=1.0)}

    @staticmethod
    def features(x):
        return torch.stack([torch.ones_like(x[:, 0]), x[:, 0], x[:, 1], x[:, 0] ** 2, x[:, 0] * x[:, 1], x[:, 1] ** 2], 1)

    def loss_terms(self, model, step, active, gen):
        x = torch.rand(32, 2, generator=gen, dtype=self.dtype) * 2 - 1
        self.seen.append((step, float(x.sum())))
        phi = self.features(x)
        return {"fit": (model(phi).squeeze(-1) - phi @ self.TRUE).pow(2).mean()}


def _phase(trainer) -> LBFGSPhase:
    return next(c for c in trainer.callbacks if isinstance(c, LBFGSPhase))


def test_lbfgs_phase_reaches_the_least_squares_minimum_on_one_sample():
    c = build_config({"training": {"iterations": 5, "lbfgs_steps": 3, "lr": 1e-2, "log_every": 1,
                                   "dtype": "float64", "feasibility_checks": 0}, "seed": 0})
    task = PolynomialFit(c)
    tr = Trainer(task, c, None, progress=False)
    out = tr.train()
    assert tr.step == 8 and isinstance(_phase(tr).optimizer, torch.optim.LBFGS)
    w = out.model.weight.detach().reshape(-1)
    # Adam alone is 2.3 off after 5 steps; L-BFGS stops when the loss changes by less than 1e-9
    assert (w - PolynomialFit.TRUE).abs().max().item() < 1e-4
    phase = [v for s, v in task.seen if s >= 5]
    assert len(phase) > 10 and len(set(phase)) == 1  # every evaluation of the phase sees the same points
    assert len({v for s, v in task.seen if s < 5}) == 5  # Adam: a fresh sample every step


def test_resume_in_the_lbfgs_phase_is_bitwise_identical(tmp_path):
    def config(lbfgs):
        return build_config({"training": {"iterations": 6, "lbfgs_steps": lbfgs, "lr": 1e-2, "log_every": 1,
                                          "checkpoint_every": 4, "feasibility_checks": 0}, "seed": 1})

    full = Trainer(CircleFit(config(8)), config(8), tmp_path / "a", progress=False).train()
    Trainer(CircleFit(config(3)), config(3), tmp_path / "b", progress=False).train()  # stops inside the phase
    resumed = Trainer(CircleFit(config(8)), config(8), tmp_path / "b", progress=False)
    assert resumed.resume() and resumed.step == 9 and _phase(resumed).state_dict() is not None
    out = resumed.train()
    assert torch.equal(weights(full.model), weights(out.model))
