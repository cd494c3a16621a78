"""The generic training loop: Adam, exponential schedule, clipping, balancing, checkpoints.

Reliability guarantees:

* A non-finite loss or gradient never reaches the weights: the step is skipped and logged. After
  ``max_bad_steps`` consecutive bad steps the run rolls back to the last checkpoint and continues
  with the learning rate multiplied by ``rollback_lr_factor``.
* SIGINT / SIGTERM finish the current step, write a checkpoint and stop cleanly (status
  ``"interrupted"``); ``ginn resume RUN_DIR`` continues. A checkpoint is written every
  ``checkpoint_every`` iterations or ``checkpoint_seconds`` of training, whichever comes first, so
  after ``kill -9`` at most that much work is lost.
* On CPU, resuming reproduces an uninterrupted run bitwise from any checkpoint: the checkpoint
  holds the model, optimiser, scheduler, balancer, task state (e.g. the connectedness loss's
  critical points and surface network) and every RNG state; ``metrics.jsonl`` is cut back to it.
* ``status.json`` tells the truth: ``running`` with the step and a heartbeat refreshed at every
  checkpoint, then ``completed``, ``interrupted``, ``failed`` (with the one-line reason) or a
  hook's status. A write that fails (full disk, read-only directory) is one line that names the
  file and says that the last checkpoint is intact.
"""

from __future__ import annotations

import json
import math
import signal
import sys
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import torch
from torch import Tensor, nn

from ..config import DTYPES, RunConfig, TrainingConfig
from ..errors import ConfigError, GinnError
from ..eval.feasibility import short_summary
from ..models import compile_derivatives
from .balancing import make_balancer
from .checkpoint import load_checkpoint, rng_state, save_checkpoint, set_rng_state
from .distributed import DistContext
from .rundir import io_error, truncate_metrics, write_status
from .task import Task
from .tblog import TensorBoardLog, tensorboard_available


class TrainingDiverged(GinnError):
    """Non-finite losses persist even after rolling back with lower learning rates."""


def candidate_ratios(iterate: dict[str, float | None], mean: dict[str, float | None] | None) -> dict[str, float | None]:
    """Each constraint's ratio to its bound in the better of the two candidates a check can keep:
    the iterate and the mean of the weights since the previous check (``None``: undefined, worse
    than any number). A constraint that one candidate meets needs no larger multiplier: the run
    can end with that candidate, and what separates the two is the optimiser's noise."""
    if not mean:
        return dict(iterate)

    def better(a, b):
        return b if a is None else a if b is None else min(a, b)

    return {k: better(v, mean.get(k)) for k, v in iterate.items()}


class StopRun(Exception):
    """Raised by a hook to end a run early: the trainer writes a checkpoint and returns with
    ``status`` (e.g. ``"pruned"`` for a sweep trial that the pruner stopped)."""

    def __init__(self, status: str, reason: str = ""):
        super().__init__(reason or status)
        self.status = status


def lr_factor(t: TrainingConfig, it: int) -> float:
    """Learning rate at iteration ``it`` relative to ``t.lr``: ``lr_decay^(it / lr_decay_every)``, and
    from ``lr_restart_at`` (if > 0) on ``lr_restart / lr * lr_decay^((it - lr_restart_at) / lr_decay_every)``."""
    if t.lr_restart_at > 0 and it >= t.lr_restart_at:
        return t.lr_restart / t.lr * t.lr_decay ** ((it - t.lr_restart_at) / t.lr_decay_every)
    return t.lr_decay ** (it / t.lr_decay_every)


@dataclass
class TrainResult:
    """What :meth:`Trainer.train` returns."""

    model: nn.Module
    status: str  # "completed" | "interrupted" | a StopRun's status
    step: int
    seconds: float
    last_losses: dict[str, float]
    reason: str = ""


