"""Constraint losses of Table 1 (and eikonal, obstacle, surface strain) as small objects.

Each loss takes explicit tensors (field values or derivatives at the points that sample its
domain of integration) and returns a scalar. Weights and start iterations live in the config.

Normalisation: every integral is estimated by the Monte Carlo *mean* over uniform samples of its
domain, i.e. the integral divided by the measure of that domain (``vol(X \\ E)`` for the design
region, ``|I|`` for the interface, the boundary's area for curvature terms). This keeps the loss
scale independent of the problem's size; multiply by the measure to get the integral itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from .. import fields
from ..config import STRAIN_CLIP


def _wmean(v: Tensor, w: Tensor | None) -> Tensor:
    if v.numel() == 0:
        return v.new_zeros(())
    if w is None:
        return v.mean()
    return (v * w).sum() / w.sum().clamp_min(1e-12)


@dataclass(frozen=True)
class DesignRegionLoss:
    """``mean over X \\ E of |min(0, f)|^power``: the shape must stay inside E. Input: f ``(n,)``.

    ``power = 2`` is the paper's quadratic penalty. Its gradient vanishes as a violation becomes
    shallow, so a thin sliver of shape just outside E costs almost nothing at any finite weight;
    ``power = 1`` (an exact penalty) pushes shallow violations with a constant force.
    """

    name: str = "design_region"
    power: int = 2

    def __call__(self, f_outside: Tensor) -> Tensor:
        v = torch.clamp(f_outside, max=0.0)
        return _wmean(v.pow(2) if self.power == 2 else -v, None)


@dataclass(frozen=True)
class ObstacleLoss(DesignRegionLoss):
    """As the design-region loss, on samples inside the obstacles."""

    name: str = "obstacle"


@dataclass(frozen=True)
class InterfaceLoss:
    """``mean over I of f^2`` (optionally weighted per sample, e.g. corners). Input: f ``(n,)``."""

    name: str = "interface"

    def __call__(self, f_interface: Tensor, weights: Tensor | None = None) -> Tensor:
        return _wmean(f_interface.pow(2), weights)


@dataclass(frozen=True)
class NormalLoss:
    """``mean over I of |grad f / |grad f| - n_bar|^2``: 0 when aligned, 4 when opposite.

    Inputs: gradients ``(n, d)`` and prescribed unit normals ``(n, d)``.
    """

    name: str = "normal"

    def __call__(self, grad_interface: Tensor, normals: Tensor) -> Tensor:
        return _wmean((fields.unit_normal(grad_interface) - normals).pow(2).sum(-1), None)


@dataclass(frozen=True)
class EikonalLoss:
    """``mean (|grad f| - 1)^2`` over domain samples. Input: gradients ``(n, d)``."""

    name: str = "eikonal"

    def __call__(self, grad: Tensor) -> Tensor:
        return _wmean((grad.norm(dim=-1) - 1.0).pow(2), None)


@dataclass(frozen=True)
class MeanCurvatureLoss:
    """``mean over dOmega of div(grad f / |grad f|)^2`` (Plateau). Inputs at boundary points:
    gradients ``(m, d)`` and Hessians ``(m, d, d)``."""

    name: str = "mean_curvature"

    def __call__(self, grad: Tensor, hess: Tensor) -> Tensor:
        return _wmean(fields.divergence_of_normal(grad, hess).pow(2), None)


@dataclass(frozen=True)
class StrainLoss:
    """``mean over dOmega \\ I of min(kappa_1^2 + kappa_2^2, clip)`` (smoothness, bracket).

    The clip (Appendix B.1's kappa_max = 1000) keeps tiny spurious components from dominating.
    Inputs at boundary points away from the interfaces: gradients ``(m, d)``, Hessians ``(m, d, d)``.
    """

    clip: float = STRAIN_CLIP
    name: str = "strain"

    def __call__(self, grad: Tensor, hess: Tensor) -> Tensor:
        return _wmean(fields.surface_strain(grad, hess).clamp(max=self.clip), None)
