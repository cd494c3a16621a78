"""Feasibility checks during training, a plug-in of the trainer that a shape task contributes.

``training.feasibility_checks`` times per run (after the step that completes each of that many
equal parts of the Adam iterations, and at the end) the shapes are judged against the problem's
tolerances on a coarse grid (:class:`ginn.eval.feasibility.FeasibilityCheck`, the verdicts of
``ginn eval``), and the summary is logged as a ``feasibility`` event. Each check also:

* hands the balancer the worst ratio of every constraint to its bound (``balancing.method:
  feasibility`` raises the multipliers of the constraints off track): the better of the iterate's
  and the interval mean's (:func:`candidate_ratios`);
* ``training.keep_most_feasible``: judges the mean of the weights since the previous check as
  well, and keeps the best candidate (:meth:`FeasibilitySummary.rank`: the most feasible shapes,
  then the set's bounds met, then the most feasible held-out codes; on a tie the mean at one
  check, the latest of equals, unless both are feasible throughout and the problem measures an
  objective, a verdict with ``objective`` (the compliance of a structural problem), by which the
  other candidate is better, spending no more volume or clear of the volume bound:
  :meth:`FeasibilityChecks._at_least`); a
  completed run ends with it (a ``restored`` event when that is not the last iterate);
* ``training.stop_when_feasible``: ends the run when every shape is feasible, the set meets its
  bounds and the objective terms moved by less than 1 % since the previous check.

Under data parallelism (torchrun) rank 0 judges every shape and hands the summaries to every rank,
which all take the same decisions: a rank judging only its own share of the shapes would calibrate
and raise on other numbers than the single process, and without the checks a generative model's
diversity bound kept its uncalibrated training estimate (the 4-shape cantilever's shortfall 0 on
2 ranks against 0.45 in one process after the first check).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TypeVar

from torch import Tensor, nn

from ...config import TrainingConfig
from ...constraints import Constraint, Verdict
from ...eval.results import FeasibilitySummary
from ...train.callbacks import Callback, StopRun
from ...train.distributed import DistContext
from ...train.trainer import Trainer

__all__ = ["FeasibilityChecks", "candidate_ratios"]

T = TypeVar("T")


def _heldout_record(h: FeasibilitySummary) -> dict:
    """The held-out codes' part of a check's event: the count and the worst code."""
    out: dict = {"feasible": h.feasible, "shapes": h.shapes}
    w = h.worst_latent()
    if w is not None:
        out["worst_latent"], out["worst_ratio"] = w[0], w[1]
    return out


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


class FeasibilityChecks(Callback):
    """The checks of the module docstring.

    Arguments:
        judge: the summary of the model's shapes now (:class:`ginn.eval.feasibility.FeasibilityCheck`).
        training: the run's training settings.
        verdicts: what the summaries judge (for their texts).
        constraints: the task's terms, each told every check's ratios (:meth:`Constraint.checked`).
        dist: the process group of a data-parallel run (torchrun): rank 0 judges, every rank
            takes its summaries, so the balancer, the terms' calibrations, the kept weights and a
            stop are the same on every rank (None: one process).
        objective: ``(objective, volume, inside)`` of the model's shapes, the objective lower is
            better (a verdict's :meth:`~ginn.constraints.Verdict.objective_of`), or None where it
            measures none.
    """

    key = "feasibility"

    def __init__(self, judge: Callable[[nn.Module], FeasibilitySummary], training: TrainingConfig,
                 verdicts: Sequence[Verdict] = (), constraints: Sequence[Constraint] = (),
                 dist: DistContext | None = None,
                 objective: Callable[[nn.Module], tuple[float, float, bool]] | None = None):
        self.judge, self.t, self.verdicts = judge, training, list(verdicts)
        self.measure_objective = objective
        self.constraints = list(constraints)
        self.dist = dist
        self.last: FeasibilitySummary | None = None  # the last check's summary
        self.objective = [0.0, 0]  # sum and count of the objective terms since the last check
        self.objective_before: float | None = None  # their mean over the interval before
        self.best: dict | None = None  # the check with the most feasible shapes: step, summary, weights
        self.mean: dict[str, Tensor] | None = None  # the running mean of the weights since the last check
        self.mean_count = 0
        self.averaging = training.keep_most_feasible
        self.restored: dict | None = None  # the 'restored' event, when the run ended with the best weights

    # --- state -----------------------------------------------------------------------------------

    def state_dict(self) -> dict:
        """Plain data and tensors (the summaries as their JSON)."""
        best = None if self.best is None else {**self.best, "summary": self.best["summary"].to_json()}
        return {"last": None if self.last is None else self.last.to_json(), "objective": list(self.objective),
                "objective_before": self.objective_before, "best": best, "mean": self.mean,
                "mean_count": self.mean_count, "averaging": self.averaging}

    def load_state_dict(self, state: dict | None) -> None:
        state = state or {}
        self.last = None if state.get("last") is None else FeasibilitySummary.from_json(state["last"])
        self.objective = list(state.get("objective", [0.0, 0]))
        self.objective_before = state.get("objective_before")
        self.best = state.get("best")
        if self.best is not None:
            self.best = {**self.best, "summary": FeasibilitySummary.from_json(self.best["summary"])}
        self.mean = state.get("mean")
        self.mean_count = int(state.get("mean_count", 0))
        self.averaging = bool(state.get("averaging", self.t.keep_most_feasible))

    # --- the loop ----------------------------------------------------------------------------------

    def on_step(self, trainer: Trainer, step: int, values: dict[str, float]) -> None:
        if self.averaging:
            self._accumulate(trainer.model)
        weights = trainer.balancer.multipliers()
        objective = [k for k in trainer.active_terms(step) if k in values and trainer.balancer.is_objective(k)]
        self.objective[0] += sum(weights.get(k, 0.0) * values[k] for k in objective)
        self.objective[1] += 1

    def on_record(self, trainer: Trainer, step: int, values: dict[str, float]) -> None:
        if self._due(trainer):
            self.check(trainer)

    def on_finish(self, trainer: Trainer, status: str) -> None:
        if status == "completed":
            self._restore(trainer)

    def note(self) -> str | None:
        return None if self.last is None else self.last.short()

    def report(self) -> list[str]:
        lines = []
        if self.restored is not None:
            r = self.restored
            what = (f"the mean of the weights over iterations {r['from_step'] - r['mean_iterations'] + 1}-{r['from_step']}"
                    if r["mean"] else f"the weights of iteration {r['from_step']}")
            held = r.get("heldout")
            also = "" if held is None else (f" and {held['feasible']} of {held['shapes']} held-out latents "
                                             f"({held['instead_of']} at the end)")
            lines.append(f"kept {what}: {r['feasible']} of {r['shapes']} shapes feasible there{also}, "
                         f"{r['instead_of']} at the end (training.keep_most_feasible)")
        if self.last is not None:
            lines.append(f"{self.last.text(self.verdicts)}\n(checked on a coarse grid; `ginn eval` for every metric)")
        return lines

    def _every(self) -> int:
        return max(1, math.ceil(self.t.iterations / max(1, self.t.feasibility_checks)))

    def _due(self, trainer: Trainer) -> bool:
        """After the step that completes one of ``feasibility_checks`` equal parts of the run."""
        if self.t.feasibility_checks <= 0 or self.t.iterations <= 0:
            return False
        return trainer.step % self._every() == 0 or trainer.step in (self.t.iterations, trainer.total_iterations)

    def _checks_left(self, trainer: Trainer) -> int:
        """How many checks come after the current step (the last one at the final iteration)."""
        return max(0, math.ceil((self.t.iterations - trainer.step) / self._every()))

    def check(self, trainer: Trainer) -> FeasibilitySummary:
        """Judge the shapes, log the summary (an event: ``step`` is the number of completed
        iterations), update the balancer and the best candidate, and decide whether
        ``stop_when_feasible`` ends the run (raises :class:`StopRun`)."""
        summary = self._shared(lambda: self.judge(trainer.model))
        self.last = summary
        for c in self.constraints:
            c.checked(summary.ratios)
        record = {"step": trainer.step, "event": "feasibility", "feasible": summary.feasible, "shapes": summary.shapes,
                  "worst": summary.worst, "violated": summary.violated_counts(), "ratios": summary.ratios}
        if summary.heldout is not None:
            record["heldout"] = _heldout_record(summary.heldout)
        interval_mean, n_mean, self.mean, self.mean_count = self.mean, self.mean_count, None, 0
        averaged = None
        if self.t.keep_most_feasible and interval_mean is not None and n_mean > 1:
            averaged = self._shared(lambda: self._judge_weights(trainer.model, interval_mean))
            record["mean"] = {"feasible": averaged.feasible, "worst": averaged.worst, "iterations": n_mean,
                              "ratios": averaged.ratios}
            if averaged.heldout is not None:
                record["mean"]["heldout"] = _heldout_record(averaged.heldout)
        raised = {}
        if trainer.step < self.t.iterations:  # not at the end, nor in the L-BFGS phase
            ratios = candidate_ratios(summary.judged_ratios(), None if averaged is None else averaged.judged_ratios())
            raised = trainer.balancer.on_check(ratios, self._checks_left(trainer))
        if raised:
            record["raised"] = {k: round(v, 4) for k, v in raised.items()}
        if self.t.keep_most_feasible:
            top = iterate = {"step": trainer.step, "summary": summary, "model": None, "mean": False,
                             "mean_iterations": 0}
            mean = None
            if averaged is not None:
                mean = {"step": trainer.step, "summary": averaged, "model": interval_mean, "mean": True,
                        "mean_iterations": n_mean}
                # the mean wins a tie: it is the centre of what the weights did over the interval
                if self._at_least(trainer.model, mean, iterate):
                    top = mean
            if self.best is None or self._at_least(trainer.model, top, self.best):
                if top["model"] is None:
                    top["model"] = {k: v.detach().clone() for k, v in trainer.model.state_dict().items()}
                self.best = top
            if iterate.get("objective") is not None:
                record["objective"] = iterate["objective"]
            if mean is not None and mean.get("objective") is not None:
                record["mean"]["objective"] = mean["objective"]
        trainer.log(record)
        total, count = self.objective
        mean = total / count if count else None
        before, self.objective_before, self.objective = self.objective_before, mean, [0.0, 0]
        if (self.t.stop_when_feasible and summary.all_feasible
                and mean is not None and before is not None
                and abs(before - mean) <= 0.01 * max(abs(before), abs(mean), 1e-12)):
            raise StopRun("completed", f"every shape feasible and the objectives steady at iteration {trainer.step}")
        return summary

    def _at_least(self, model: nn.Module, a: dict, b: dict) -> bool:
        """Whether candidate ``a`` (the later, or the mean at one check) is kept over ``b`` (each
        ``{"summary", "model"}``, the weights None for the model's own): a higher
        :meth:`FeasibilitySummary.rank`, or an equal one unless both are feasible throughout and
        ``b`` is better by the problem's objective while it spends no more volume than ``a`` or
        lies clear of the volume bound (``docs/structural.md``, "The kept candidate")."""
        ra, rb = a["summary"].rank(), b["summary"].rank()
        if ra != rb:
            return ra > rb
        if self.measure_objective is None or not (a["summary"].all_feasible and b["summary"].all_feasible):
            return True
        (ca, va, _), (cb, vb, inside) = self._objective(model, a), self._objective(model, b)
        return not (cb < ca and (vb <= va or inside))

    def _objective(self, model: nn.Module, candidate: dict) -> tuple[float, float, bool]:
        """The candidate's ``(objective, volume, inside)``, measured once (rank 0's in a data-parallel run)."""
        if candidate.get("objective") is None:
            def measure() -> tuple[float, float, bool]:
                if candidate["model"] is None:
                    return self.measure_objective(model)
                return self._with_weights(model, candidate["model"], self.measure_objective)

            value = measure() if self.dist is None or self.dist.is_main else None
            value = list(value if self.dist is None else self.dist.broadcast_object(value))
            candidate["objective"] = value
        return tuple(candidate["objective"])

    def _shared(self, judge: Callable[[], FeasibilitySummary]) -> FeasibilitySummary:
        """``judge()``; in a data-parallel run rank 0's, on every rank (the model is the same on all)."""
        if self.dist is None:
            return judge()
        return FeasibilitySummary.from_json(self.dist.broadcast_object(judge().to_json() if self.dist.is_main else None))

    def _judge_weights(self, model: nn.Module, weights: dict[str, Tensor]) -> FeasibilitySummary:
        """The summary of the model with ``weights`` (its own weights are put back)."""
        return self._with_weights(model, weights, self.judge)

    @staticmethod
    def _with_weights(model: nn.Module, weights: dict[str, Tensor], measure: Callable[[nn.Module], T]) -> T:
        """``measure(model)`` with ``weights`` loaded (the model's own are put back)."""
        own = {k: v.detach().clone() for k, v in model.state_dict().items()}
        model.load_state_dict(weights)
        try:
            return measure(model)
        finally:
            model.load_state_dict(own)

    def _accumulate(self, model: nn.Module) -> None:
        """Add the current weights to the running mean since the previous check."""
        state = model.state_dict()
        self.mean_count += 1
        if self.mean is None:
            self.mean = {k: v.detach().clone() for k, v in state.items()}
            return
        w = 1.0 / self.mean_count
        for k, v in state.items():
            if v.is_floating_point():
                self.mean[k].lerp_(v.detach(), w)
            else:
                self.mean[k].copy_(v)

    def _restore(self, trainer: Trainer) -> None:
        """End with the weights of the check (the iterate there, or the mean of the weights since
        the check before it) that found the most feasible shapes, the latest of equals, when those
        are not the last iterate's."""
        best, last = self.best, self.last
        if best is None or last is None or (best["step"] == trainer.step and not best.get("mean", False)):
            return
        trainer.model.load_state_dict(best["model"])
        self.last = best["summary"]
        self.restored = {"step": trainer.step, "event": "restored", "from_step": best["step"], "mean": best.get("mean", False),
                         "mean_iterations": best.get("mean_iterations", 0),
                         "feasible": best["summary"].feasible, "shapes": best["summary"].shapes,
                         "instead_of": last.feasible}
        if best["summary"].heldout is not None and last.heldout is not None:
            self.restored["heldout"] = {"feasible": best["summary"].heldout.feasible,
                                        "shapes": best["summary"].heldout.shapes, "instead_of": last.heldout.feasible}
        trainer.log(self.restored)
