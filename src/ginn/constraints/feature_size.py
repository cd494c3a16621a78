"""Least feature sizes: every part of the solid at least ``t`` thick (``tolerances.min_thickness``)
and every gap and hole at least ``t`` wide (``tolerances.min_gap``).

Verdict: the share of the shape's volume that the morphological opening by a ball of diameter
``t`` removes (``thickness_removed``), or that the closing adds (``gap_filled``), measured on the
evaluation grid (:mod:`ginn.extract.morphology`), at most the spec's ``removed``. The nodes within
the interface tolerance plus ``t / 2`` of an interface's rim are not counted
(:meth:`ginn.problems.Problem.near_rims`): a rim is an edge the spec prescribes (a bolt hole's wall
meets its seat at a right angle), the opening rounds it whatever the shape, and all it removes
there lies within ``t / 2`` of the edge. A wall that is too thin along an interface is still
counted away from the interface's rims. On the bracket's shapes (``t = 0.05``) the opening removed
1.17 to 1.42 % of the volume, 0.54 to 0.67 % of it within 0.03 of the rims, nearly all that it
removed near the interfaces (``docs/results.md``, "The interface residual in units of length").

Loss: the inner-normal segment test. A ball of diameter ``t`` that touches the boundary at ``p``
from inside holds the segment from ``p`` to ``p - t n`` (``n`` the outward unit normal); where the
solid is thinner than ``t`` that segment leaves it. So at each surface sample ``p`` (the points
projected onto ``f = 0``, :meth:`ginn.constraints.Batch.surface`) the field is read at ``p - s n``
for ``s = t/4, t/2, 3t/4, t`` and the loss is the mean of ``relu(f)`` there: where a neck, a plate
or a tip is thinner than ``t`` the far side of it lies on the segment, and the penalty lowers the
field there, growing the solid on that side until the segment stays inside. It reads only the
sign of ``f`` along the segment, so it holds for a field that is not a distance. For the gaps it
is the same outward: ``relu(-f)`` at ``p + s n``, where the segment crosses another part of the
solid. An exact penalty (power 1) in units of length, like the containment terms; the checks raise
its multiplier while the verdict is violated.

The opening also rounds every convex edge (a right angle loses ``(1 - pi / 4) (t / 2)^2`` of
area), which the segment test does not see: its segment stays inside at a convex edge. A ball of
radius ``r = t / 2`` rolls inside a smooth solid along its whole boundary exactly when the solid is
at least ``t`` thick (the segments) and no principal curvature of its boundary is above ``1 / r``
(convex). So each bound has a second term on the edges (``thickness_edges``, ``gap_edges``): at
the surface samples with Hessians (:meth:`ginn.constraints.Batch.surface_hessians`) away from the
interfaces and their rims, the mean of ``min(relu(kappa r - 1), CLIP)``, ``kappa`` the largest convex principal
curvature (for the gaps: the largest concave one, where the closing fills an inner corner),
dimensionless like the fillet radius's term (:mod:`ginn.constraints.fillet`). Without it a part
that fills a sharp edge of its design region keeps that edge: on the bracket's shapes the opening
by a ball of 0.05 removed 1.1 % of the volume within 0.025 of E's boundary and 0.15 % elsewhere.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from torch import Tensor

from .. import fields
from ..extract.morphology import closing_added, opening_removed
from ..extract.proximity import nodes_near
from ..problems.problem import FeatureSize, Problem
from .base import Constraint, Setting, Stage
from .batch import Batch
from .fillet import curvature_hinge
from .samples import DOMAIN
from .verdict import Verdict, Violation, number_text

__all__ = ["MinThicknessVerdict", "MinGapVerdict", "MinThickness", "MinGap", "ThicknessEdges", "GapEdges",
           "SEGMENT_FRACTIONS", "signed_curvature"]

#: where along the normal segment of length ``t`` the field is read, as fractions of ``t``
SEGMENT_FRACTIONS = (0.25, 0.5, 0.75, 1.0)


class _FeatureVerdict(Verdict):
    """A share of the shape's volume at most the bound ``removed`` (module docstring)."""

    metric: str = ""

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = (self.metric,)
        self.bound: FeatureSize = getattr(problem.tolerances, self.name)
        self.resolves = self.bound.size  # the ball's diameter
        self._rims = None

    def _value(self, inside, spacing, weights, left_out) -> float | None:
        raise NotImplementedError

    def rims(self, grid) -> np.ndarray:
        """``(grid.shape)`` bool: the nodes within the interface tolerance plus the ball's radius of
        an interface's rim (:meth:`ginn.problems.Problem.near_rims`), once per grid."""
        if self._rims is None or self._rims[0] is not grid:
            reach = self.problem.interface_tolerance + 0.5 * self.bound.size
            self._rims = (grid, nodes_near(self.problem.interfaces, grid, np.ones(grid.shape, dtype=bool), reach, rims=True))
        return self._rims[1]

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        g = context.grid
        return {self.metric: self._value(shape.inside, g.spacing, context.weights, self.rims(g))}

    def violation(self, metrics: Mapping) -> Violation | None:
        v = metrics.get(self.metric)
        if v is None or v <= self.bound.removed:
            return None
        return Violation(float(v), self.bound.removed)

    def ratio(self, metrics: Mapping) -> float | None:
        v = metrics.get(self.metric)
        if v is None:
            return None
        return v / self.bound.removed if self.bound.removed > 0 else (float("inf") if v > 0 else 0.0)

    @classmethod
    def describe(cls, v: Violation) -> str:
        return f"{cls.name}: {cls.metric} {number_text(v.value)} > {number_text(v.bound)}"


