"""Plug-ins of the training loop: the trainer calls them at named points and knows nothing else of them.

A :class:`Callback` overrides the points it needs, in the order a run meets them:

=====================  =========================================================================
point                  when
=====================  =========================================================================
``on_build``           the model was built, before the optimiser (compile its kernels)
``on_start``           :meth:`Trainer.train` begins (open a log, a progress bar)
``takes_step``         before each step: a plug-in that answers True runs it (``step``), e.g. the
                       L-BFGS phase after the Adam iterations
``on_step``            a step was taken (not skipped): ``(trainer, step, values)``, before the
                       step's line of ``metrics.jsonl``; may raise :class:`StopRun`
``on_record``          after that line: checks that log events of their own; may raise StopRun
``on_log``             every record written to ``metrics.jsonl`` (steps and events)
``on_stop``            the loop ended, for whatever reason (close a progress bar)
``on_finish``          the run ended normally (``status``), before its last checkpoint
``on_results``         the result files written at the end (a log that shows figures)
``on_close``           the trainer is closed
=====================  =========================================================================

A plug-in with a ``key`` keeps its ``state_dict`` in every checkpoint under that key, so that a
resumed run continues exactly. ``note`` adds to the progress bar's text; ``report`` gives lines
for the terminal when the run is over; ``extra_steps`` adds steps after the Adam iterations.

The plug-ins here are the engine's own, contributed by the run's configuration
(:func:`standard_callbacks`); a task contributes its own (:meth:`ginn.train.task.Task.callbacks`).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar

import torch
from torch import Tensor

from ..config import RunConfig
from ..errors import ConfigError
from ..models import compile_derivatives
from .tblog import TensorBoardLog, tensorboard_available

if TYPE_CHECKING:
    from .trainer import Trainer

__all__ = ["Callback", "StopRun", "Hook", "CompileKernels", "LBFGSPhase", "TensorBoard", "Progress", "PlainProgress",
           "standard_callbacks"]


class StopRun(Exception):
    """Raised by a plug-in to end a run early: the trainer writes a checkpoint and returns with
    ``status`` (e.g. ``"pruned"`` for a sweep trial that the pruner stopped)."""

    def __init__(self, status: str, reason: str = ""):
        super().__init__(reason or status)
        self.status = status


class Callback:
    """A plug-in of the training loop (see the module docstring); every point does nothing here."""

    #: the checkpoint entry of its state (None: it keeps none)
    key: ClassVar[str | None] = None

    def on_build(self, trainer: Trainer) -> None: ...
    def on_start(self, trainer: Trainer) -> None: ...
    def on_step(self, trainer: Trainer, step: int, values: dict[str, float]) -> None: ...
    def on_record(self, trainer: Trainer, step: int, values: dict[str, float]) -> None: ...
    def on_log(self, trainer: Trainer, record: dict) -> None: ...
    def on_stop(self, trainer: Trainer) -> None: ...
    def on_finish(self, trainer: Trainer, status: str) -> None: ...
    def on_results(self, trainer: Trainer, paths: list) -> None: ...
    def on_close(self, trainer: Trainer) -> None: ...

    def takes_step(self, trainer: Trainer) -> bool:
        return False

    def step(self, trainer: Trainer) -> dict[str, float] | None:
        raise NotImplementedError

    def extra_steps(self) -> int:
        return 0

    def note(self) -> str | None:
        return None

    def report(self) -> list[str]:
        return []

    def state_dict(self) -> Any:
        return None

    def load_state_dict(self, state: Any) -> None: ...


class Hook(Callback):
    """A callable ``hook(trainer, step, values)`` run after every step (``on_step``)."""

    def __init__(self, fn: Callable[[Trainer, int, dict], None]):
        self.fn = fn

    def on_step(self, trainer: Trainer, step: int, values: dict[str, float]) -> None:
        self.fn(trainer, step, values)


class CompileKernels(Callback):
    """``training.compile``: the SIREN's training pass as ``torch.compile`` kernels
    (:func:`ginn.models.compile_derivatives`)."""

    def __init__(self, on: bool):
        self.on = on

    def on_build(self, trainer: Trainer) -> None:
        compile_derivatives(trainer.model, self.on)


class LBFGSPhase(Callback):
    """``training.lbfgs_steps``: after the Adam iterations, L-BFGS steps (up to 20 iterations each,
    strong-Wolfe line search, history 20) on one fixed sample of points (every evaluation restarts
    the generator from the phase's first state), the multipliers as they are. A step that meets a
    non-finite value is undone and logged."""

    key = "lbfgs"

    def __init__(self, steps: int):
        self.steps = steps
        self.optimizer: torch.optim.LBFGS | None = None
        self.sample: Tensor | None = None
        self._pending: dict | None = None  # a restored state, taken up at the next step

    def extra_steps(self) -> int:
        return self.steps

    def takes_step(self, trainer: Trainer) -> bool:
        return trainer.step >= trainer.cfg.training.iterations

    def step(self, trainer: Trainer) -> dict[str, float] | None:
        if self.optimizer is None:
            # up to 20 iterations per step: with one per call, torch's L-BFGS can stall (a least-squares
            # fit stopped at loss 9e-3 where 20 per call reach 1e-33, tests/test_trainer.py)
            self.optimizer = torch.optim.LBFGS(trainer.model.parameters(), lr=1.0, max_iter=20, history_size=20,
                                               line_search_fn="strong_wolfe")
            self.sample = trainer.gen.get_state()
            if self._pending is not None:
                self.sample = self._pending["sample"]
                self.optimizer.load_state_dict(self._pending["optimizer"])
                self._pending = None
        step = trainer.step
        active = trainer.active_terms(step)
        first: dict[str, float] = {}
        finite = [True]

        def closure() -> Tensor:
            self.optimizer.zero_grad(set_to_none=True)
            trainer.gen.set_state(self.sample)
            losses, total = trainer.objective(step, active)
            if not math.isfinite(float(total.detach())):
                finite[0] = False
                return total.detach()
            total.backward()
            if trainer.dist is not None:
                trainer.dist.average_gradients(trainer.model.parameters())
            if not first:
                first.update({k: float(v.detach()) for k, v in losses.items()})
                first["total"] = float(total.detach())
            return total

        params = list(trainer.model.parameters())
        before = [p.detach().clone() for p in params]
        self.optimizer.step(closure)
        trainer.step += 1
        if not finite[0] or not all(bool(torch.isfinite(p).all()) for p in params):
            with torch.no_grad():
                for p, b in zip(params, before):
                    p.copy_(b)
            trainer.log({"step": step, "event": "skipped_non_finite", "phase": "lbfgs"})
            return None
        return first

    def state_dict(self) -> Any:
        if self.optimizer is None:
            return self._pending
        return {"optimizer": self.optimizer.state_dict(), "sample": self.sample}

    def load_state_dict(self, state: Any) -> None:
        self.optimizer, self.sample, self._pending = None, None, state


class TensorBoard(Callback):
    """``training.log: [..., tensorboard]``: every record of ``metrics.jsonl`` mirrored in
    ``RUN/tensorboard`` (:class:`ginn.train.tblog.TensorBoardLog`), and the result figures."""

    def __init__(self) -> None:
        if not tensorboard_available():
            raise ConfigError("training.log: tensorboard needs the tensorboard package (pip install 'ginn[track]')")
        self.log: TensorBoardLog | None = None

    def on_start(self, trainer: Trainer) -> None:
        if trainer.run_dir is not None and trainer.is_main and self.log is None:
            self.log = TensorBoardLog(trainer.run_dir, purge_step=trainer.step + 1 if trainer.step > 0 else 0)

    def on_log(self, trainer: Trainer, record: dict) -> None:
        if self.log is not None:
            self.log.write(record)
            if "event" in record:
                self.log.writer.flush()

    def on_results(self, trainer: Trainer, paths: list) -> None:
        if self.log is not None:
            self.log.figures(paths, trainer.step)

    def on_close(self, trainer: Trainer) -> None:
        if self.log is not None:
            self.log.close()
            self.log = None


class PlainProgress:
    """Progress for a log file (stderr not a terminal): one plain line every tenth of the run or
    every ``seconds``, whichever comes first, instead of a redrawn bar. The same calls as tqdm's
    that :class:`Progress` makes (``update``, ``set_postfix``, ``close``)."""

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


class Progress(Callback):
    """A progress bar (tqdm on a terminal, :class:`PlainProgress` in a log file) with the loss
    terms every ``training.log_every`` steps and the notes of the other plug-ins."""

    def __init__(self) -> None:
        self.bar = None

    def on_start(self, trainer: Trainer) -> None:
        total = trainer.total_iterations
        if not trainer.is_main or trainer.step >= total:
            return
        if sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, initial=trainer.step, dynamic_ncols=True, unit="it", leave=True)
        else:
            self.bar = PlainProgress(total, trainer.step)

    def on_record(self, trainer: Trainer, step: int, values: dict[str, float]) -> None:
        if self.bar is None:
            return
        self.bar.update(1)
        if step % max(1, trainer.cfg.training.log_every) == 0:
            shown = {k: f"{v:.2e}" for k, v in values.items() if not k.startswith("_") and k != "grad_norm"}
            for cb in trainer.callbacks:
                if (text := cb.note()) is not None:
                    shown["feasible"] = text
            self.bar.set_postfix(shown, refresh=False)

    def on_stop(self, trainer: Trainer) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def standard_callbacks(cfg: RunConfig, progress: bool, extra: list[Callback] = ()) -> list[Callback]:
    """The engine's plug-ins that ``cfg`` asks for, in their order: compiled kernels, the L-BFGS
    phase, the TensorBoard log; ``extra`` (the task's) after them; the progress bar (with
    ``progress``) last, so that it shows what the others noted at the same step."""
    t = cfg.training
    out: list[Callback] = [CompileKernels(t.compile)]
    if t.lbfgs_steps > 0:
        out.append(LBFGSPhase(t.lbfgs_steps))
    if "tensorboard" in t.log:
        out.append(TensorBoard())
    return out + list(extra) + ([Progress()] if progress else [])
