"""The diversity objective of a generative model (paper Appendix E), and its optional lower bound.

Loss: ``-delta``, the aggregated distance between the shapes measured at their surface samples
(:func:`ginn.losses.diversity.diversity_nearest` for the minimal aggregation, equation 11, which
evaluates only the nearest pairs; :func:`ginn.losses.diversity.diversity` for the sum, equation
10; across ranks under data parallelism, :func:`ginn.train.distributed.cross_values_sharded`).

Verdict (only where the spec states ``tolerances.diversity``): a bound on the set,
``diversity_mean >= tolerances.diversity * unit_scale``; the diversity is then a *bounded
objective*: its multiplier also falls while the set is more diverse than asked.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from torch import Tensor

from ..losses.diversity import aggregate, distance_matrix, diversity, diversity_nearest
from ..problems.problem import Problem
from ..train.distributed import cross_values_sharded
from .base import Constraint, Setting, Stage
from .batch import Batch
from .verdict import Verdict, Violation, number_text

__all__ = ["Diversity", "LeastDiversity"]


class LeastDiversity(Verdict):
    """``diversity_mean`` of the set at least ``tolerances.diversity * unit_scale`` (sets of two or
    more shapes)."""

    name = "diversity"
    on_set = True

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("diversity_mean",)
        self.bound = problem.tolerances.diversity * problem.unit_scale

    def violation(self, metrics: Mapping) -> Violation | None:
        div = metrics.get("diversity_mean")
        if metrics.get("n_shapes", 0) < 2 or (div is not None and div >= self.bound):
            return None
        return Violation(div, self.bound)

    def ratio(self, metrics: Mapping) -> float | None:
        if metrics.get("n_shapes", 0) < 2:
            return None
        div = metrics.get("diversity_mean")
        return self.bound / div if div is not None and div > 0 else math.inf

    @classmethod
    def describe(cls, v: Violation) -> str:
        return f"{cls.name} {number_text(v.value)} < {number_text(v.bound)}"


class Diversity(Constraint):
    """The shapes as different as possible (see the module docstring)."""

    name = "diversity"
    stage = Stage.SURFACE

    def __init__(self, setting: Setting):
        super().__init__(setting)
        p = setting.problem
        self._verdict = LeastDiversity(p) if p.tolerances.diversity is not None else None

    @property
    def verdict(self) -> LeastDiversity | None:
        return self._verdict

    def bounds_objective(self) -> bool:
        return self._verdict is not None

    def loss(self, batch: Batch) -> Tensor | None:
        if batch.Z is None:
            return None
        srf = batch.surface()
        dv = self.setting.cfg.diversity
        if batch.dist is not None:  # all shapes' cross values, exact gradients
            V, M = cross_values_sharded(batch.model, srf.x, batch.Z, srf.converged, batch.dist)
            return -aggregate(distance_matrix(V, M, dv.eps), dv.aggregation, dv.p)
        if dv.aggregation == "min":
            return -diversity_nearest(batch.model, srf.x, batch.Z, srf.converged, p=dv.p, eps=dv.eps)
        return -diversity(batch.model, srf.x, batch.Z, srf.converged, kind=dv.aggregation, p=dv.p, eps=dv.eps)
