"""The training loop: Adam, an exponential schedule, clipping, balancing, checkpoints and plug-ins.

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
  critical points and surface network), every plug-in's state and every RNG state;
  ``metrics.jsonl`` is cut back to it.
* ``status.json`` tells the truth: ``running`` with the step and a heartbeat refreshed at every
  checkpoint, then ``completed``, ``interrupted``, ``failed`` (with the one-line reason) or a
  plug-in's status. A write that fails (full disk, read-only directory) is one line that names
  the file and says that the last checkpoint is intact.

Everything else (compiled kernels, the L-BFGS phase, feasibility checks, TensorBoard, the progress
bar) is a plug-in (:mod:`ginn.train.callbacks`) contributed by the configuration and the task.
"""

from __future__ import annotations

import math
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import torch
from torch import Tensor, nn

from ..config import DTYPES, LossTerm, RunConfig, TrainingConfig
from ..errors import ConfigError, GinnError
from .balancing import make_balancer
from .callbacks import Callback, Hook, StopRun, standard_callbacks
from .checkpoint import CheckpointError, load_checkpoint, load_weights, rng_state, save_checkpoint, set_rng_state
from .distributed import DistContext
from .rundir import RunRecord, io_error, truncate_metrics
from .task import Task

__all__ = ["Trainer", "TrainResult", "TrainingDiverged", "StopRun", "lr_factor"]


class TrainingDiverged(GinnError):
    """Non-finite losses persist even after rolling back with lower learning rates."""


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


def checked_terms(terms: dict[str, LossTerm], kind: str) -> dict[str, LossTerm]:
    """``terms``, if one of them is active from iteration 0.

    Raises:
        ConfigError: every weight is 0, or no term starts at iteration 0.
    """
    if not any(term.weight > 0 for term in terms.values()):
        raise ConfigError(f"no active loss term: every loss weight of this {kind} problem is 0 "
                          f"(terms: {', '.join(sorted(terms)) or 'none'}); set losses.<term>.weight")
    first = min(term.start for term in terms.values() if term.weight > 0)
    if first > 0:
        raise ConfigError(f"no loss term is active at iteration 0 (the earliest start is {first}); "
                          "set losses.<term>.start = 0 for at least one term")
    return terms