class MinThicknessVerdict(_FeatureVerdict):
    """``thickness_removed``, the share of the volume the opening by the ball removes, within bound."""

    name = "min_thickness"
    metric = "thickness_removed"

    def _value(self, inside, spacing, weights, left_out):
        return opening_removed(inside, spacing, self.bound.size, weights, left_out)


class MinGapVerdict(_FeatureVerdict):
    """``gap_filled``, the volume the closing by the ball adds over the shape's, within bound."""

    name = "min_gap"
    metric = "gap_filled"

    def _value(self, inside, spacing, weights, left_out):
        return closing_added(inside, spacing, self.bound.size, weights, left_out)


class _Segments(Constraint):
    """The normal segment test (module docstring); ``sign`` -1 reads inward (the solid), +1
    outward (the void)."""

    stage = Stage.FIELD
    samples = (DOMAIN,)
    sign = -1.0
    verdict_type: type[_FeatureVerdict] = MinThicknessVerdict

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = self.verdict_type(setting.problem)
        self.size = self._verdict.bound.size

    @property
    def verdict(self) -> _FeatureVerdict:
        return self._verdict

    def loss(self, batch: Batch) -> Tensor | None:
        srf = batch.surface()
        ok = srf.converged.reshape(-1)
        if not bool(ok.any()):
            return None
        p = srf.x.reshape(-1, batch.d)[ok]  # (m, d)
        z = None if batch.Z is None else batch.latents_of(srf.x)[ok]
        n = fields.evaluate(batch.model, p, z, grad=True, create_graph=False).grad
        n = n / n.norm(dim=-1, keepdim=True).clamp_min(1e-12)
        s = torch.tensor(SEGMENT_FRACTIONS, device=p.device, dtype=p.dtype) * self.size  # (K,)
        q = (p[:, None, :] + self.sign * s[None, :, None] * n[:, None, :]).reshape(-1, batch.d)  # (m K, d)
        zq = None if z is None else z.repeat_interleave(len(s), dim=0)
        f = batch.model(q, zq)
        return torch.relu(-self.sign * f).mean()

    def target(self) -> float:
        """0: no segment leaves the solid (the void)."""
        return 0.0


class MinThickness(_Segments):
    """Every part of the solid at least ``min_thickness.size`` thick (module docstring)."""

    name = "thickness"
    sign = -1.0
    verdict_type = MinThicknessVerdict


class MinGap(_Segments):
    """Every gap and hole at least ``min_gap.size`` wide (module docstring)."""

    name = "gap"
    sign = 1.0
    verdict_type = MinGapVerdict


def signed_curvature(grad: Tensor, hess: Tensor, convex: bool) -> Tensor:
    """The largest convex principal curvature of the level set (``convex``), or the largest
    concave one as a positive number, at each point, ``(m,)``; negative where there is none:
    ``1 / r`` on the outside of a circle or a sphere of radius ``r`` (``f = |x| - r``)."""
    if grad.shape[-1] == 2:
        k = fields.mean_curvature(grad, hess)
        return k if convex else -k
    k = fields.principal_curvatures(grad, hess)  # (m, 2), ascending
    return k[:, 1] if convex else -k[:, 0]


class _Edges(Constraint):
    """No principal curvature above ``2 / size`` on the solid's side (``convex``) or the void's
    (module docstring)."""

    stage = Stage.SURFACE
    convex = True
    verdict_type: type[_FeatureVerdict] = MinThicknessVerdict

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = self.verdict_type(setting.problem)
        self.radius = 0.5 * self._verdict.bound.size

    @property
    def verdict(self) -> _FeatureVerdict:
        return self._verdict

    def loss(self, batch: Batch) -> Tensor | None:
        return curvature_hinge(batch, self.setting.problem, self.radius,
                               lambda grad, hess: signed_curvature(grad, hess, self.convex))

    def target(self) -> float:
        """0: no edge sharper than the ball."""
        return 0.0


class ThicknessEdges(_Edges):
    """No convex edge sharper than the ``min_thickness`` ball (module docstring)."""

    name = "thickness_edges"
    convex = True
    verdict_type = MinThicknessVerdict


class GapEdges(_Edges):
    """No concave edge sharper than the ``min_gap`` ball (module docstring)."""

    name = "gap_edges"
    convex = False
    verdict_type = MinGapVerdict
