"""Area bounds: the area (2D: length) of each shape's boundary within the bounds the spec states
(``tolerances.area``: at most, at least, or both), in the problem's units.

Verdict: ``boundary_area``, the measure of the extracted boundary's level-set elements (the caps
where the domain cuts the shape are no boundary of the part), within the bounds.

Loss: per shape, ``relu(A + s - max) / max + relu(min - A + s) / min``, the mean over the shapes.
``A`` estimates the area by the coarea formula from the uniform domain samples,
``vol(X) * mean_i delta_w(f_i) |grad f_i|`` with the smoothed delta
``delta_w(t) = sigmoid'(t / w) / w`` (it integrates to 1 across the boundary, whatever the
field's slope): differentiable w.r.t. the field's values and gradients at the samples. ``w`` is
half the mean sample spacing (:func:`ginn.constraints.volume.step_width`) and ``s`` the estimate's
standard error, by which the bound is tightened as the volume bound's is: relative to the bound,
so that the term has no scale.
"""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import Tensor

from ..problems.problem import Problem
from .base import Constraint, Setting
from .batch import Batch
from .samples import DOMAIN
from .verdict import IntervalVerdict
from .volume import step_width

__all__ = ["AreaVerdict", "Area", "coarea_estimate"]


def coarea_estimate(f: Tensor, g: Tensor, width: float, volume: float) -> tuple[Tensor, Tensor]:
    """The boundary area of each shape from uniform samples of the domain, and its standard error
    (detached): ``f (S, n)`` values and ``g (S, n, d)`` gradients there, ``volume = vol(X)``;
    ``(S,)`` each (module docstring)."""
    t = torch.sigmoid(f / width)
    y = volume * t * (1 - t) / width * g.norm(dim=-1)  # (S, n)
    n = y.shape[1]
    err = y.detach().std(dim=1) / math.sqrt(n) if n > 1 else torch.zeros_like(y[:, 0])
    return y.mean(dim=1), err


class AreaVerdict(IntervalVerdict):
    """``boundary_area`` within ``tolerances.area`` (problems that state it)."""

    name = "area"
    metric = "boundary_area"

    def __init__(self, problem: Problem):
        super().__init__(problem, problem.tolerances.area)

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        b = shape.boundary
        if b.n_elements == 0:
            return {"boundary_area": 0.0}
        return {"boundary_area": float(b.element_measures()[b.level_set_elements()].sum())}


class Area(Constraint):
    """Each shape's boundary area within its bounds (module docstring)."""

    name = "area"
    samples = (DOMAIN,)

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = AreaVerdict(setting.problem)
        self.width = step_width(setting)
        dom = setting.problem.domain
        self.volume = math.prod(float(h - lo) for lo, h in zip(dom.lo, dom.hi))

    @property
    def verdict(self) -> AreaVerdict:
        return self._verdict

    def loss(self, batch: Batch) -> Tensor | None:
        b = self._verdict.bounds
        if "domain" not in batch.g:
            return None
        A, err = coarea_estimate(batch.f["domain"], batch.g["domain"], self.width, self.volume)
        zero = torch.zeros_like(A)
        over = torch.relu(A + err - b.max) / b.max if b.max is not None else zero
        under = torch.relu(b.min - A + err) / b.min if b.min is not None and b.min > 0 else zero
        return (over + under).mean()

    def target(self) -> float:
        """0: within the bounds."""
        return 0.0