class _StopFlag:
    def __init__(self) -> None:
        self.stop, self.signum = False, None
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
        task: the problem (builds the model, returns unweighted loss terms, contributes plug-ins).
        cfg: the resolved run configuration.
        run_dir: where metrics.jsonl and checkpoints go (None: nothing is written).
        progress: show a progress bar.
        hooks: callables ``hook(trainer, step, losses)`` run after each step (they may raise
            :class:`StopRun`).
        dist: a :class:`ginn.train.distributed.DistContext` for data-parallel training (torchrun):
            the task trains its shard, losses and gradients are averaged over ranks, only rank 0
            writes; None: a single process.
        callbacks: the plug-ins (None: the hooks, :func:`~ginn.train.callbacks.standard_callbacks`
            of ``cfg`` and the task's own).
    """

    def __init__(self, task: Task, cfg: RunConfig, run_dir: str | Path | None = None, progress: bool = True,
                 hooks: list[Callable] | None = None, dist: DistContext | None = None,
                 callbacks: list[Callback] | None = None):
        self.task, self.cfg, self.dist = task, cfg, dist
        self.is_main = dist is None or dist.is_main
        self.run_dir = Path(run_dir) if run_dir is not None else None
        if self.run_dir is not None and self.is_main:
            self.run_dir.mkdir(parents=True, exist_ok=True)
        self.record = RunRecord(self.run_dir, self.is_main, self.checkpoint_path)
        if callbacks is None:
            callbacks = [Hook(h) for h in hooks or []] + standard_callbacks(cfg, progress and self.is_main, task.callbacks(dist))
        self.callbacks = callbacks
        self.device, self.dtype = torch.device(cfg.device), DTYPES[cfg.training.dtype]
        if cfg.training.threads > 0:
            torch.set_num_threads(cfg.training.threads)
        torch.manual_seed(cfg.seed)
        self.gen = torch.Generator(device=self.device).manual_seed(cfg.seed)
        self.model = task.build_model().to(device=self.device, dtype=self.dtype)
        self._notify("on_build")
        if dist is not None:
            task.distribute(dist)
            dist.broadcast_parameters(self.model)
        t = cfg.training
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=t.lr)
        self.scheduler = torch.optim.lr_scheduler.LambdaLR(self.optimizer, lambda it: lr_factor(t, it))
        self.terms = checked_terms(task.terms(), task.kind)
        self.balancer = make_balancer(self.terms, cfg.balancing, task.balance())
        self.step = self.bad_steps = self.rollbacks = 0
        self.lr_scale, self.elapsed = 1.0, 0.0
        self._saved_at = 0.0  # training time of the last checkpoint
        self._step_seconds = 0.0  # the longest iteration so far

    def _notify(self, point: str, *args) -> None:
        for cb in self.callbacks:
            getattr(cb, point)(self, *args)

    @property
    def total_iterations(self) -> int:
        """The Adam iterations and the plug-ins' steps after them (the L-BFGS phase)."""
        return self.cfg.training.iterations + sum(cb.extra_steps() for cb in self.callbacks)

    def active_terms(self, step: int) -> set[str]:
        return {k for k, t in self.terms.items() if t.weight > 0 and step >= t.start}

    # --- checkpoints -------------------------------------------------------------------------

    @property
    def checkpoint_path(self) -> Path | None:
        return None if self.run_dir is None else self.run_dir / "checkpoints" / "last.pt"

    def state_dict(self) -> dict:
        """The checkpoint; distributed: a collective (every rank's task and RNG state under "ranks")."""
        state = {"format": "ginn-checkpoint-1", "step": self.step, "elapsed": self.elapsed, "lr_scale": self.lr_scale,
                 "rollbacks": self.rollbacks, "bad_steps": self.bad_steps, "model": self.model.state_dict(),
                 "optimizer": self.optimizer.state_dict(), "scheduler": self.scheduler.state_dict(),
                 "balancer": self.balancer.state_dict(), "task": self.task.state_dict(), "rng": rng_state(self.gen)}
        state.update({cb.key: cb.state_dict() for cb in self.callbacks if cb.key is not None})
        if self.dist is not None:
            state["ranks"] = self.dist.gather_objects({"task": self.task.state_dict(), "rng": rng_state(self.gen)})
        return state

    def load_state_dict(self, state: dict) -> None:
        load_weights(self.model, state, self.checkpoint_path)
        self.optimizer.load_state_dict(state["optimizer"])
        self.scheduler.load_state_dict(state["scheduler"])
        self.balancer.load_state_dict(state["balancer"])
        ranks = state.get("ranks") if self.dist is not None else None
        own = ranks[self.dist.rank] if ranks is not None and len(ranks) == self.dist.world else state  # same world size: exact
        self.task.load_state_dict(own["task"])
        set_rng_state(own["rng"], self.gen)
        for cb in self.callbacks:
            if cb.key is not None:
                cb.load_state_dict(state.get(cb.key))
        self.step, self.elapsed = int(state["step"]), float(state.get("elapsed", 0.0))
        self.lr_scale, self.rollbacks = float(state.get("lr_scale", 1.0)), int(state.get("rollbacks", 0))
        self.bad_steps = int(state.get("bad_steps", 0))
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
                    raise GinnError(f"{io_error(e, self.checkpoint_path)}; {self.record.intact()}") from None
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
        try:
            self.load_state_dict(load_checkpoint(p, map_location=self.device))
        except (KeyError, TypeError, ValueError, IndexError) as e:  # the layout of another program's file
            raise CheckpointError(f"checkpoint {p} is not a checkpoint of this run ({type(e).__name__}: {e})") from None
        if self.run_dir is not None and self.is_main:
            truncate_metrics(self.run_dir / "metrics.jsonl", self.step)
        return True

    def _status(self, status: str, reason: str = "", write=None) -> None:
        every = max(self.cfg.training.checkpoint_seconds, self._step_seconds)
        (write or self.record.status)(status, self.step, self.elapsed, reason, heartbeat_every=every)

    def _apply_lr_scale(self) -> None:
        t = self.cfg.training
        self.scheduler.base_lrs = [t.lr * self.lr_scale for _ in self.scheduler.base_lrs]
        for g in self.optimizer.param_groups:
            g["lr"] = t.lr * self.lr_scale * lr_factor(t, self.scheduler.last_epoch)

    def _rollback(self) -> None:
        if self.rollbacks >= self.cfg.training.max_rollbacks:
            self.log({"step": self.step, "event": "diverged"})
            raise TrainingDiverged(f"training diverged: non-finite losses persisted through {self.rollbacks} rollbacks at "
                                   f"iteration {self.step}; lower training.lr or the loss weights")
        rollbacks, scale = self.rollbacks + 1, self.lr_scale * self.cfg.training.rollback_lr_factor
        p = self.checkpoint_path
        if p is not None and p.exists():
            self.load_state_dict(load_checkpoint(p, map_location=self.device))
        self.rollbacks, self.lr_scale, self.bad_steps = rollbacks, scale, 0
        self._apply_lr_scale()
        self.log({"step": self.step, "event": "rollback", "lr_scale": self.lr_scale})

    # --- logging -------------------------------------------------------------------------------

    def log(self, record: dict) -> None:
        """Append ``record`` to ``metrics.jsonl`` (rank 0 of a run with a directory) and hand it to
        the plug-ins."""
        if self.record.append(record):
            self._notify("on_log", record)

    def log_figures(self, paths: list[Path]) -> None:
        """Hand the run's result files to the plug-ins (a log that shows figures)."""
        self._notify("on_results", paths)

    def close(self) -> None:
        """Close the plug-ins (a later ``train`` opens them again)."""
        self._notify("on_close")

    # --- the loop ------------------------------------------------------------------------------

    def objective(self, step: int, active: set[str]) -> tuple[dict[str, Tensor], Tensor]:
        """The task's loss terms at ``step`` (averaged over ranks) and their balanced sum."""
        losses = self.task.loss_terms(self.model, step, active, self.gen)
        if self.dist is not None:  # values: means over all ranks; gradients: this rank's share
            losses = self.dist.globalize(losses)
        return losses, self.balancer.combine({k: v for k, v in losses.items() if k in active}, step)

    def train_step(self) -> dict[str, float] | None:
        """One step (Adam, or a plug-in's, e.g. L-BFGS after the Adam iterations); returns the
        loss values, or None if the step was skipped."""
        for cb in self.callbacks:
            if cb.takes_step(self):
                return cb.step(self)
        step = self.step
        active = self.active_terms(step)
        self.optimizer.zero_grad(set_to_none=True)
        losses, total = self.objective(step, active)
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
            self.log({"step": step, "event": "skipped_non_finite", **{k: v for k, v in values.items() if math.isfinite(v)}})
            if self.bad_steps >= self.cfg.training.max_bad_steps:
                self._rollback()
            return None
        self.bad_steps = 0
        if self.cfg.training.grad_clip > 0:
            nn.utils.clip_grad_norm_(self.model.parameters(), self.cfg.training.grad_clip)
        self.optimizer.step()
        self.scheduler.step()
        self.balancer.observe({k: values[k] for k in active if k in values}, step)
        self.step += 1
        return values

    def _record(self, step: int, values: dict[str, float]) -> None:
        t = self.cfg.training
        if step % t.log_every == 0 or self.step == self.total_iterations:
            rec = {"step": step, "time": round(self.elapsed, 3), "lr": self.optimizer.param_groups[0]["lr"], **values}
            if self.cfg.balancing.method != "weighted":
                rec["multipliers"] = {k: float(f"{v:.6g}") for k, v in self.balancer.multipliers().items() if k in values}
            self.log(rec)

    def _checkpoint_due(self) -> bool:
        """Every ``checkpoint_every`` iterations, or when ``checkpoint_seconds`` of training have
        passed since the last checkpoint (decided on rank 0's clock under torchrun)."""
        t = self.cfg.training
        due = self.step % t.checkpoint_every == 0 or self.elapsed - self._saved_at >= t.checkpoint_seconds
        return self.dist.broadcast_object(due) if self.dist is not None else due

    def train(self) -> TrainResult:
        """Run until ``training.iterations`` and the plug-ins' steps after them (from the current
        step); handles signals."""
        total_iters, last, status, stopped = self.total_iterations, {}, "completed", None
        t0 = time.perf_counter() - self.elapsed
        self._notify("on_start")
        self._status("running")
        try:
            with _StopFlag() as flag:
                while self.step < total_iters:
                    step, before = self.step, self.elapsed
                    values = self.train_step()
                    self.elapsed = time.perf_counter() - t0
                    self._step_seconds = max(self._step_seconds, self.elapsed - before)
                    if values is not None:
                        last = values
                        try:
                            self._notify("on_step", step, values)
                            self._record(step, values)
                            self._notify("on_record", step, values)
                        except StopRun as e:
                            stopped, status = e, e.status
                            break
                    if values is not None and self.step > 0 and self._checkpoint_due():
                        self.save()
                    if flag.stop if self.dist is None else self.dist.any(flag.stop):
                        status = "interrupted"
                        break
            self._notify("on_stop")
            self._notify("on_finish", status)
            self.save()
            if status == "interrupted":
                self.log({"step": self.step, "event": "interrupted", "signal": flag.signum})
            elif stopped is not None:
                self.log({"step": self.step, "event": status, "reason": str(stopped)})
        except KeyboardInterrupt:
            self._notify("on_stop")
            self._status("interrupted", "stopped without a checkpoint at this iteration; resume from the last one",
                         self.record.try_status)
            raise
        except Exception as e:
            self._notify("on_stop")
            self._status("failed", str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__,
                         self.record.try_status)
            raise
        reason = str(stopped) if stopped is not None else ""
        self._status(status, reason)
        return TrainResult(self.model, status, self.step, self.elapsed, last, reason)
