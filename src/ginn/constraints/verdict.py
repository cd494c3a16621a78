"""Verdicts: the bound a constraint states on a metric of ``ginn eval``, and its judgement.

A :class:`Verdict` reads named per-shape metrics (:data:`ginn.eval.results.METRIC_NAMES`, and any
it measures itself: ``measure``; ``None`` where a metric does not apply) and says whether one
shape violates its bound (a :class:`Violation`) and by how much (``ratio``: value over bound,
above 1 violated). A set verdict
(``on_set = True``) reads the metrics of the whole set instead (``diversity_mean`` and
``n_shapes``). The same objects judge ``ginn eval`` and the checks during training
(:mod:`ginn.eval.feasibility`), so the two never disagree on what a bound means.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from ..problems.problem import Bounds, Problem

__all__ = ["Violation", "Verdict", "IntervalVerdict", "number_text"]


@dataclass(frozen=True)
class Violation:
    """A violated bound.

    Attributes:
        value: the measured value (a number, ``{name: count}`` for Betti numbers, or None where
            it is undefined, e.g. the CD1 of an empty shape).
        bound: the bound (same kind).
        interfaces: for connectedness, the share of interface components one piece reaches.
    """

    value: Any
    bound: Any
    interfaces: float | None = None

    def to_json(self) -> dict:
        out = {"value": self.value, "bound": self.bound}
        if self.interfaces is not None:
            out["interfaces"] = self.interfaces
        return out

    @classmethod
    def from_json(cls, data: Mapping) -> Violation:
        return cls(data.get("value"), data.get("bound"), data.get("interfaces"))


def number_text(v: float | None) -> str:
    """A value for a verdict's text (``undefined (no boundary)`` for None)."""
    return "undefined (no boundary)" if v is None else f"{v:.3g}"


class Verdict(abc.ABC):
    """A bound on metrics of ``ginn eval`` (see the module docstring).

    Arguments:
        problem: the problem whose tolerances set the bound.

    Class attributes: ``name`` (the constraint's name in the verdict and in
    ``metrics.json``), ``on_set`` (judges the set, not each shape), ``judges`` (False for a report
    that never finds a shape infeasible: ``ginn eval`` measures it, the feasibility checks of
    :class:`ginn.eval.feasibility.FeasibilityCheck` do not), ``hard`` (the bound has no tolerance
    of its own, being a level of a quantity that is not an error, so that ``value / bound`` near
    1 says nothing of how far off a shape is; the check-driven multipliers raise such a bound's
    terms by their full factor, :mod:`ginn.train.balancing`), ``enforced_by`` (for a verdict that
    is no constraint's own: the loss terms whose multipliers its violation raises, as a
    constraint's does its terms'), ``objective`` (it measures the problem's objective,
    :meth:`objective_of`: the feasibility checks keep an earlier of two feasible candidates by
    it). Instances: ``metrics``, the metric names it reads, and
    ``resolves``, the least length its measure on a grid must resolve (None: none; the checks
    during training choose their grid by it, :func:`ginn.eval.feasibility.check_resolution`).
    """

    name: ClassVar[str]
    on_set: ClassVar[bool] = False
    judges: ClassVar[bool] = True
    hard: ClassVar[bool] = False
    enforced_by: ClassVar[tuple[str, ...]] = ()
    objective: ClassVar[bool] = False

    def __init__(self, problem: Problem):
        self.problem = problem
        self.metrics: tuple[str, ...] = ()
        self.resolves: float | None = None

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        """Metrics this verdict reads that ``ginn eval`` does not measure (none by default):
        ``{name: value}`` for one shape, given the extracted ``shape``
        (:class:`ginn.eval.context.ExtractedShape`), the problem's metric ``context``
        (:class:`ginn.eval.context.MetricContext`), the ``field`` and the shape's latent ``z``."""
        return {}

    def objective_of(self, field, Z) -> tuple[float, float, bool]:
        """``(objective, volume, inside)`` over the shapes of ``field`` at the codes ``Z`` ``(S, k)``
        (None: the single shape), for a verdict with ``objective``: the problem's objective (lower
        is better) and the volume fraction it was measured on, each the mean over the shapes, and
        whether every shape lies inside its volume bound by more than that measure's error; none by
        default."""
        raise NotImplementedError(f"{type(self).__name__} measures no objective")

    @abc.abstractmethod
    def violation(self, metrics: Mapping) -> Violation | None:
        """The violated bound of one shape (the set, for a set verdict), or None when met."""

    @abc.abstractmethod
    def ratio(self, metrics: Mapping) -> float | None:
        """The value over its bound (``inf`` where the value is undefined); None where the
        metric does not apply."""

    @classmethod
    def describe(cls, v: Violation) -> str:
        """A few words for a violation: ``interface 0.012 > 0.005``."""
        return f"{cls.name} {number_text(v.value)} > {number_text(v.bound)}"

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class IntervalVerdict(Verdict):
    """One per-shape metric ``metric`` within ``bounds`` (a :class:`~ginn.problems.problem.Bounds`
    from the problem's tolerances, set by the subclass); a hard bound."""

    metric: ClassVar[str]
    hard = True

    def __init__(self, problem: Problem, bounds: Bounds):
        super().__init__(problem)
        self.metrics = (self.metric,)
        self.bounds = bounds

    def violation(self, metrics: Mapping) -> Violation | None:
        v = metrics.get(self.metric)
        b = self.bounds
        if b is None or v is None or not b.violated(v):
            return None
        return Violation(float(v), b.max if b.max is not None and v > b.max else b.min)

    def ratio(self, metrics: Mapping) -> float | None:
        """The larger of ``value / max`` and ``min / value`` (above 1: violated)."""
        v = metrics.get(self.metric)
        b = self.bounds
        if b is None or v is None:
            return None
        out = 0.0
        if b.max is not None:
            out = v / b.max if b.max > 0 else (math.inf if v > 0 else 0.0)
        if b.min is not None and b.min > 0:
            out = max(out, b.min / v if v > 0 else math.inf)
        return out

    @classmethod
    def describe(cls, v: Violation) -> str:
        side = ">" if v.value > v.bound else "<"
        return f"{cls.name} {number_text(v.value)} {side} {number_text(v.bound)}"
