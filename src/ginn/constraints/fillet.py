"""The smallest radius of curvature (``tolerances.min_radius``): no edge of the boundary sharper
than a fillet of radius ``r``, i.e. every principal curvature at most ``1 / r`` in absolute value
(convex and concave edges alike), away from the interfaces, whose geometry the problem fixes.

Verdict: ``sharp_share``, the share of the boundary (area-uniform points on the zero level set
near the extracted boundary, :func:`ginn.extract.curvature.boundary_curvatures`) whose largest
absolute principal curvature exceeds ``1 / r``, the points within the interface tolerance of an
interface or within the tolerance plus ``r`` of its rim left out (the edges an interface prescribes,
:meth:`ginn.problems.Problem.near_rims`); at most ``share``. ``ginn eval`` also reports the largest curvature found,
``curvature_max``.

Loss: at the surface samples with Hessians (:meth:`ginn.constraints.Batch.surface_hessians`) away
from the interfaces and their rims, the mean of ``min(relu(kappa r - 1), CLIP)``, ``kappa`` the largest absolute
principal curvature: dimensionless, zero where the boundary is as smooth as asked, and clipped
where a sample lands on a near-singular point of the field, as the strain is.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import torch
from torch import Tensor

from ..extract.curvature import boundary_curvatures, largest_curvature
from ..problems.problem import CurvatureBound, Problem
from .base import Constraint, Setting, Stage
from .batch import Batch
from .verdict import Verdict, Violation, number_text

__all__ = ["MinRadiusVerdict", "MinRadius", "CLIP", "curvature_hinge"]

#: the largest per-point value of the loss (``kappa r - 1``)
CLIP = 10.0


def curvature_hinge(batch: Batch, problem: Problem, radius: float,
                    curvature: Callable[[Tensor, Tensor], Tensor]) -> Tensor | None:
    """The mean of ``min(relu(kappa radius - 1), CLIP)`` at the surface samples with Hessians away
    from the interfaces and their rims (:meth:`ginn.problems.Problem.near_rims`), ``kappa =
    curvature(grad (q, d), hess (q, d, d)) -> (q,)``; None where no sample is left."""
    v, X = batch.surface_hessians()
    if v.hessian.shape[0] == 0:
        return None
    with torch.no_grad():
        x = X[v.hessian_index]
        keep = ~(problem.near_interfaces(x) | problem.near_rims(x, radius))
    if not bool(keep.any()):
        return None
    k = torch.nan_to_num(curvature(v.hessian_grad[keep], v.hessian[keep]), nan=0.0, posinf=0.0, neginf=0.0)
    return torch.clamp(torch.relu(k * radius - 1.0), max=CLIP).mean()


class MinRadiusVerdict(Verdict):
    """``sharp_share`` at most ``tolerances.min_radius.share`` (module docstring)."""

    name = "min_radius"
    #: area-uniform boundary points per shape
    n_samples = 2048

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("sharp_share",)
        self.bound: CurvatureBound = problem.tolerances.min_radius

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        x, k = boundary_curvatures(field, z, shape.boundary, self.n_samples, np.random.default_rng(0),
                                   step_cap=float(context.grid.spacing.max()))
        if len(k) == 0:
            return {"sharp_share": None, "curvature_max": None}
        with torch.no_grad():
            xt = torch.as_tensor(x, dtype=torch.float64)
            keep = ~(self.problem.near_interfaces(xt) | self.problem.near_rims(xt, self.bound.radius)).numpy()
        if not keep.any():
            return {"sharp_share": None, "curvature_max": None}
        k = k[keep]
        return {"sharp_share": float(np.mean(k > 1.0 / self.bound.radius)), "curvature_max": float(k.max())}

    def violation(self, metrics: Mapping) -> Violation | None:
        v = metrics.get("sharp_share")
        if v is None or v <= self.bound.share:
            return None
        return Violation(float(v), self.bound.share)

    def ratio(self, metrics: Mapping) -> float | None:
        v = metrics.get("sharp_share")
        if v is None:
            return None
        return v / self.bound.share if self.bound.share > 0 else (math.inf if v > 0 else 0.0)

    @classmethod
    def describe(cls, v: Violation) -> str:
        return f"min_radius: {number_text(v.value)} of the boundary sharper > {number_text(v.bound)}"


class MinRadius(Constraint):
    """No edge sharper than the fillet radius (module docstring)."""

    name = "fillet"
    stage = Stage.SURFACE

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = MinRadiusVerdict(setting.problem)
        self.radius = self._verdict.bound.radius

    @property
    def verdict(self) -> MinRadiusVerdict:
        return self._verdict

    def loss(self, batch: Batch) -> Tensor | None:
        return curvature_hinge(batch, self.setting.problem, self.radius, largest_curvature)

    def target(self) -> float:
        """0: no surface sample sharper than the radius."""
        return 0.0
