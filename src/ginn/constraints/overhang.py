"""The largest overhang for additive manufacturing (``tolerances.overhang``): no surface faces
down by more than ``angle`` below the horizontal along the build direction ``up``, except on the
build plate and at the interfaces.

Verdict: ``overhang_share``, the share of the down-facing boundary of the extracted shape that
overhangs (:func:`ginn.extract.overhang.overhang_share`), at most ``share``. The plate is the
height ``plate`` along ``up`` (the domain's lowest point along ``up`` when the spec gives none);
the plate is exempt within the interface tolerance ``tol = tolerances.interface * unit_scale``,
and so is the boundary that realises an interface: within ``tol`` of it, or, farther, as near as
the boundary comes to its nearest interface point ``q``, within ``tol``
(``|p - q| <= tol + dist(q, boundary)``, :func:`ginn.extract.overhang.realising_elements`). That
is the interface's surface wherever the shape has put it; how far it is from the interface is the
interface verdict's to judge.

Loss: at the surface samples (points projected onto ``f = 0``) that are not exempt, with
``down = -n . up`` and ``n = grad f / |grad f|`` differentiable w.r.t. the parameters, the sum of

* the mean of ``relu(down - sin(angle))`` over the samples that face down (how far each normal
  points down beyond the limit): per unit of down-facing boundary, as the verdict measures, so
  that its scale does not depend on how much of a shape faces up;
* the mean over the shapes of ``relu(tail - sin(angle))``, ``tail`` the mean ``down`` of the
  ``share`` of a shape's down-facing samples that face down most (at least one;
  :func:`tail_means`).

It rotates the normals of the overhanging parts towards the limit, which raises their underside
into a self-supporting slope; a normal has no scale, so its weight is a number like the
prescribed normals'. The verdict is a bound on a share, ``P(down > sin(angle)) <= share``; the
tail's mean is that share's conditional value at risk, and keeping it at the limit keeps the share
within the bound (the tail's members lie on both sides of their mean), the convex surrogate of a
chance constraint (Rockafellar and Uryasev). The mean alone weighs a face by its share of the
down-facing boundary, so that a face just past the limit on a hundredth of it pulls with a
hundredth of the strength of the terms it competes with, and such faces stay just past the limit:
on the bracket made by additive manufacturing the overhang was 45 to 56 degrees (median 46 to 48)
on 1.05 to 1.21 % of the down-facing area of three shapes of seed 2 (``docs/results.md``,
"Manufacturing constraints on the bracket").

The loss leaves out the same samples as the verdict, the distance to ``q``'s boundary taken to
first order (``dist(q, {f = 0}) = |f(q)| / |grad f(q)|``). An exemption by the distance to the
interface alone is unstable: a ceiling that an interface prescribes (the top of a horizontal hole
faces straight down) and that drifts past the tolerance is overhang to the loss, which then tilts
it further away, while the interface's mean distance (CD1) tolerates the drift. On the bracket with
manufacturing bounds that turned both clevis pin holes into teardrops, open at the top over part of
their length, and nearly all that the verdict counted as overhang (1.04 to 1.32 % of the
down-facing area) lay 0.005 to 0.02 from the pin holes (``docs/results.md``, "Manufacturing
constraints on the bracket").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from torch import Tensor

from .. import fields
from ..extract.overhang import element_normals, exempt_elements, overhang_share, realising_elements
from ..geometry.base import nearest_interface_points
from ..problems.derived import length_scale
from ..problems.problem import Overhang as OverhangBound
from ..problems.problem import Problem
from .base import Constraint, Setting, Stage
from .batch import Batch
from .interface import level_distance
from .samples import DOMAIN
from .verdict import Verdict, Violation, number_text

__all__ = ["OverhangVerdict", "Overhang", "plate_height", "tail_means"]


def plate_height(problem: Problem, bound: OverhangBound) -> float:
    """The build plate's height along ``up``: the spec's, or the domain's lowest point along it."""
    if bound.plate is not None:
        return float(bound.plate)
    lo, hi = problem.domain.lo, problem.domain.hi
    return float(sum(min(u * a, u * b) for u, a, b in zip(bound.up, lo, hi)))


