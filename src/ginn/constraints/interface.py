"""The interface constraint: the shape's boundary passes through the interfaces I.

Loss: ``mean over I of f^2`` (:class:`ginn.losses.InterfaceLoss`); with
``sampling.interface_corner_weight > 1`` the interfaces' corners (polyline vertices, end points
included) join the samples with that weight. Verdict: ``interface_cd1 <= tolerances.interface *
unit_scale`` (the one-sided Chamfer distance from I to the boundary, equation 4).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import torch
from torch import Tensor

from .. import fields
from ..geometry import sampling
from ..losses.constraints import InterfaceLoss
from ..problems.problem import Problem
from .base import Constraint, Setting
from .batch import Batch
from .samples import INTERFACE
from .verdict import Verdict, Violation

__all__ = ["Interface", "InterfaceVerdict"]


class InterfaceVerdict(Verdict):
    """``interface_cd1`` within the interface tolerance (problems with interfaces)."""

    name = "interface"

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("interface_cd1",)
        self.bound = problem.tolerances.interface * problem.unit_scale

    def violation(self, metrics: Mapping) -> Violation | None:
        if not self.problem.interfaces:
            return None
        cd1 = metrics.get("interface_cd1")
        ok = cd1 is not None and math.isfinite(cd1)
        if ok and cd1 <= self.bound:
            return None
        return Violation(float(cd1) if ok else None, self.bound)  # None: no boundary to measure from

    def ratio(self, metrics: Mapping) -> float | None:
        if not self.problem.interfaces:
            return None
        cd1 = metrics.get("interface_cd1")
        return float(cd1) / self.bound if cd1 is not None and math.isfinite(cd1) else math.inf


class Interface(Constraint):
    """``f = 0`` on the interfaces (see the module docstring)."""

    name = "interface"
    samples = (INTERFACE,)

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = InterfaceVerdict(setting.problem)
        self.fn = InterfaceLoss()
        c = sampling.interface_corners(setting.problem.interfaces, setting.device, setting.dtype)
        self.corners = c if c.shape[0] > 0 else None

    @property
    def verdict(self) -> InterfaceVerdict:
        return self._verdict

    def loss(self, batch: Batch) -> Tensor:
        fi = batch.f["interface"].reshape(-1)
        weight = self.setting.cfg.sampling.interface_corner_weight
        if self.corners is None or weight <= 1:
            return self.fn(fi)
        if batch.Z is None:
            fc = batch.model(self.corners, None)
        else:
            fc = batch.model(*fields.broadcast_latents(self.corners, batch.Z))
        w = torch.cat([torch.ones_like(fi), torch.full_like(fc, weight)])
        return self.fn(torch.cat([fi, fc]), w)

    def target(self) -> float:
        """``d^2`` with ``d`` half the interface tolerance: mean ``f^2`` on I."""
        d = self.setting.half_tolerance()
        return d * d
