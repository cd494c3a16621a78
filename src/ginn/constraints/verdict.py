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
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from ..problems.problem import Problem

__all__ = ["Violation", "Verdict", "number_text"]


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
    ``metrics.json``), ``on_set`` (judges the set, not each shape). Instances: ``metrics``, the
    metric names it reads.
    """

    name: ClassVar[str]
    on_set: ClassVar[bool] = False

    def __init__(self, problem: Problem):
        self.problem = problem
        self.metrics: tuple[str, ...] = ()

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        """Metrics this verdict reads that ``ginn eval`` does not measure (none by default):
        ``{name: value}`` for one shape, given the extracted ``shape``
        (:class:`ginn.eval.context.ExtractedShape`), the problem's metric ``context``
        (:class:`ginn.eval.context.MetricContext`), the ``field`` and the shape's latent ``z``."""
        return {}

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