class OverhangVerdict(Verdict):
    """``overhang_share`` at most ``tolerances.overhang.share`` (module docstring)."""

    name = "overhang"

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("overhang_share",)
        self.bound: OverhangBound = problem.tolerances.overhang
        self.plate = plate_height(problem, self.bound)

    def exempt(self, boundary) -> np.ndarray:
        """``(m,)`` bool: the elements of ``boundary`` exempt (module docstring)."""
        up = np.asarray(self.bound.up, dtype=np.float64)
        tol = self.problem.interface_tolerance
        out = exempt_elements(boundary, up, self.plate, tol, self.problem.interfaces)
        down = -(element_normals(boundary) @ (up / np.linalg.norm(up)))
        return out | realising_elements(boundary, self.problem.interfaces, tol, ~out & (down > 0))

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        b = shape.boundary
        return {"overhang_share": overhang_share(b, self.bound.up, self.bound.angle, self.exempt(b))}

    def violation(self, metrics: Mapping) -> Violation | None:
        v = metrics.get("overhang_share")
        if v is None or v <= self.bound.share:
            return None
        return Violation(float(v), self.bound.share)

    def ratio(self, metrics: Mapping) -> float | None:
        v = metrics.get("overhang_share")
        if v is None:
            return None
        return v / self.bound.share if self.bound.share > 0 else (math.inf if v > 0 else 0.0)

    @classmethod
    def describe(cls, v: Violation) -> str:
        return f"overhang: {number_text(v.value)} of the down-facing boundary > {number_text(v.bound)}"


def tail_means(down: Tensor, facing: Tensor, share: float) -> Tensor:
    """Per shape, the mean of the largest ``down`` over the ``share`` of its ``facing`` samples that
    face down most (at least one): their conditional value at risk at level ``share``.

    Arguments:
        down: ``(S, m)`` how far each sample's normal points down, ``-n . up``, per shape.
        facing: ``(S, m)`` bool, the samples that count.
        share: the level, in ``[0, 1]``.

    Returns:
        ``(k,)`` the means of the ``k`` shapes with a facing sample, in order.
    """
    key = torch.where(facing, down.detach(), torch.full_like(down, -math.inf))
    order = key.argsort(dim=1, descending=True)  # (S, m): each shape's facing samples first, worst first
    count = facing.sum(dim=1)  # (S,)
    k = torch.clamp(torch.ceil(share * count.to(down.dtype)).to(torch.long), min=1)
    take = torch.arange(down.shape[1], device=down.device)[None, :] < k[:, None]  # (S, m)
    sums = (torch.gather(down, 1, order) * take).sum(dim=1)
    has = count > 0
    return (sums / k.to(down.dtype))[has]


class Overhang(Constraint):
    """No surface facing down beyond the overhang angle (module docstring)."""

    name = "overhang"
    stage = Stage.FIELD
    samples = (DOMAIN,)

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = OverhangVerdict(setting.problem)
        b = self._verdict.bound
        self.up = torch.tensor(b.up, device=setting.device, dtype=setting.dtype)
        self.limit = math.sin(math.radians(b.angle))
        self.plate = self._verdict.plate
        self.tol = setting.problem.interface_tolerance
        self.reach = 2.0 * length_scale(setting.problem)  # the domain's longest side

    @property
    def verdict(self) -> OverhangVerdict:
        return self._verdict

    def _exempt(self, p: Tensor) -> Tensor:
        """``(m,)`` bool: surface points on the plate or near an interface."""
        return (((p @ self.up) - self.plate).abs() <= self.tol) | self.setting.problem.near_interfaces(p)

    def _realising(self, model, p: Tensor, z: Tensor | None) -> Tensor:
        """``(m,)`` bool: the surface points ``p (m, d)`` that are, within the interface tolerance,
        as near as the boundary comes to their nearest interface point ``q``:
        ``|p - q| <= tol + dist(q, {f = 0})``, the distance taken to first order
        (:func:`ginn.constraints.interface.level_distance`)."""
        d, q = nearest_interface_points(self.setting.problem.interfaces, p.detach())
        far = torch.isinf(d)
        if bool(far.all()):
            return ~far
        v = fields.evaluate(model, q, z, grad=True, create_graph=False)
        return ~far & (d <= self.tol + level_distance(v.f, v.grad, self.reach).abs())

    def loss(self, batch: Batch) -> Tensor | None:
        srf = batch.surface()
        S, m = srf.converged.shape
        p = srf.x.reshape(-1, batch.d)
        with torch.no_grad():
            ok = srf.converged.reshape(-1) & ~self._exempt(p)
        if not bool(ok.any()):
            return None
        # every sample, the exempt ones masked: one shape of call per run (a compiled SIREN's
        # kernels are made per shape of input)
        z = None if batch.Z is None else batch.latents_of(srf.x)
        g = fields.evaluate(batch.model, p, z, grad=True, create_graph=True).grad
        n = g / g.norm(dim=-1, keepdim=True).clamp_min(1e-12)
        down = -(n @ self.up)  # (S * m,)
        facing = ok & (down.detach() > 0)
        if self.setting.problem.interfaces and bool(facing.any()):
            i = facing.nonzero().squeeze(-1)
            facing[i] = ~self._realising(batch.model, p[i], None if z is None else z[i])
        hinge = (torch.relu(down - self.limit) * facing).sum() / facing.sum().clamp_min(1)
        tail = tail_means(down.reshape(S, m), facing.reshape(S, m), self._verdict.bound.share)
        return hinge + torch.relu(tail - self.limit).sum() / max(tail.numel(), 1)

    def target(self) -> float:
        """0: no surface sample overhangs."""
        return 0.0
