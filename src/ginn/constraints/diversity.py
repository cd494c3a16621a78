"""The diversity objective of a generative model (paper Appendix E), and its optional lower bound.

Loss: ``-delta``, the aggregated distance between the shapes measured at their surface samples
(:func:`ginn.losses.diversity.diversity_nearest` for the minimal aggregation, equation 11, which
evaluates only the nearest pairs; :func:`ginn.losses.diversity.diversity` for the sum, equation
10; across ranks under data parallelism, :func:`ginn.train.distributed.cross_values_sharded`).

Where the spec states ``tolerances.diversity``, the verdict bounds the set,
``diversity_mean >= tolerances.diversity * unit_scale`` (equation 6 over the chamfer distances
of equation 5), and the term is that constraint rather than an objective, held by every shape:
its loss is the mean over the step's shapes of ``relu(1 - m_i / bound)``, ``m_i`` shape ``i``'s
mean distance to the others (:func:`ginn.losses.diversity.shape_shares`, the rows that equation 6
aggregates, so that the set meets the verdict's bound once every shape does) from the chamfer
distances between the shapes' boundary samples (:func:`ginn.losses.diversity.boundary_distances`:
each sample's distance to the nearest sample of the other shape, with the boundary sensitivity as
its gradient). Once every shape is as far from the rest as asked the term is zero and the other
objectives (a compliance) choose the shapes: maximising the diversity instead pushed every shape
away from its nearest neighbour whatever the cost.

Why each shape's share rather than the set's: the set's ``delta_mean`` is met as well by a family
that runs along one direction as by one that bends round its middle, and a shortfall on the set
pushes its end shapes hardest (on a line, a point's gradient of the summed distances grows with
its rank from the middle), so a family of one latent spread to a bound stretched into a segment
whose ends were its worst shapes (``docs/structural.md``, "Sixteen shapes"). A shape in the middle
of a segment has half the mean distance of an end shape, so the shortfall on its own share pushes
it off the segment, across it (along it its mean distance does not change), and the family bends:
for the same ``delta_mean`` its shapes stay nearer their middle. The run logs
``_diversity_mean``, the training estimate of the set's ``delta_mean``.

The estimate and the verdict still differ: the verdict samples the extracted boundaries
uniformly and measures exact distances, where the step has its own boundary samples (a 16-shape
cantilever 700 iterations into its run: the estimate 0.118, the verdict 0.095). So each feasibility
check calibrates the term: the bound it holds each share's estimate to is the verdict's bound times the
estimate's running average (:attr:`Diversity.AVERAGE`) over the verdict's measurement of the
reported shapes (:meth:`Diversity.checked`; 1 before the first check and without checks).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import torch
from torch import Tensor

from .. import fields
from ..losses.diversity import aggregate, boundary_distances, distance_matrix, diversity, diversity_nearest, mean_diversity, shape_shares
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
    """The shapes as different as possible, or as different as the bound asks (see the module
    docstring)."""

    name = "diversity"
    stage = Stage.SURFACE
    #: the factor of the running average of the estimate (about the last ten steps)
    AVERAGE = 0.9

    def __init__(self, setting: Setting):
        super().__init__(setting)
        p = setting.problem
        self._verdict = LeastDiversity(p) if p.tolerances.diversity is not None else None
        self.calibration = 1.0  # the estimate over the verdict's measurement at the last check
        self.average: list = [0.0, 0]  # the running average of the estimate (not bias-corrected, a tensor once
        # updated, so that a step never waits for the device) and its count

    @property
    def verdict(self) -> LeastDiversity | None:
        return self._verdict

    def shortfall(self, batch: Batch) -> Tensor:
        """The mean over the step's shapes of ``relu(1 - m_i / bound)``, ``m_i`` each shape's mean
        distance to the others (module docstring)."""
        srf = batch.surface()
        Xf = srf.x.reshape(-1, batch.d)
        v = fields.evaluate(batch.model, Xf, batch.latents_of(srf.x), grad=True, create_graph=True)
        f, g, x, mask = v.f.reshape(srf.converged.shape), v.grad.detach().reshape(srf.x.shape), srf.x, srf.converged
        if batch.dist is not None:  # every shape's samples on every rank; the field values keep their graph
            ctx = batch.dist
            x, g = ctx.all_gather_cat(x.detach(), dim=0), ctx.all_gather_cat(g, dim=0)
            mask = ctx.all_gather_cat(mask.to(torch.uint8), dim=0).bool()
            f = ctx.all_gather_cat_autograd(f, dim=0)
        D = distance_matrix(boundary_distances(x, mask, f, g), mask)
        delta = mean_diversity(D)
        batch.diagnostics["_diversity_mean"] = delta.detach()
        avg, n = self.average
        self.average = [self.AVERAGE * avg + (1.0 - self.AVERAGE) * delta.detach(), n + 1]
        return torch.relu(1.0 - shape_shares(D) / (self.calibration * self._verdict.bound)).mean()

    def estimate(self) -> float | None:
        """The bias-corrected running average of the training estimate (None before a step)."""
        avg, n = self.average
        return float(avg) / (1.0 - self.AVERAGE ** n) if n else None

    def checked(self, ratios: Mapping[str, float | None]) -> None:
        """Calibrate on the check's ``diversity_mean`` (``bound / ratio``; module docstring)."""
        q, est = ratios.get("diversity"), self.estimate()
        if self._verdict is None or q is None or est is None or not math.isfinite(q) or q <= 0:
            return
        self.calibration = est / (self._verdict.bound / q)

    def state_dict(self) -> dict:
        if self._verdict is None:
            return {}
        avg, n = self.average
        return {"calibration": self.calibration, "average": [avg.clone() if torch.is_tensor(avg) else avg, n]}

    def load_state_dict(self, state: dict) -> None:
        self.calibration = float(state.get("calibration", 1.0))
        avg, n = state.get("average", [0.0, 0])
        self.average = [avg.to(self.setting.device) if torch.is_tensor(avg) else float(avg), int(n)]

    def loss(self, batch: Batch) -> Tensor | None:
        if batch.Z is None:
            return None
        if self._verdict is not None:
            return self.shortfall(batch)
        srf = batch.surface()
        dv = self.setting.cfg.diversity
        if batch.dist is not None:  # all shapes' cross values, exact gradients
            V, M = cross_values_sharded(batch.model, srf.x, batch.Z, srf.converged, batch.dist)
            return -aggregate(distance_matrix(V, M, dv.eps), dv.aggregation, dv.p)
        if dv.aggregation == "min":
            return -diversity_nearest(batch.model, srf.x, batch.Z, srf.converged, p=dv.p, eps=dv.eps)
        return -diversity(batch.model, srf.x, batch.Z, srf.converged, kind=dv.aggregation, p=dv.p, eps=dv.eps)
