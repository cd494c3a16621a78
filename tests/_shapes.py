"""Tiny geometry test doubles for the surface/metrics/export/plot tests (exact SDFs, float64)."""

from __future__ import annotations

import math

import torch
from torch import Tensor

from ginn.geometry.base import Interface, Region


class Disk(Region):
    def __init__(self, center, radius):
        self.c = torch.tensor(center, dtype=torch.float64)
        self.r = float(radius)
        self.dim = len(center)

    def sdf(self, x: Tensor) -> Tensor:
        return (x - self.c.to(x)).norm(dim=-1) - self.r


class Rect(Region):
    def __init__(self, lo, hi):
        self.lo = torch.tensor(lo, dtype=torch.float64)
        self.hi = torch.tensor(hi, dtype=torch.float64)
        self.dim = len(lo)

    def sdf(self, x: Tensor) -> Tensor:
        lo, hi = self.lo.to(x), self.hi.to(x)
        q = (x - (lo + hi) / 2).abs() - (hi - lo) / 2
        return q.clamp_min(0).norm(dim=-1) + q.max(dim=-1).values.clamp_max(0)


class Circle(Interface):
    """A circle of radius r (one component) in 2D."""

    dim = 2

    def __init__(self, radius, center=(0.0, 0.0)):
        self.r = float(radius)
        self.c = torch.tensor(center, dtype=torch.float64)

    def sample(self, n, generator=None, device=None, dtype=torch.float32):
        t = torch.rand(n, generator=generator, dtype=torch.float64) * 2 * math.pi
        nrm = torch.stack([t.cos(), t.sin()], dim=1)
        return (self.c + self.r * nrm).to(dtype), nrm.to(dtype)

    def measure(self):
        return 2 * math.pi * self.r


class VerticalSegments(Interface):
    """Vertical segments ``{(x_i, y) : |y| <= half}``, one component each."""

    dim = 2

    def __init__(self, xs, half):
        self.xs = torch.tensor(xs, dtype=torch.float64)
        self.half = float(half)

    def sample(self, n, generator=None, device=None, dtype=torch.float32):
        k = self.xs.shape[0]
        i = torch.arange(n) % k
        y = (torch.rand(n, generator=generator, dtype=torch.float64) * 2 - 1) * self.half
        x = torch.stack([self.xs[i], y], dim=1)
        nrm = torch.stack([torch.sign(self.xs[i]), torch.zeros(n, dtype=torch.float64)], dim=1)
        return x.to(dtype), nrm.to(dtype)

    def measure(self):
        return 2 * self.half * self.xs.shape[0]

    @property
    def n_components(self):
        return int(self.xs.shape[0])

    def component_of(self, x):
        return (x[:, :1] - self.xs.to(x)[None, :]).abs().argmin(dim=1)

    def distance(self, x):
        dx = (x[:, :1] - self.xs.to(x)[None, :]).abs()
        dy = (x[:, 1:2].abs() - self.half).clamp_min(0)
        return torch.sqrt(dx * dx + dy * dy).min(dim=1).values


def union(*sdfs):
    def f(x, z=None):
        return torch.stack([s(x) for s in sdfs]).min(dim=0).values

    return f


class DiskField(torch.nn.Module):
    """The signed distance to the circle of radius ``r`` at the origin, ``r`` a parameter (a model
    whose loss terms can be differentiated)."""

    def __init__(self, r):
        super().__init__()
        self.r = torch.nn.Parameter(torch.tensor(r))

    def forward(self, x, z=None):
        return x.norm(dim=-1) - self.r


class LineField(torch.nn.Module):
    """The signed distance to the line through the origin with unit normal at ``beta`` degrees, the
    normal a parameter."""

    def __init__(self, beta):
        super().__init__()
        b = math.radians(beta)
        self.n = torch.nn.Parameter(torch.tensor([math.cos(b), math.sin(b)]))

    def forward(self, x, z=None):
        return x @ self.n
