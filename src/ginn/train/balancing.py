"""Combining loss terms into one objective: fixed weights, constraints with tolerances and adaptive
multipliers, or an augmented Lagrangian.

Fixed weights (the paper): ``L = sum_i lambda_i l_i``.

Augmented Lagrangian (optional; the paper names the sensitivity to the many weights as a main
limitation). The constraint terms ``c_i >= 0`` (interface, design region, normal, obstacle, ...)
are driven to zero while the objective terms (eikonal, curvature, strain, connectedness,
diversity, with their configured weights) are minimised::

    L = sum_obj w_j l_j + sum_con ( lambda_i c_i + mu / 2 c_i^2 )

Every ``update_every`` iterations the multipliers take a dual ascent step
``lambda_i <- lambda_i + lambda_lr * mu * mean(c_i since the last update)`` and ``mu`` grows by
``mu_growth`` (capped at ``mu_max``). The initial multipliers are the configured weights, so a
problem's hand-tuned weights are a starting point, not a requirement.

Adaptive multipliers (``method: adaptive``): each constraint term ``l_i`` has a target ``eps_i``
(the task's :attr:`Balance.targets`, derived from the problem's
tolerances) and the objective is ``sum_obj w_j l_j + sum_con lambda_i l_i``, the Lagrangian of
``min objectives s.t. l_i <= eps_i`` up to a constant. After every step the running average
``m_i`` of ``l_i`` (an exponential average with factor ``average``, bias-corrected) moves the
multiplier by a relative step::

    r_i = tanh(log((m_i + t_i) / (eps_i + t_i)))        in (-1, 1); t_i = 1e-3 eps_i + 1e-30
    lambda_i <- clip(lambda_i + 0.01 * max(lambda_i, 0.01) * r_i, 0, 1e8)     (average 0.99)

so a violated constraint's multiplier grows by up to 1 % of itself per iteration, a satisfied
one shrinks, and an inactive one reaches 0 (below 0.01 the steps are absolute). Relative steps
make the update free of units: the same settings find multipliers of 1e-1 or 1e4, whatever the
scale of the term. A term without a target is an objective with its configured weight.

Check-driven multipliers (``method: feasibility``): the weights are the starting multipliers, and
each feasibility check during training (``training.feasibility_checks``) raises the multiplier of
the terms behind a constraint it finds violated and not on track to be met by the end of the run.
With ``q_c`` the constraint's value over its bound for the worst shape
(:func:`ginn.eval.feasibility.ratios`: CD1 / bound, volume outside E / bound, pieces inside E; the
smaller of the iterate's and the interval mean's, :func:`ginn.tasks.shape.checks.candidate_ratios`),
``q_c'`` the same at the check before and ``R`` the number of checks still to come::

    on track:  q_c (q_c / q_c')^R <= 1     (the last interval's rate, kept up, meets the bound)
    if q_c > 1 and not on track:   lambda_t <- lambda_t * min(q_c^2, 2)   for every term t of c

This is the classical augmented-Lagrangian penalty rule (raise the penalty when the violation has
not shrunk enough since the last outer iteration) with the violation measured the way the
verdict measures it, in units of the tolerance, so it needs no per-problem target in loss units,
and with "enough" set by the budget left: early in a run slow progress suffices, late in it only
a rate that reaches the bound in the checks that remain. The square overshoots: where the
violation falls like ``1 / lambda`` (a quadratic penalty), a factor ``q_c`` would only approach
the bound, ``q_c^2`` lands a factor ``q_c`` inside it. The first check only records ``q``.
Multipliers never fall below the weights, so a problem the weights already solve trains as with
``weighted`` while every check finds it on track, and a constraint that stays violated gains
weight against the others (at most a factor 2 per check).

A *hard* bound (:attr:`ginn.constraints.verdict.Verdict.hard`: an interval on a quantity that is
not an error, such as a volume fraction at most 0.48) has no tolerance to measure a violation
in: its ratio ``value / bound`` sits near 1 however wrong the shape is (0.4876 against 0.48 is
1.016, and ``q^2`` a rise of 3 %), while the terms it competes with may have risen by factors of
2. Its terms are exact penalties, met exactly once their multiplier passes a finite threshold,
so the rule is the exact-penalty one: ``lambda_t <- lambda_t * 2`` whenever the check finds the
bound violated and not on track. On the 16-shape double-load cantilever (``docs/structural.md``)
the ``q^2`` rule raised the volume's multiplier from 10 to 17.6 over the run (connectedness's
went from 10.7 to 171) and left 7 of 16 shapes over the bound; with this rule, 1 of 16.

A *gated objective* (:attr:`Balance.gated`: the mean curvature, whose minimisers need not meet
the constraints, since every plane has zero mean curvature) acts in proportion to how closely the
terms of the verdict's constraints meet their targets (:attr:`Balance.targets`)::

    weight_t = w_t * min(1, min_i eps_i / m_i)

with ``m_i`` the bias-corrected running average (factor ``AVERAGE``) of each such term ``i`` with
a positive target ``eps_i``, and full weight once every one meets its target (``metrics.jsonl``
logs it among the multipliers). Given its full
weight at once, the curvature objective of Plateau's problem flattened the zero set within 50
iterations of its start and took the surface off the polygon (CD1 0.24 at the next check), and
the run spent most of its iterations on the way back (``docs/plateau.md``); gated, the surface
stays on the polygon and moves towards the minimal surface from the first iteration.

A term that enforces several constraints (the interface: its own, and the reference verdict of
Plateau's problem, whose area is lost where the surface misses the polygon) has the largest of
their factors.

"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from torch import Tensor

from ..config import BalancingConfig, LossTerm


def _debiased(avg: float, n: int, beta: float) -> float:
    """An exponential average ``avg`` of ``n`` updates with factor ``beta``, bias-corrected (0
    before any update)."""
    return avg / (1.0 - beta ** n) if n else 0.0


class WeightedSum:
    """``sum_i w_i l_i`` with the configured weights; ``objectives``: the terms that count as
    objectives (the rest are constraints) where it matters (``training.stop_when_feasible``)."""

    def __init__(self, terms: dict[str, LossTerm], objectives=()):
        self.weights = {k: t.weight for k, t in terms.items()}
        self.objectives = set(objectives)

    def is_objective(self, term: str) -> bool:
        return term in self.objectives

    def weight(self, term: str) -> float:
        """The factor of ``term`` in the combined loss now."""
        return self.weights.get(term, 0.0)

    def combine(self, losses: dict[str, Tensor], step: int) -> Tensor:
        total = None
        for k, v in losses.items():
            if k.startswith("_"):
                continue
            t = self.weight(k) * v
            total = t if total is None else total + t
        if total is None:
            raise ValueError("no active loss term")
        return total

    def observe(self, losses: dict[str, float], step: int) -> None:
        pass

    def multipliers(self) -> dict[str, float]:
        return dict(self.weights)

    def on_check(self, ratios: dict[str, float | None], remaining: int) -> dict[str, float]:
        """A feasibility check's worst ``{constraint: value / bound}``, ``remaining`` checks still
        to come; returns the multiplier factors it applied (none here)."""
        return {}

    def state_dict(self) -> dict:
        return {}

    def load_state_dict(self, state: dict) -> None:
        pass


class AugmentedLagrangian(WeightedSum):
    """Constraints as targets (``c_i -> 0``), objectives minimised; see the module docstring."""

    def __init__(self, terms: dict[str, LossTerm], cfg: BalancingConfig):
        super().__init__(terms, cfg.objectives)
        self.cfg = cfg
        self.lam = {k: w for k, w in self.weights.items() if k not in self.objectives}
        self.mu = cfg.mu
        self._acc: dict[str, float] = {}
        self._count = 0

    def combine(self, losses: dict[str, Tensor], step: int) -> Tensor:
        total = None
        for k, v in losses.items():
            if k.startswith("_"):
                continue
            if k in self.objectives:
                t = self.weights.get(k, 0.0) * v
            else:
                t = self.lam.get(k, 0.0) * v + 0.5 * self.mu * v * v
            total = t if total is None else total + t
        if total is None:
            raise ValueError("no active loss term")
        return total

    def observe(self, losses: dict[str, float], step: int) -> None:
        for k, v in losses.items():
            if k in self.lam:
                self._acc[k] = self._acc.get(k, 0.0) + float(v)
        self._count += 1
        if self._count >= self.cfg.update_every:
            for k, s in self._acc.items():
                self.lam[k] += self.cfg.lambda_lr * self.mu * s / self._count
            self.mu = min(self.mu * self.cfg.mu_growth, self.cfg.mu_max)
            self._acc, self._count = {}, 0

    def multipliers(self) -> dict[str, float]:
        out = {k: w for k, w in self.weights.items() if k in self.objectives}
        out.update(self.lam)
        return out

    def state_dict(self) -> dict:
        return {"lam": dict(self.lam), "mu": self.mu, "acc": dict(self._acc), "count": self._count}

    def load_state_dict(self, state: dict) -> None:
        self.lam = {k: float(v) for k, v in state["lam"].items()}
        self.mu = float(state["mu"])
        self._acc = {k: float(v) for k, v in state["acc"].items()}
        self._count = int(state["count"])


class AdaptiveMultipliers(WeightedSum):
    """Constraints ``l_i <= eps_i`` with multipliers adapted from their running violation; see
    the module docstring.

    Arguments:
        terms: every loss term (the weights start the multipliers and weigh the objectives).
        targets: ``{term: eps}`` for the constraint terms (others are objectives).

    The update's constants are the class attributes ``STEP`` (largest relative change of a
    multiplier per iteration), ``AVERAGE`` (factor of the running averages), ``FLOOR`` (below it
    a multiplier moves by absolute steps, so it can reach 0) and ``MAX``; they do not depend on
    the problem (the steps are relative), so they are not settings.
    """

    STEP = 0.01
    AVERAGE = 0.99
    FLOOR = 1e-2
    MAX = 1e8

    def __init__(self, terms: dict[str, LossTerm], targets: dict[str, float]):
        self.targets = {k: float(v) for k, v in targets.items() if k in terms}
        super().__init__(terms, [k for k in terms if k not in self.targets])
        self.lam = {k: max(self.weights[k], self.FLOOR) for k in self.targets}
        self.avg = {k: 0.0 for k in self.targets}  # exponential averages, not bias-corrected
        self.seen = {k: 0 for k in self.targets}  # updates of each average

    def weight(self, term: str) -> float:
        return self.lam[term] if term in self.lam else self.weights.get(term, 0.0)

    def running(self, k: str) -> float:
        """The bias-corrected running average of constraint ``k``."""
        return _debiased(self.avg[k], self.seen[k], self.AVERAGE)

    def observe(self, losses: dict[str, float], step: int) -> None:
        beta = self.AVERAGE
        for k, v in losses.items():
            if k not in self.lam or not math.isfinite(v):
                continue
            self.avg[k] = beta * self.avg[k] + (1.0 - beta) * float(v)
            self.seen[k] += 1
            eps = self.targets[k]
            tiny = 1e-3 * eps + 1e-30
            r = math.tanh(math.log((max(self.running(k), 0.0) + tiny) / (eps + tiny)))
            lam = self.lam[k] + self.STEP * max(self.lam[k], self.FLOOR) * r
            self.lam[k] = min(max(lam, 0.0), self.MAX)

    def multipliers(self) -> dict[str, float]:
        out = {k: w for k, w in self.weights.items() if k not in self.lam}
        out.update(self.lam)
        return out

    def state_dict(self) -> dict:
        return {"lam": dict(self.lam), "avg": dict(self.avg), "seen": dict(self.seen)}

    def load_state_dict(self, state: dict) -> None:
        self.lam = {k: float(v) for k, v in state["lam"].items()}
        self.avg = {k: float(v) for k, v in state["avg"].items()}
        self.seen = {k: int(v) for k, v in state["seen"].items()}


_HUGE = 1e300  # an undefined ratio (an empty shape): violated beyond any bound


def _on_track(q: float, before: float, remaining: int) -> bool:
    """Whether ``q (q / before)^remaining <= 1``: the violation, shrinking from ``before`` to ``q``
    per check and kept at that rate, meets its bound within ``remaining`` checks."""
    return math.log(q) + max(remaining, 0) * (math.log(q) - math.log(before)) <= 0.0


class CheckedMultipliers(WeightedSum):
    """Multipliers raised by the feasibility checks; see the module docstring.

    Arguments:
        terms: every loss term (the weights start the multipliers and weigh the objectives).
        groups: ``{constraint: (term, ...)}``, the loss terms that enforce each constraint of the
            verdict (:attr:`Balance.groups`); terms in no group keep their
            weights.
        hard: the constraints whose bound has no tolerance (:attr:`Balance.hard`): raised by
            ``GROWTH`` whenever violated and off track.

    ``GROWTH`` (the largest factor per check) is a class constant: it acts on ratios to the
    tolerance, not on the problem's units.
    """

    GROWTH = 2.0
    AVERAGE = AdaptiveMultipliers.AVERAGE

    def __init__(self, terms: dict[str, LossTerm], groups: dict[str, tuple[str, ...]], objectives=(),
                 hard: tuple[str, ...] = (), gated: tuple[str, ...] = (),
                 targets: dict[str, float] | None = None):
        super().__init__(terms, objectives)
        self.hard = tuple(hard)
        self.groups = {c: tuple(t for t in ts if t in terms) for c, ts in groups.items()}
        self.groups = {c: ts for c, ts in self.groups.items() if ts}
        self.scale = {c: 1.0 for c in self.groups}  # each constraint's multipliers over their weights
        self.previous: dict[str, float] = {}  # q of each constraint at the last check
        self.gated = tuple(t for t in gated if t in terms and terms[t].weight > 0)
        enforcing = {t for ts in self.groups.values() for t in ts}
        self.gate_targets = {t: float(e) for t, e in (targets or {}).items() if t in enforcing and e > 0} if self.gated else {}
        self.avg = {t: 0.0 for t in self.gate_targets}  # running averages, not bias-corrected
        self.seen = {t: 0 for t in self.gate_targets}

    def weight(self, term: str) -> float:
        w = self.weights.get(term, 0.0)
        if term in self.gated:
            return w * self.gate()
        scales = [self.scale[c] for c, ts in self.groups.items() if term in ts]
        return w * max(scales) if scales else w  # a term of several constraints: the largest demand

    def gate(self) -> float:
        """The factor of the gated objectives: ``min(1, eps_i / m_i)`` over the enforcing terms
        with a positive target seen so far (1 before any)."""
        out = 1.0
        for t, eps in self.gate_targets.items():
            m = _debiased(self.avg[t], self.seen[t], self.AVERAGE)
            out = min(out, eps / m) if m > 0 else out
        return out

    def observe(self, losses: dict[str, float], step: int) -> None:
        for t in self.gate_targets:
            v = losses.get(t)
            if v is not None and math.isfinite(v):
                self.avg[t] = self.AVERAGE * self.avg[t] + (1.0 - self.AVERAGE) * float(v)
                self.seen[t] += 1

    def on_check(self, ratios: dict[str, float | None], remaining: int) -> dict[str, float]:
        """Update from one check's worst ratios ``{constraint: value / bound}`` (None: undefined,
        e.g. an empty shape) with ``remaining`` checks still to come; returns the factors applied
        ``{constraint: factor}``."""
        raised = {}
        for c in self.groups:
            if c not in ratios:
                continue
            q = ratios[c]
            q = _HUGE if q is None or not math.isfinite(float(q)) else max(float(q), 1e-300)
            before = self.previous.get(c)
            if before is not None and q > 1.0 and not _on_track(q, before, remaining):
                f = self.GROWTH if c in self.hard else min(q * q, self.GROWTH)
                self.scale[c] *= f
                raised[c] = f
            self.previous[c] = q
        return raised

    def multipliers(self) -> dict[str, float]:
        return {k: self.weight(k) for k in self.weights}

    def state_dict(self) -> dict:
        out = {"scale": dict(self.scale), "previous": dict(self.previous)}
        if self.gate_targets:
            out.update(avg=dict(self.avg), seen=dict(self.seen))
        return out

    def load_state_dict(self, state: dict) -> None:
        self.scale.update({k: float(v) for k, v in state["scale"].items()})
        self.previous = {k: float(v) for k, v in state["previous"].items()}
        self.avg.update({k: float(v) for k, v in state.get("avg", {}).items() if k in self.avg})
        self.seen.update({k: int(v) for k, v in state.get("seen", {}).items() if k in self.seen})


@dataclass(frozen=True)
class Balance:
    """What a task tells the balancer about its terms (:meth:`ginn.train.task.Task.balance`).

    Attributes:
        targets: ``{term: eps}``: the terms that are constraints ``term <= eps`` under
            ``adaptive`` (the rest are objectives).
        groups: ``{constraint: (term, ...)}``: the constraints of the feasibility verdict and the
            terms that enforce each, for ``feasibility``.
        hard: the constraints of ``groups`` whose bound has no tolerance (an interval on a
            volume or an area): a violation raises them by the full factor.
        gated: the objectives that act in proportion to how closely the terms of ``groups`` meet
            their ``targets`` (:attr:`ginn.constraints.Constraint.gated`), for ``feasibility``.
    """

    targets: dict[str, float] = field(default_factory=dict)
    groups: dict[str, tuple[str, ...]] = field(default_factory=dict)
    hard: tuple[str, ...] = ()
    gated: tuple[str, ...] = ()


def make_balancer(terms: dict[str, LossTerm], cfg: BalancingConfig, balance: Balance | None = None) -> WeightedSum:
    """The balancer of ``cfg.method`` for ``terms``, with the task's targets and groups."""
    b = balance or Balance()
    if cfg.method == "weighted":
        return WeightedSum(terms, cfg.objectives)
    if cfg.method == "adaptive":
        return AdaptiveMultipliers(terms, b.targets)
    if cfg.method == "feasibility":
        return CheckedMultipliers(terms, b.groups, cfg.objectives, b.hard, b.gated, b.targets)
    return AugmentedLagrangian(terms, cfg)


