"""Volume bounds: each shape's volume inside E, as a fraction of vol(E), within the bounds the spec
states (``tolerances.volume_fraction``: at most, at least, or both).

Loss: per shape, ``relu(V + s - max) + relu(min - V + s)``, the mean over the shapes. ``V`` is
the share of the ``m`` uniform domain samples in E that lie in the shape (``f <= 0``), an
unbiased estimate of the volume fraction; its gradient is that of the smoothed count
``sigmoid(-f / w)`` (the value of the one, the derivative of the other). The smoothed count alone
depends on how steep the field is on each side of the boundary, and a trained field is a distance
only near its boundary, if there: trained on it, the obstacle with ``max: 0.35`` (4 shapes) ended
with smoothed counts 0.02 to 0.03 below the share of samples and shapes over the bound on the
grid (``docs/results.md``, "Volume bounds"). The step's width ``w`` is half the mean spacing of the domain samples,
``(vol(X) / n_domain)^(1/d) / 2``, so that the samples near the boundary carry the gradient.
``s = sqrt(V (1 - V) / m)`` is the estimate's standard error: the penalty acts only on the steps
whose estimate lies beyond the bound, so the forces that widen a shape (diversity, the
interfaces) would hold it where about half the estimates do, over the bound; moved by ``s``, it
holds the shapes inside. An exact penalty (power 1), like the containment terms.

A structural problem (``physics:``) estimates the fractions on its element grid instead, from the
field at the element centres that its compliance term evaluates (:mod:`ginn.constraints.compliance`),
so that the volume and the stiffness see one material (with the sampled estimate and its margin
the half MBB beam, ``mbb``, ended at a volume fraction of 0.47 under a bound of 0.5): the mean
over E of the share of each element the shape covers
(:func:`~ginn.constraints.compliance.covered`, the field taken as linear across the element), each
element counted up to the share of it that lies in E and E's volume the sum of those shares
(:func:`~ginn.problems.structural.design_shares`, the same model for E's signed distance; the
obstacles in E count in it, as in the spec's denominator), with its own gradient. Counting the
elements whose centre lies in E instead put E's area 1.2 % over its own on
``benchmarks/suite/plate-loads-2d.yaml`` (90 x 50 elements): its shapes were held at the bound on
that count and measured up to 0.007 over it on the evaluation grid. The margin ``s`` is the
standard error of the plain centre count, ``sqrt(n_b / 12) / n_E`` for the ``n_b`` elements the
boundary crosses (:func:`~ginn.constraints.compliance.volume_margin`), and the compliance term's
offset holds its shapes the same margin inside the bound: a shape held at the bound on one grid
lies on either side of it on another. On trained beams and cantilevers the covered-share estimate
on the training grid was within 5e-4 of that on a grid 8 times finer, the centre count within
2.8e-3, and the margins were 1.0e-3 to 1.9e-3; without the margin, a beam held at the bound on its
grid measured 0.50009 under a bound of 0.5 on the evaluation grid.

Verdict: ``volume_fraction`` of ``ginn eval`` (:func:`ginn.eval.metrics.volume_fraction`, grid
volumes) within the bounds.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from ..problems.derived import smallest_feature
from ..problems.problem import Problem
from ..problems.structural import design_shares, structural_grid
from .base import Constraint, Setting
from .batch import Batch
from .compliance import ELEMENTS, covered, volume_margin
from .samples import DOMAIN
from .verdict import IntervalVerdict

__all__ = ["VolumeFractionVerdict", "VolumeFraction", "step_width"]


class VolumeFractionVerdict(IntervalVerdict):
    """``volume_fraction`` within ``tolerances.volume_fraction`` (problems that state it)."""

    name = "volume_fraction"
    metric = "volume_fraction"

    def __init__(self, problem: Problem):
        super().__init__(problem, problem.tolerances.volume_fraction)


def step_width(setting: Setting) -> float:
    """``w``: half the mean spacing of the domain samples (module docstring)."""
    dom = setting.problem.domain
    volume = math.prod(float(h - l) for l, h in zip(dom.lo, dom.hi))
    return 0.5 * (volume / setting.cfg.sampling.n_domain) ** (1.0 / setting.dim)


class VolumeFraction(Constraint):
    """Each shape's volume fraction of E within its bounds (see the module docstring)."""

    name = "volume"
    samples = (DOMAIN,)

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = VolumeFractionVerdict(setting.problem)
        self.width = step_width(setting)
        self.centres: Tensor | None = None
        p = setting.problem
        if p.physics is not None:  # the element grid of the compliance term
            self.grid = structural_grid(p, setting.cfg.structural.cells, smallest_feature(p))
            self.centres = torch.as_tensor(self.grid.centres, dtype=setting.dtype, device=setting.device)
            shares = design_shares(p, self.grid)  # E's share of each element, obstacles included
            self.in_design = torch.as_tensor(shares, dtype=setting.dtype, device=setting.device)
            self.design_volume = float(shares.sum())

    @property
    def verdict(self) -> VolumeFractionVerdict:
        return self._verdict

    def fractions(self, batch: Batch) -> tuple[Tensor, Tensor]:
        """The estimated volume fraction of each shape and its margin (detached), ``(S,)`` each:
        sampled, the share of the samples with the smoothed count's gradient and its standard
        error; on a structural problem's element grid, the covered shares and the count's
        standard error (module docstring)."""
        if self.centres is not None:
            share = covered(batch.field_at(ELEMENTS, self.centres), self.grid)
            inside = torch.minimum(share, self.in_design)  # the shape's part of each element in E, at most E's
            return inside.sum(dim=1) / self.design_volume, volume_margin(share.detach(), self.in_design)
        f = batch.f["domain"]  # (S, n)
        x = batch.x["domain"]  # (S, n, d)
        member = self.setting.membership
        with torch.no_grad():
            inE = (torch.ones(f.shape, dtype=torch.bool, device=f.device) if member is None
                   else member.contains(x.reshape(-1, batch.d)).reshape(f.shape))
        weight = inE.to(f.dtype)
        m = weight.sum(dim=1).clamp_min(1.0)
        smooth = (torch.sigmoid(-f / self.width) * weight).sum(dim=1) / m
        with torch.no_grad():
            share = ((f <= 0).to(f.dtype) * weight).sum(dim=1) / m
            err = (share * (1 - share)).div(m).sqrt()
        return share + (smooth - smooth.detach()), err

    def loss(self, batch: Batch) -> Tensor | None:
        b = self.setting.problem.tolerances.volume_fraction
        if b is None or (self.centres is None and "domain" not in batch.f):
            return None
        v, err = self.fractions(batch)
        zero = torch.zeros_like(v)
        over = torch.relu(v + err - b.max) if b.max is not None else zero
        under = torch.relu(b.min - v + err) if b.min is not None else zero
        return (over + under).mean()

    def target(self) -> float:
        """0: within the bounds."""
        return 0.0