class PlainProgress:
    """Progress for a log file (stderr not a terminal): one plain line every tenth of the run or
    every ``seconds``, whichever comes first, instead of a redrawn bar. The same calls as tqdm's
    that the trainer makes (``update``, ``set_postfix``, ``close``)."""

    def __init__(self, total: int, initial: int = 0, seconds: float = 60.0, stream=None):
        self.total, self.n, self.seconds = total, initial, seconds
        self.stream = stream if stream is not None else sys.stderr
        self.every = max(1, total // 10)
        self.t0 = self.last = time.monotonic()
        self.postfix: dict = {}

    def update(self, k: int = 1) -> None:
        self.n += k
        now = time.monotonic()
        if self.n % self.every == 0 or self.n == self.total or now - self.last >= self.seconds:
            self.last = now
            terms = ", ".join(f"{k} {v}" for k, v in self.postfix.items())
            self.stream.write(f"iteration {self.n}/{self.total} ({100 * self.n / max(self.total, 1):.0f} %, "
                              f"{now - self.t0:.0f} s)" + (f": {terms}" if terms else "") + "\n")
            self.stream.flush()

    def set_postfix(self, values: dict, refresh: bool = False) -> None:
        self.postfix = dict(values)

    def close(self) -> None:
        pass


class _StopFlag:
    def __init__(self) -> None:
        self.stop = False
        self.signum: int | None = None
        self._old: dict[int, object] = {}

    def __enter__(self) -> _StopFlag:
        for s in (signal.SIGINT, signal.SIGTERM):
            try:
                self._old[s] = signal.signal(s, self._handle)
            except ValueError:  # not in the main thread
                pass
        return self

    def _handle(self, signum, frame) -> None:
        if self.stop and signum == signal.SIGINT:  # second Ctrl-C: give up at once
            raise KeyboardInterrupt
        self.stop, self.signum = True, signum

    def __exit__(self, *exc) -> None:
        for s, h in self._old.items():
            signal.signal(s, h)


class Trainer:
    """Trains one :class:`Task`.

    Arguments:
        task: the problem (builds the model, returns unweighted loss terms).
        cfg: the resolved run configuration.
        run_dir: where metrics.jsonl and checkpoints go (None: nothing is written).
        progress: show a progress bar.
        hooks: optional callables ``hook(trainer, step, losses)`` run after each step.
        dist: a :class:`ginn.train.distributed.DistContext` for data-parallel training (torchrun):
            the task trains its shard, losses and gradients are averaged over ranks, only rank 0
            writes; None: a single process.
    """

    def __init__(
        self,
        task: Task,
        cfg: RunConfig,
        run_dir: str | Path | None = None,
        progress: bool = True,
        hooks: list[Callable] | None = None,
        dist: DistContext | None = None,
    ):
        self.task, self.cfg = task, cfg
        self.dist = dist
        self.is_main = dist is None or dist.is_main
        self.run_dir = Path(run_dir) if run_dir is not None else None
        if self.run_dir is not None and self.is_main:
            self.run_dir.mkdir(parents=True, exist_ok=True)
        self.progress = progress and self.is_main
        self.hooks = hooks or []
        self.device = torch.device(cfg.device)
        self.dtype = DTYPES[cfg.training.dtype]
        if cfg.training.threads > 0:
            torch.set_num_threads(cfg.training.threads)
        torch.manual_seed(cfg.seed)
        self.gen = torch.Generator(device=self.device).manual_seed(cfg.seed)
        self.model = task.build_model().to(device=self.device, dtype=self.dtype)
        compile_derivatives(self.model, cfg.training.compile)
        if dist is not None:
            task.distribute(dist)
            dist.broadcast_parameters(self.model)
        t = cfg.training
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=t.lr)
        self.lr_scale = 1.0
        self.scheduler = torch.optim.lr_scheduler.LambdaLR(self.optimizer, lambda it: lr_factor(t, it))
        self.terms = task.terms()
        if not any(term.weight > 0 for term in self.terms.values()):
            raise ConfigError(f"no active loss term: every loss weight of this {task.kind} problem is 0 "
                              f"(terms: {', '.join(sorted(self.terms)) or 'none'}); set losses.<term>.weight")
        first = min(term.start for term in self.terms.values() if term.weight > 0)
        if first > 0:
            raise ConfigError(f"no loss term is active at iteration 0 (the earliest start is {first}); "
                              "set losses.<term>.start = 0 for at least one term")
        self.balancer = make_balancer(self.terms, cfg.balancing, task.constraint_targets(), task.constraint_terms(),
                                      task.bounded_objectives())
        self.step = 0
        self.bad_steps = 0
        self.rollbacks = 0
        self.elapsed = 0.0
        self._saved_at = 0.0  # training time of the last checkpoint
        self._step_seconds = 0.0  # the longest iteration so far
        self.feasibility: dict | None = None  # the last feasibility check's summary
        self._objective = [0.0, 0]  # sum and count of the objective terms since the last check
        self._objective_before: float | None = None  # their mean over the interval before
        self.best: dict | None = None  # the check with the most feasible shapes: step, summary, weights
        # keep_most_feasible: the running mean of the weights since the previous check, and its count
        self._mean: dict[str, Tensor] | None = None
        self._mean_count = 0
        self._averaging = (cfg.training.keep_most_feasible and dist is None and cfg.training.feasibility_checks > 0)
        self.restored: dict | None = None  # the 'restored' event, when the run ended with the best weights
        # training.lbfgs_steps: the L-BFGS optimiser of the final phase and the generator state
        # that fixes its sample (created at the phase's first step)
        self.lbfgs: torch.optim.LBFGS | None = None
        self._lbfgs_sample: Tensor | None = None
        self._tb: TensorBoardLog | None = None  # opened by train() with training.log: [..., tensorboard]
        if "tensorboard" in cfg.training.log and not tensorboard_available():
            raise ConfigError("training.log: tensorboard needs the tensorboard package (pip install 'ginn[track]')")

    # --- checkpoints -------------------------------------------------------------------------

    @property
    def checkpoint_path(self) -> Path | None:
        return None if self.run_dir is None else self.run_dir / "checkpoints" / "last.pt"

    def state_dict(self) -> dict:
        """The checkpoint; distributed: a collective (every rank's task and RNG state under "ranks")."""
        state = {
            "format": "ginn-checkpoint-1",
            "step": self.step,
            "elapsed": self.elapsed,
            "lr_scale": self.lr_scale,
            "rollbacks": self.rollbacks,
            "bad_steps": self.bad_steps,
            "model": self.model.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "scheduler": self.scheduler.state_dict(),
            "balancer": self.balancer.state_dict(),
            "task": self.task.state_dict(),
            "rng": rng_state(self.gen),
            "lbfgs": None if self.lbfgs is None else {"optimizer": self.lbfgs.state_dict(), "sample": self._lbfgs_sample},
            "feasibility": {"last": self.feasibility, "objective": list(self._objective),
                            "objective_before": self._objective_before, "best": self.best,
                            "mean": self._mean, "mean_count": self._mean_count, "averaging": self._averaging},
        }
        if self.dist is not None:
            state["ranks"] = self.dist.gather_objects({"task": self.task.state_dict(), "rng": rng_state(self.gen)})
        return state

    def load_state_dict(self, state: dict) -> None:
        self.model.load_state_dict(state["model"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.scheduler.load_state_dict(state["scheduler"])
        self.balancer.load_state_dict(state["balancer"])
        ranks = state.get("ranks") if self.dist is not None else None
        if ranks is not None and len(ranks) == self.dist.world:  # same world size: exact continuation
            self.task.load_state_dict(ranks[self.dist.rank]["task"])
            set_rng_state(ranks[self.dist.rank]["rng"], self.gen)
        else:
            self.task.load_state_dict(state["task"])
            set_rng_state(state["rng"], self.gen)
        lbfgs = state.get("lbfgs")
        if lbfgs is not None:
            self._start_lbfgs(lbfgs["sample"])
            self.lbfgs.load_state_dict(lbfgs["optimizer"])
        self.step = int(state["step"])
        self.elapsed = float(state.get("elapsed", 0.0))
        self.lr_scale = float(state.get("lr_scale", 1.0))
        self.rollbacks = int(state.get("rollbacks", 0))
        self.bad_steps = int(state.get("bad_steps", 0))
        feas = state.get("feasibility") or {}
        self.feasibility = feas.get("last")
        self._objective = list(feas.get("objective", [0.0, 0]))
        self._objective_before = feas.get("objective_before")
        self.best = feas.get("best")
        self._mean = feas.get("mean")
        self._mean_count = int(feas.get("mean_count", 0))
        self._averaging = bool(feas.get("averaging", self._averaging))
        self._saved_at = self.elapsed
        self._apply_lr_scale()

    def save(self) -> None:
        """Write the checkpoint (atomically) and refresh the heartbeat of ``status.json``."""
        if self.checkpoint_path is not None:
            state = self.state_dict()
            if self.is_main:
                try:
                    save_checkpoint(self.checkpoint_path, state)
                except OSError as e:
                    raise GinnError(f"{io_error(e, self.checkpoint_path)}; {self._intact()}") from None
                self._status("running")
            if self.dist is not None:
                self.dist.barrier()
        self._saved_at = self.elapsed

    def resume(self) -> bool:
        """Load the last checkpoint of ``run_dir`` if there is one, and cut ``metrics.jsonl`` back
        to it. Returns whether it did."""
        p = self.checkpoint_path
        if p is None or not p.exists():
            return False
        self.load_state_dict(load_checkpoint(p, map_location=self.device))
        if self.run_dir is not None and self.is_main:
            truncate_metrics(self.run_dir / "metrics.jsonl", self.step)
        return True

    def _status(self, status: str, reason: str = "") -> None:
        if self.run_dir is not None and self.is_main:
            every = max(self.cfg.training.checkpoint_seconds, self._step_seconds)
            write_status(self.run_dir, status, self.step, self.elapsed, reason, heartbeat_every=every)

    def _apply_lr_scale(self) -> None:
        t = self.cfg.training
        self.scheduler.base_lrs = [t.lr * self.lr_scale for _ in self.scheduler.base_lrs]
        for g in self.optimizer.param_groups:
            g["lr"] = t.lr * self.lr_scale * lr_factor(t, self.scheduler.last_epoch)

    def _rollback(self) -> None:
        if self.rollbacks >= self.cfg.training.max_rollbacks:
            self._log({"step": self.step, "event": "diverged"})
            raise TrainingDiverged(
                f"training diverged: non-finite losses persisted through {self.rollbacks} rollbacks at iteration {self.step}; "
                "lower training.lr or the loss weights"
            )
        rollbacks, scale = self.rollbacks + 1, self.lr_scale * self.cfg.training.rollback_lr_factor
        p = self.checkpoint_path
        if p is not None and p.exists():
            self.load_state_dict(load_checkpoint(p, map_location=self.device))
        self.rollbacks, self.lr_scale = rollbacks, scale
        self._apply_lr_scale()
        self.bad_steps = 0
        self._log({"step": self.step, "event": "rollback", "lr_scale": self.lr_scale})

    # --- logging -------------------------------------------------------------------------------

    def _log(self, record: dict) -> None:
        if self.run_dir is None or not self.is_main:
            return
        path = self.run_dir / "metrics.jsonl"
        try:
            with open(path, "a") as fh:
                fh.write(json.dumps(record) + "\n")
        except OSError as e:
            raise GinnError(f"{io_error(e, path)}; {self._intact()}") from None
        if self._tb is not None:
            self._tb.write(record)

    def log_figures(self, paths: list[Path]) -> None:
        """Add the run's result figures to the TensorBoard log (when it is on), at the last step."""
        if self._tb is not None:
            self._tb.figures(paths, self.step)

    def close(self) -> None:
        """Flush and close the TensorBoard log (a later ``train`` opens it again)."""
        if self._tb is not None:
            self._tb.close()
            self._tb = None

    # --- the loop ------------------------------------------------------------------------------

    def _checkpoint_due(self) -> bool:
        """Every ``checkpoint_every`` iterations, or when ``checkpoint_seconds`` of training have
        passed since the last checkpoint (decided on rank 0's clock under torchrun)."""
        t = self.cfg.training
        due = self.step % t.checkpoint_every == 0 or self.elapsed - self._saved_at >= t.checkpoint_seconds
        if self.dist is not None:
            due = self.dist.broadcast_object(due)
        return due

    def _intact(self) -> str:
        """What is left after a failed write: the last checkpoint, which a failed write never touches."""
        p = self.checkpoint_path
        if p is not None and p.is_file():
            return f"the last checkpoint ({p}) is intact; `ginn resume {self.run_dir}` continues from it"
        return "no checkpoint had been written yet"

    def _try_status(self, status: str, reason: str) -> None:
        """Record how the run ended, if the disk still lets us (the original error is what matters)."""
        try:
            self._status(status, reason)
        except GinnError:
            pass

    def _check_due(self) -> bool:
        """After the step that completes one of ``feasibility_checks`` equal parts of the run (one
        process only: under torchrun each rank holds a share of the shapes)."""
        t = self.cfg.training
        if t.feasibility_checks <= 0 or self.dist is not None or t.iterations <= 0:
            return False
        every = max(1, math.ceil(t.iterations / t.feasibility_checks))
        return self.step % every == 0 or self.step in (t.iterations, self.total_iterations)

    def _checks_left(self) -> int:
        """How many checks come after the current step (the last one at the final iteration)."""
        t = self.cfg.training
        every = max(1, math.ceil(t.iterations / max(1, t.feasibility_checks)))
        return max(0, math.ceil((t.iterations - self.step) / every))

    @property
    def total_iterations(self) -> int:
        """The Adam iterations and the L-BFGS steps after them."""
        return self.cfg.training.iterations + self.cfg.training.lbfgs_steps

    def _check_feasibility(self) -> dict | None:
        """Check the shapes against the problem's tolerances, log the summary (an event: ``step``
        is the number of completed iterations) and decide whether ``stop_when_feasible`` ends the
        run (raises :class:`StopRun`)."""
        summary = self.task.feasibility(self.model)
        if summary is None:
            self._averaging, self._mean = False, None  # a task without tolerances: nothing to choose
            return None
        self.feasibility = summary
        record = {"step": self.step, "event": "feasibility", "feasible": summary["feasible"], "shapes": summary["shapes"],
                  "worst": summary["worst"], "violated": _violated_counts(summary)}
        if summary.get("ratios") is not None:
            record["ratios"] = summary["ratios"]
        interval_mean, n_mean, self._mean, self._mean_count = self._mean, self._mean_count, None, 0
        averaged = None
        if self.cfg.training.keep_most_feasible and interval_mean is not None and n_mean > 1:
            averaged = self._judge(interval_mean)
            record["mean"] = {"feasible": averaged["feasible"], "worst": averaged["worst"], "iterations": n_mean}
            if averaged.get("ratios") is not None:
                record["mean"]["ratios"] = averaged["ratios"]
        raised = {}
        if self.step < self.cfg.training.iterations:  # not at the end, nor in the L-BFGS phase
            ratios = candidate_ratios(summary.get("ratios") or {}, None if averaged is None else averaged.get("ratios"))
            raised = self.balancer.on_check(ratios, self._checks_left())
        if raised:
            record["raised"] = {k: round(v, 4) for k, v in raised.items()}
        if self.cfg.training.keep_most_feasible:
            candidates = [(summary, None)]
            if averaged is not None:
                candidates.append((averaged, interval_mean))
            # the mean wins a tie: it is the centre of what the weights did over the interval
            top, weights = max(reversed(candidates), key=lambda c: c[0]["feasible"])
            if self.best is None or top["feasible"] >= self.best["summary"]["feasible"]:
                if weights is None:
                    weights = {k: v.detach().clone() for k, v in self.model.state_dict().items()}
                self.best = {"step": self.step, "summary": top, "model": weights, "mean": top is not summary,
                             "mean_iterations": n_mean if top is not summary else 0}
        self._log(record)
        total, count = self._objective
        mean = total / count if count else None
        before, self._objective_before, self._objective = self._objective_before, mean, [0.0, 0]
        if (self.cfg.training.stop_when_feasible and summary["feasible"] == summary["shapes"]
                and not summary.get("set_violations")
                and mean is not None and before is not None
                and abs(before - mean) <= 0.01 * max(abs(before), abs(mean), 1e-12)):
            raise StopRun("completed", f"every shape feasible and the objectives steady at iteration {self.step}")
        return summary

    def _judge(self, weights: dict[str, Tensor]) -> dict:
        """The feasibility summary of the model with ``weights`` (its own weights are put back)."""
        own = {k: v.detach().clone() for k, v in self.model.state_dict().items()}
        self.model.load_state_dict(weights)
        try:
            return self.task.feasibility(self.model)
        finally:
            self.model.load_state_dict(own)

    def _accumulate_mean(self) -> None:
        """Add the current weights to the running mean since the previous check."""
        state = self.model.state_dict()
        self._mean_count += 1
        if self._mean is None:
            self._mean = {k: v.detach().clone() for k, v in state.items()}
            return
        w = 1.0 / self._mean_count
        for k, v in state.items():
            if v.is_floating_point():
                self._mean[k].lerp_(v.detach(), w)
            else:
                self._mean[k].copy_(v)

    def _restore_most_feasible(self) -> None:
        """``training.keep_most_feasible``: end with the weights of the check (the iterate there,
        or the mean of the weights since the check before it) that found the most feasible
        shapes, the latest of equals, when those are not the last iterate's."""
        best, last = self.best, self.feasibility
        if best is None or last is None or (best["step"] == self.step and not best.get("mean", False)):
            return
        self.model.load_state_dict(best["model"])
        self.feasibility = best["summary"]
        self.restored = {"step": self.step, "event": "restored", "from_step": best["step"], "mean": best.get("mean", False),
                         "mean_iterations": best.get("mean_iterations", 0),
                         "feasible": best["summary"]["feasible"], "shapes": best["summary"]["shapes"],
                         "instead_of": last["feasible"]}
        self._log(self.restored)

    def _track_objective(self, values: dict[str, float], active: set[str]) -> None:
        weights = self.balancer.multipliers()
        objective = [k for k in active if k in values and self.balancer.is_objective(k)]
        self._objective[0] += sum(weights.get(k, 0.0) * values[k] for k in objective)
        self._objective[1] += 1

    def active_terms(self, step: int) -> set[str]:
        return {k for k, t in self.terms.items() if t.weight > 0 and step >= t.start}

    def _start_lbfgs(self, sample: Tensor | None = None) -> None:
        """The L-BFGS phase's optimiser, and the generator state every evaluation restarts from
        (``sample``: a saved one; None: the current state)."""
        # up to 20 iterations per step: with one per call, torch's L-BFGS can stall (a least-squares
        # fit stopped at loss 9e-3 where 20 per call reach 1e-33, tests/test_trainer.py)
        self.lbfgs = torch.optim.LBFGS(self.model.parameters(), lr=1.0, max_iter=20, history_size=20,
                                       line_search_fn="strong_wolfe")
        self._lbfgs_sample = self.gen.get_state() if sample is None else sample

    def lbfgs_step(self) -> dict[str, float] | None:
        """One L-BFGS step (``training.lbfgs_steps``: up to 20 iterations) on the phase's fixed sample, with the
        multipliers as they are; returns the loss values at the step's start, or None (and the
        weights of before) when it met a non-finite value."""
        if self.lbfgs is None:
            self._start_lbfgs()
        step = self.step
        active = self.active_terms(step)
        first: dict[str, float] = {}
        finite = [True]

        def closure() -> Tensor:
            self.lbfgs.zero_grad(set_to_none=True)
            self.gen.set_state(self._lbfgs_sample)
            losses = self.task.loss_terms(self.model, step, active, self.gen)
            if self.dist is not None:
                losses = self.dist.globalize(losses)
            total = self.balancer.combine({k: v for k, v in losses.items() if k in active}, step)
            if not math.isfinite(float(total.detach())):
                finite[0] = False
                return total.detach()
            total.backward()
            if self.dist is not None:
                self.dist.average_gradients(self.model.parameters())
            if not first:
                first.update({k: float(v.detach()) for k, v in losses.items()})
                first["total"] = float(total.detach())
            return total

        before = [p.detach().clone() for p in self.model.parameters()]
        self.lbfgs.step(closure)
        if not finite[0] or not all(bool(torch.isfinite(p).all()) for p in self.model.parameters()):
            with torch.no_grad():
                for p, b in zip(self.model.parameters(), before):
                    p.copy_(b)
            self._log({"step": step, "event": "skipped_non_finite", "phase": "lbfgs"})
            self.step += 1
            return None
        if self._averaging:
            self._accumulate_mean()
        self._track_objective(first, active)
        self.step += 1
        return first

    def train_step(self) -> dict[str, float] | None:
        """One optimisation step (Adam, or L-BFGS once the Adam iterations are done); returns the
        loss values, or None if the step was skipped."""
        if self.step >= self.cfg.training.iterations:
            return self.lbfgs_step()
        step = self.step
        active = self.active_terms(step)
        self.optimizer.zero_grad(set_to_none=True)
        losses = self.task.loss_terms(self.model, step, active, self.gen)
        if self.dist is not None:  # values: means over all ranks; gradients: this rank's share
            losses = self.dist.globalize(losses)
        total = self.balancer.combine({k: v for k, v in losses.items() if k in active}, step)
        values = {k: float(v.detach()) for k, v in losses.items()}
        values["total"] = float(total.detach())
        ok = math.isfinite(values["total"])
        if ok:
            total.backward()
            if self.dist is not None:
                self.dist.average_gradients(self.model.parameters())
            grads = [p.grad for p in self.model.parameters() if p.grad is not None]
            gnorm = torch.linalg.vector_norm(torch.stack([torch.linalg.vector_norm(g) for g in grads])) if grads else torch.zeros(())
            ok = bool(torch.isfinite(gnorm))
            values["grad_norm"] = float(gnorm)
        if not ok:
            self.optimizer.zero_grad(set_to_none=True)
            self.bad_steps += 1
            self._log({"step": step, "event": "skipped_non_finite", **{k: v for k, v in values.items() if math.isfinite(v)}})
            if self.bad_steps >= self.cfg.training.max_bad_steps:
                self._rollback()
            return None
        self.bad_steps = 0
        if self.cfg.training.grad_clip > 0:
            nn.utils.clip_grad_norm_(self.model.parameters(), self.cfg.training.grad_clip)
        self.optimizer.step()
        self.scheduler.step()
        if self._averaging:
            self._accumulate_mean()
        self.balancer.observe({k: values[k] for k in active if k in values}, step)
        self._track_objective(values, active)
        self.step += 1
        return values

    def train(self) -> TrainResult:
        """Run until ``training.iterations`` and then ``training.lbfgs_steps`` more (from the
        current step); handles signals."""
        t = self.cfg.training
        total_iters = self.total_iterations
        bar = None
        if self.progress and self.step < total_iters:
            if sys.stderr.isatty():
                from tqdm import tqdm

                bar = tqdm(total=total_iters, initial=self.step, dynamic_ncols=True, unit="it", leave=True)
            else:
                bar = PlainProgress(total_iters, self.step)
        last: dict[str, float] = {}
        status = "completed"
        t0 = time.perf_counter() - self.elapsed
        stopped: StopRun | None = None
        if "tensorboard" in t.log and self.run_dir is not None and self.is_main and self._tb is None:
            self._tb = TensorBoardLog(self.run_dir, purge_step=self.step + 1 if self.step > 0 else 0)
        self._status("running")
        try:
            with _StopFlag() as flag:
                while self.step < total_iters:
                    step = self.step
                    before = self.elapsed
                    values = self.train_step()
                    self.elapsed = time.perf_counter() - t0
                    self._step_seconds = max(self._step_seconds, self.elapsed - before)
                    if values is not None:
                        last = values
                        try:
                            for h in self.hooks:
                                h(self, step, values)
                        except StopRun as e:
                            stopped, status = e, e.status
                            break
                        if step % t.log_every == 0 or self.step == total_iters:
                            rec = {"step": step, "time": round(self.elapsed, 3), "lr": self.optimizer.param_groups[0]["lr"]}
                            rec.update(values)
                            if self.cfg.balancing.method != "weighted":
                                rec["multipliers"] = {k: float(f"{v:.6g}") for k, v in self.balancer.multipliers().items()
                                                      if k in values}
                            self._log(rec)
                        if self._check_due():
                            try:
                                self._check_feasibility()
                            except StopRun as e:
                                stopped, status = e, e.status
                                break
                        if bar is not None:
                            bar.update(1)
                            if step % max(1, t.log_every) == 0:
                                shown = {k: f"{v:.2e}" for k, v in values.items() if not k.startswith("_") and k != "grad_norm"}
                                if self.feasibility is not None:
                                    shown["feasible"] = short_summary(self.feasibility)
                                bar.set_postfix(shown, refresh=False)
                    if values is not None and self.step > 0 and self._checkpoint_due():
                        self.save()
                    if flag.stop if self.dist is None else self.dist.any(flag.stop):
                        status = "interrupted"
                        break
            if bar is not None:
                bar.close()
            if status == "completed":
                self._restore_most_feasible()
            self.save()
            if status == "interrupted":
                self._log({"step": self.step, "event": "interrupted", "signal": flag.signum})
            elif stopped is not None:
                self._log({"step": self.step, "event": status, "reason": str(stopped)})
            if self._tb is not None:
                self._tb.writer.flush()
        except KeyboardInterrupt:
            if bar is not None:
                bar.close()
            self._try_status("interrupted", "stopped without a checkpoint at this iteration; resume from the last one")
            raise
        except Exception as e:
            if bar is not None:
                bar.close()
            self._try_status("failed", str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__)
            raise
        self._status(status, str(stopped) if stopped is not None else "")
        return TrainResult(self.model, status, self.step, self.elapsed, last, str(stopped) if stopped else "")


def _violated_counts(summary: dict) -> dict[str, int]:
    """How many shapes violate each constraint."""
    return dict(Counter(name for v in summary["violations"] for name in v))
