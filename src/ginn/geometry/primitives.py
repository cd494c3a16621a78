"""Solid primitives with exact signed distance functions (torch, vectorised, any device/dtype).

Every class is a :class:`~ginn.geometry.base.Region`: ``sdf(x)`` maps points ``(n, d)`` to
``(n,)`` (negative inside) and is *exact* (the Euclidean distance to the boundary, with sign), so
``|grad sdf| = 1`` away from the medial axis. Parameters are stored as float64 CPU tensors and
moved to the points' device and dtype at evaluation.

2D: :class:`Rectangle`, :class:`Disk`, :class:`Polygon`.
3D: :class:`Cuboid`, :class:`Sphere`, :class:`Cylinder` (finite, any axis), :class:`Extrusion`
(a 2D polygon extruded along z). Any dimension: :class:`AABox`, :class:`Ball`, :class:`HalfSpace`.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from ._tensor import as_f64, box_combine, like, unit
from .base import Region


class AABox(Region):
    """Axis-aligned box ``[lo, hi]`` in any dimension.

    Arguments:
        lo, hi: corners, length ``d`` each, ``lo < hi`` componentwise.
    """

    lipschitz = True  # an exact signed distance

    def __init__(self, lo, hi):
        self.lo = as_f64(lo, "lo")
        self.hi = as_f64(hi, "hi", tuple(self.lo.shape))
        if self.lo.dim() != 1 or not bool((self.lo < self.hi).all()):
            raise ValueError("box needs lo < hi in every coordinate")
        self.dim = self.lo.shape[0]

    def sdf(self, x: Tensor) -> Tensor:
        c = like((self.lo + self.hi) / 2, x)
        h = like((self.hi - self.lo) / 2, x)
        return box_combine((x - c).abs() - h)

    def volume(self) -> float:
        return float(torch.prod(self.hi - self.lo))

    def bounds(self):
        return self.lo.clone(), self.hi.clone()


class Rectangle(AABox):
    """2D axis-aligned rectangle ``[lo, hi]``."""

    def __init__(self, lo, hi):
        super().__init__(lo, hi)
        if self.dim != 2:
            raise ValueError("a rectangle is 2D")


class Cuboid(AABox):
    """3D axis-aligned box ``[lo, hi]``."""

    def __init__(self, lo, hi):
        super().__init__(lo, hi)
        if self.dim != 3:
            raise ValueError("a cuboid is 3D")


class Ball(Region):
    """Ball ``|x - center| <= radius`` in any dimension."""

    lipschitz = True  # an exact signed distance

    def __init__(self, center, radius: float):
        self.center = as_f64(center, "center")
        self.radius = float(radius)
        if not (self.radius > 0 and math.isfinite(self.radius)):
            raise ValueError("radius must be > 0")
        self.dim = self.center.shape[0]

    def sdf(self, x: Tensor) -> Tensor:
        return (x - like(self.center, x)).norm(dim=-1) - self.radius

    def volume(self) -> float:
        d = self.dim
        return math.pi ** (d / 2) / math.gamma(d / 2 + 1) * self.radius**d

    def bounds(self):
        return self.center - self.radius, self.center + self.radius


class Disk(Ball):
    """2D disk."""

    def __init__(self, center, radius: float):
        super().__init__(center, radius)
        if self.dim != 2:
            raise ValueError("a disk is 2D")


class Sphere(Ball):
    """3D (solid) sphere."""

    def __init__(self, center, radius: float):
        super().__init__(center, radius)
        if self.dim != 3:
            raise ValueError("a sphere is 3D")


class HalfSpace(Region):
    """Half-space ``(x - point) . normal <= 0``; ``normal`` is the outward normal (normalised here)."""

    lipschitz = True  # an exact signed distance

    def __init__(self, point, normal):
        self.point = as_f64(point, "point")
        self.normal = unit(normal, "normal")
        if self.normal.shape != self.point.shape:
            raise ValueError("point and normal must have the same dimension")
        self.dim = self.point.shape[0]

    def sdf(self, x: Tensor) -> Tensor:
        return (x - like(self.point, x)) @ like(self.normal, x)


def _segment_distance_2d(x: Tensor, a: Tensor, b: Tensor) -> Tensor:
    """Distances ``(n, m)`` from points ``(n, 2)`` to segments ``a[j] b[j]`` (``(m, 2)`` each)."""
    ab = b - a  # (m, 2)
    ap = x[:, None, :] - a[None, :, :]  # (n, m, 2)
    denom = (ab * ab).sum(-1).clamp_min(1e-300)
    t = ((ap * ab[None]).sum(-1) / denom).clamp(0, 1)
    return (ap - t[..., None] * ab[None]).norm(dim=-1)


class Polygon(Region):
    """Simple 2D polygon (convex or not) given by its vertices in order (either orientation).

    The SDF is exact: the distance to the nearest edge, negative inside (even-odd rule).
    """

    lipschitz = True  # an exact signed distance

    def __init__(self, vertices):
        v = as_f64(vertices, "vertices")
        if v.dim() != 2 or v.shape[1] != 2 or v.shape[0] < 3:
            raise ValueError("a polygon needs at least 3 vertices of 2 coordinates")
        self.vertices = v
        self.dim = 2
        area = self.signed_area()
        if abs(area) <= 1e-14:
            raise ValueError("polygon has zero area")

    def signed_area(self) -> float:
        v = self.vertices
        w = torch.roll(v, -1, 0)
        return float(0.5 * (v[:, 0] * w[:, 1] - w[:, 0] * v[:, 1]).sum())

    def area(self) -> float:
        return abs(self.signed_area())

    def sdf(self, x: Tensor) -> Tensor:
        a = like(self.vertices, x)
        b = torch.roll(a, -1, 0)
        dist = _segment_distance_2d(x, a, b).min(dim=-1).values
        # even-odd crossing test with a horizontal ray to +x
        ya, yb = a[:, 1][None], b[:, 1][None]
        px, py = x[:, 0:1], x[:, 1:2]
        straddle = (ya > py) != (yb > py)
        dy = torch.where(straddle, yb - ya, torch.ones_like(yb - ya))
        xcross = a[:, 0][None] + (py - ya) * (b[:, 0] - a[:, 0])[None] / dy
        crossings = (straddle & (px < xcross)).sum(-1)
        inside = (crossings % 2) == 1
        return torch.where(inside, -dist, dist)

    def bounds(self):
        return self.vertices.min(0).values, self.vertices.max(0).values


class Cylinder(Region):
    """Finite (capped) solid cylinder with an arbitrary axis.

    Arguments:
        center: midpoint of the axis segment, ``(3,)``.
        axis: axis direction (normalised here), ``(3,)``.
        radius: > 0.
        length: total length along the axis, > 0.
    """

    lipschitz = True  # an exact signed distance

    def __init__(self, center, axis, radius: float, length: float):
        self.center = as_f64(center, "center", (3,))
        self.axis = unit(axis, "axis")
        self.radius = float(radius)
        self.length = float(length)
        if not (self.radius > 0 and self.length > 0):
            raise ValueError("radius and length must be > 0")
        self.dim = 3

    def _coords(self, x: Tensor) -> tuple[Tensor, Tensor]:
        p = x - like(self.center, x)
        t = p @ like(self.axis, x)
        rho = (p - t[:, None] * like(self.axis, x)).norm(dim=-1)
        return t, rho

    def sdf(self, x: Tensor) -> Tensor:
        t, rho = self._coords(x)
        return box_combine(torch.stack([rho - self.radius, t.abs() - self.length / 2], dim=-1))

    def volume(self) -> float:
        return math.pi * self.radius**2 * self.length

    def bounds(self):
        a = self.axis
        ext = (a.abs() * self.length / 2) + self.radius * (1 - a * a).clamp_min(0).sqrt()
        return self.center - ext, self.center + ext


class Extrusion(Region):
    """A 2D polygon (in the xy-plane) extruded along z over ``[z0, z1]`` (exact SDF).

    Use :class:`~ginn.geometry.csg.Transformed` for other directions.
    """

    lipschitz = True  # an exact signed distance

    def __init__(self, polygon: Polygon | object, z0: float, z1: float):
        self.polygon = polygon if isinstance(polygon, Polygon) else Polygon(polygon)
        self.z0, self.z1 = float(z0), float(z1)
        if not self.z0 < self.z1:
            raise ValueError("extrusion needs z0 < z1")
        self.dim = 3

    def sdf(self, x: Tensor) -> Tensor:
        d2 = self.polygon.sdf(x[:, :2])
        dz = (x[:, 2] - (self.z0 + self.z1) / 2).abs() - (self.z1 - self.z0) / 2
        return box_combine(torch.stack([d2, dz], dim=-1))

    def volume(self) -> float:
        return self.polygon.area() * (self.z1 - self.z0)

    def bounds(self):
        lo, hi = self.polygon.bounds()
        return (torch.cat([lo, torch.tensor([self.z0], dtype=lo.dtype)]), torch.cat([hi, torch.tensor([self.z1], dtype=hi.dtype)]))
