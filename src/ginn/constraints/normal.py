"""The normal constraint: the shape's outward normal on the interfaces is the prescribed one.

Loss: ``mean over I of |grad f / |grad f| - n|^2`` (:class:`ginn.losses.NormalLoss`) over the
interface samples that carry a normal. Not part of the verdict.
"""

from __future__ import annotations

import math

from torch import Tensor

from ..losses.constraints import NormalLoss
from .base import Constraint
from .batch import Batch
from .samples import INTERFACE

__all__ = ["Normal"]


class Normal(Constraint):
    """Prescribed normals on the interfaces (see the module docstring)."""

    name = "normal"
    samples = (INTERFACE,)
    fn = NormalLoss()

    def loss(self, batch: Batch) -> Tensor:
        d = batch.d
        ni = batch.attrs["normals"].reshape(-1, d)
        has = ni.norm(dim=-1) > 0.5
        return self.fn(batch.g["interface"].reshape(-1, d)[has], ni[has])

    def target(self) -> float:
        """``2 (1 - cos a)`` with ``a = tolerances.normal_angle``: the mean ``|n - n_bar|^2`` of
        normals off by that angle."""
        return 2.0 * (1.0 - math.cos(math.radians(self.setting.problem.tolerances.normal_angle)))
