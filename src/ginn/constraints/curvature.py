"""Objectives on the curvature of the boundary, at the surface samples (Hessians there only).

* ``mean_curvature``: ``mean over dOmega of div(grad f / |grad f|)^2`` (Plateau's minimal surface,
  :class:`ginn.losses.MeanCurvatureLoss`);
* ``strain``: ``mean over dOmega \\ I of min(kappa_1^2 + kappa_2^2, clip)`` (smoothness, the
  bracket; :class:`ginn.losses.StrainLoss`), leaving out the surface samples within
  ``sampling.strain_interface_clearance`` of an interface (the paper's "away from the interfaces").

Both read the gradients and Hessians of one shared pass at the converged surface samples.
"""

from __future__ import annotations

import torch
from scipy.spatial import cKDTree
from torch import Tensor

from ..geometry import sampling
from ..losses.constraints import MeanCurvatureLoss, StrainLoss
from .base import Constraint, Setting, Stage
from .batch import Batch

__all__ = ["MeanCurvature", "Strain"]


class MeanCurvature(Constraint):
    """Squared mean curvature of the boundary (see the module docstring)."""

    name = "mean_curvature"
    stage = Stage.SURFACE
    fn = MeanCurvatureLoss()
    gated = True  # every plane has zero mean curvature

    def loss(self, batch: Batch) -> Tensor:
        v, _ = batch.surface_hessians()
        return self.fn(v.hessian_grad, v.hessian)


class Strain(Constraint):
    """Surface strain of the boundary away from the interfaces (see the module docstring)."""

    name = "strain"
    stage = Stage.SURFACE

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self.fn = StrainLoss(clip=setting.cfg.sampling.strain_clip)
        self._cloud: cKDTree | None = None  # a dense fixed sample of I, for distances

    def loss(self, batch: Batch) -> Tensor:
        v, X = batch.surface_hessians()
        keep = self.away_from_interfaces(X[v.hessian_index], self.setting.cfg.sampling.strain_interface_clearance)
        return self.fn(v.hessian_grad[keep], v.hessian[keep])

    def away_from_interfaces(self, x: Tensor, c: float) -> Tensor:
        """``(n,)``: whether each point of ``x (n, d)`` is farther than ``c`` from every interface."""
        p = self.setting.problem
        if c <= 0 or not p.interfaces:
            return torch.ones(x.shape[0], dtype=torch.bool, device=x.device)
        if self._cloud is None:
            g = torch.Generator(device=self.setting.device).manual_seed(12345)
            cloud, _ = sampling.sample_interfaces(p.interfaces, 20000, g, device=self.setting.device, dtype=self.setting.dtype)
            self._cloud = cKDTree(cloud.detach().cpu().double().numpy())
        dist, _ = self._cloud.query(x.detach().cpu().double().numpy(), distance_upper_bound=c)
        return torch.from_numpy(dist > c).to(x.device)
