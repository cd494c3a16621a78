"""The eikonal objective: ``|grad f| = 1``, a field that is a distance (paper Section 3).

Loss: ``mean (|grad f| - 1)^2`` (:class:`ginn.losses.EikonalLoss`) over the domain samples and
the band around the interfaces.
"""

from __future__ import annotations

import torch
from torch import Tensor

from ..losses.constraints import EikonalLoss
from .base import Constraint
from .batch import Batch
from .samples import BAND, DOMAIN

__all__ = ["Eikonal"]


class Eikonal(Constraint):
    """``|grad f| = 1`` (see the module docstring)."""

    name = "eikonal"
    samples = (DOMAIN, BAND)
    fn = EikonalLoss()

    def loss(self, batch: Batch) -> Tensor:
        g = batch.g["domain"] if "band" not in batch.g else torch.cat([batch.g["domain"], batch.g["band"]], dim=1)
        return self.fn(g.reshape(-1, batch.d))

    def target(self) -> float:
        """0.01: a mean squared deviation of a tenth in ``|grad f|``."""
        return 0.01
