"""Constructive solid geometry and rigid transforms of regions.

Exactness: a rigid transform of an exact SDF is exact. For CSG of exact SDFs, ``min`` (union),
``max`` (intersection) and ``max(a, -b)`` (difference) always have the correct *sign* (so
``contains`` is exact) and their magnitude is a *lower bound* of the true distance
(``|sdf| <= dist(x, boundary)``); the union is exact outside, the intersection exact inside. This is
all that sampling and the design-region loss need.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import Tensor

from ._tensor import as_f64, like
from .base import Region


def _dim_of(children: Sequence[Region]) -> int:
    if not children:
        raise ValueError("a CSG node needs at least one child")
    dims = {c.dim for c in children}
    if len(dims) != 1:
        raise ValueError(f"CSG children have different dimensions {sorted(dims)}")
    return dims.pop()


class Union(Region):
    """Union of regions: ``min_i sdf_i`` (exact outside, a bound inside)."""

    def __init__(self, *children: Region):
        self.children = tuple(children)
        self.dim = _dim_of(self.children)
        self.lipschitz = all(c.lipschitz for c in self.children)  # a min of 1-Lipschitz functions is one

    def sdf(self, x: Tensor) -> Tensor:
        return torch.stack([c.sdf(x) for c in self.children], dim=-1).min(dim=-1).values

    def contains(self, x: Tensor) -> Tensor:
        out = self.children[0].contains(x)
        for c in self.children[1:]:
            out = out | c.contains(x)
        return out

    def bounds(self):
        bs = [c.bounds() for c in self.children]
        if any(b is None for b in bs):
            return None
        return torch.stack([b[0] for b in bs]).min(0).values, torch.stack([b[1] for b in bs]).max(0).values


class Intersection(Region):
    """Intersection of regions: ``max_i sdf_i`` (exact inside, a bound outside)."""

    def __init__(self, *children: Region):
        self.children = tuple(children)
        self.dim = _dim_of(self.children)
        self.lipschitz = all(c.lipschitz for c in self.children)

    def sdf(self, x: Tensor) -> Tensor:
        return torch.stack([c.sdf(x) for c in self.children], dim=-1).max(dim=-1).values

    def contains(self, x: Tensor) -> Tensor:
        out = self.children[0].contains(x)
        for c in self.children[1:]:
            out = out & c.contains(x)
        return out

    def bounds(self):
        bs = [c.bounds() for c in self.children]
        bs = [b for b in bs if b is not None]
        if not bs:
            return None
        return torch.stack([b[0] for b in bs]).max(0).values, torch.stack([b[1] for b in bs]).min(0).values


class Difference(Region):
    """``base`` minus the union of ``removed``: ``max(sdf_base, -min_i sdf_i)`` (a bound)."""

    def __init__(self, base: Region, *removed: Region):
        self.base = base
        self.removed = tuple(removed)
        self.dim = _dim_of((base, *self.removed))
        self.lipschitz = base.lipschitz and all(r.lipschitz for r in self.removed)

    def sdf(self, x: Tensor) -> Tensor:
        out = self.base.sdf(x)
        for r in self.removed:
            out = torch.maximum(out, -r.sdf(x))
        return out

    def contains(self, x: Tensor) -> Tensor:
        out = self.base.contains(x)
        for r in self.removed:
            out = out & ~r.contains(x)
        return out

    def bounds(self):
        return self.base.bounds()


def rotation_matrix(dim: int, angle_deg: float = 0.0, axis=None) -> Tensor:
    """A rotation matrix (float64): 2D by ``angle_deg`` (counter-clockwise), or 3D by ``angle_deg``
    about ``axis`` (right-hand rule, Rodrigues' formula)."""
    th = math.radians(float(angle_deg))
    c, s = math.cos(th), math.sin(th)
    if dim == 2:
        return torch.tensor([[c, -s], [s, c]], dtype=torch.float64)
    if dim != 3:
        raise ValueError("rotations are supported in 2D and 3D")
    if axis is None:
        raise ValueError("a 3D rotation needs an axis")
    k = as_f64(axis, "axis", (3,))
    if k.norm() <= 1e-12:
        raise ValueError("rotation axis must be non-zero")
    k = k / k.norm()
    K = torch.tensor([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]], dtype=torch.float64)
    return torch.eye(3, dtype=torch.float64) + s * K + (1 - c) * (K @ K)


def check_rotation(R: Tensor, tol: float = 1e-9) -> Tensor:
    """Return ``R`` (float64) after checking it is a proper rotation (``R^T R = I``, ``det R = 1``)."""
    R = as_f64(R, "rotation")
    if R.dim() != 2 or R.shape[0] != R.shape[1]:
        raise ValueError("rotation must be a square matrix")
    eye = torch.eye(R.shape[0], dtype=torch.float64)
    if (R.T @ R - eye).abs().max() > tol or abs(float(torch.linalg.det(R)) - 1) > tol:
        raise ValueError("rotation must be orthogonal with determinant 1")
    return R


class Transformed(Region):
    """A region moved rigidly: ``x -> R x + t`` applied to ``region`` (exact SDF stays exact).

    Arguments:
        region: the region in its own frame.
        rotation: ``(d, d)`` proper rotation matrix (None: identity).
        translation: ``(d,)`` (None: zero).
    """

    def __init__(self, region: Region, rotation=None, translation=None):
        self.region = region
        self.dim = region.dim
        self.lipschitz = region.lipschitz  # a rigid motion keeps distances
        d = self.dim
        self.rotation = torch.eye(d, dtype=torch.float64) if rotation is None else check_rotation(rotation)
        self.translation = torch.zeros(d, dtype=torch.float64) if translation is None else as_f64(translation, "translation", (d,))
        if self.rotation.shape != (d, d):
            raise ValueError(f"rotation must be {d}x{d}")

    def to_local(self, x: Tensor) -> Tensor:
        """World points ``(n, d)`` -> the region's own frame: ``R^T (x - t)``."""
        return (x - like(self.translation, x)) @ like(self.rotation, x)

    def sdf(self, x: Tensor) -> Tensor:
        return self.region.sdf(self.to_local(x))

    def contains(self, x: Tensor) -> Tensor:
        return self.region.contains(self.to_local(x))

    def bounds(self):
        b = self.region.bounds()
        if b is None:
            return None
        lo, hi = b
        d = self.dim
        # the 2^d corners of the local box, mapped to the world frame
        idx = torch.cartesian_prod(*[torch.tensor([0, 1])] * d).reshape(-1, d)
        corners = torch.where(idx.bool(), hi, lo)
        w = corners @ self.rotation.T + self.translation
        return w.min(0).values, w.max(0).values
