"""Abstract geometry: regions (with signed distance) and interfaces (with samples and normals).

Conventions: points ``x`` are tensors of shape ``(n, d)``; a region's ``sdf`` is negative inside,
positive outside; an interface's prescribed normal points *out of the shape* (the direction of
``grad f`` for a field whose shape is ``{f <= 0}``).
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass

import torch
from torch import Tensor


class Region(abc.ABC):
    """A solid region of R^d described by a signed distance function (exact or approximate).

    ``lipschitz`` is True when ``sdf`` has the exact sign and is 1-Lipschitz (an exact SDF, or a
    min/max of such, moved rigidly): then ``sdf(y)`` cannot change sign within ``|sdf(y)|`` of
    ``y``, which :class:`ginn.geometry.lookup.RegionLookup` uses to answer membership from a grid.
    """

    dim: int
    lipschitz: bool = False

    @abc.abstractmethod
    def sdf(self, x: Tensor) -> Tensor:
        """Signed distance ``(n, d) -> (n,)``: negative inside, positive outside."""

    def contains(self, x: Tensor) -> Tensor:
        """Boolean ``(n,)``: is each point inside (``sdf <= 0``)?"""
        return self.sdf(x) <= 0

    def bounds(self) -> tuple[Tensor, Tensor] | None:
        """An axis-aligned box ``(lo, hi)`` (float64, ``(d,)`` each) containing the region, or None
        when the region is unbounded or the bound is unknown."""
        return None


class Interface(abc.ABC):
    """A (d-1)-dimensional set the shape's boundary must pass through, optionally with normals.

    ``n_components`` is the number of connected components (the metrics count which components
    a shape reaches).
    """

    dim: int
    has_normals: bool = True
    #: corner points ``(c, d)`` (float64) the trainer may weight higher (polyline vertices), or None
    corners: Tensor | None = None

    @abc.abstractmethod
    def sample(
        self, n: int, generator: torch.Generator | None = None, device=None, dtype=torch.float32
    ) -> tuple[Tensor, Tensor]:
        """``n`` points uniformly (by length/area) on the interface, ``(n, d)``, and their unit
        prescribed normals ``(n, d)`` (zeros where ``has_normals`` is False)."""

    @abc.abstractmethod
    def measure(self) -> float:
        """Total length (2D) or area (3D)."""

    @property
    def n_components(self) -> int:
        return 1

    def component_of(self, x: Tensor) -> Tensor:
        """Component index ``(n,)`` of points lying on the interface (default: all 0)."""
        return torch.zeros(x.shape[0], dtype=torch.long, device=x.device)

    def distance(self, x: Tensor) -> Tensor:
        """Unsigned distance ``(n, d) -> (n,)`` from each point to the interface."""
        raise NotImplementedError(f"{type(self).__name__} does not implement distance()")

    def rim_distance(self, x: Tensor) -> Tensor:
        """Unsigned distance ``(n, d) -> (n,)`` from each point to the interface's rim: where it ends
        or turns (the end circles of a cylinder wall, the circles of an annulus, the vertices of a
        polyline, the open edges of a mesh), the edges that it prescribes to the shape. ``inf``
        where it has none (a circle; the default)."""
        return torch.full((x.shape[0],), math.inf, dtype=x.dtype, device=x.device)

    def nearest(self, x: Tensor) -> tuple[Tensor, Tensor]:
        """The distance ``(n,)`` from each point of ``x (n, d)`` to the interface and its nearest
        point on it ``(n, d)``, ``x - d grad d``: :meth:`distance` is differentiated through, so a
        subclass whose distance is a torch expression needs no projection of its own. No graph is
        kept."""
        with torch.enable_grad():
            y = x.detach().clone().requires_grad_(True)
            d = self.distance(y)
            (g,) = torch.autograd.grad(d.sum(), y)
        d = d.detach()
        return d, y.detach() - d[:, None] * torch.nan_to_num(g, nan=0.0)

    def bounds(self) -> tuple[Tensor, Tensor] | None:
        """An axis-aligned box ``(lo, hi)`` (float64, ``(d,)`` each) containing the interface."""
        return None


def near_any_interface(interfaces, x: Tensor, tol: float) -> Tensor:
    """``(n,)`` bool: the points of ``x (n, d)`` within ``tol`` of one of ``interfaces`` (an
    interface without :meth:`Interface.distance` marks none)."""
    out = torch.zeros(x.shape[0], dtype=torch.bool, device=x.device)
    for itf in interfaces:
        try:
            out |= itf.distance(x) <= tol
        except NotImplementedError:
            continue
    return out


def nearest_interface_points(interfaces, x: Tensor) -> tuple[Tensor, Tensor]:
    """The distance ``(n,)`` from each point of ``x (n, d)`` to the nearest of ``interfaces`` and
    that nearest point ``(n, d)`` (:meth:`Interface.nearest`); ``inf`` (and ``x`` itself) where no
    interface has a distance."""
    best = torch.full((x.shape[0],), math.inf, dtype=x.dtype, device=x.device)
    foot = x.detach().clone()
    for itf in interfaces:
        try:
            d, q = itf.nearest(x)
        except NotImplementedError:
            continue
        closer = d < best
        best = torch.where(closer, d, best)
        foot = torch.where(closer[:, None], q, foot)
    return best, foot


def near_any_rim(interfaces, x: Tensor, reach: float) -> Tensor:
    """``(n,)`` bool: the points of ``x (n, d)`` within ``reach`` of the rim of one of
    ``interfaces`` (:meth:`Interface.rim_distance`)."""
    out = torch.zeros(x.shape[0], dtype=torch.bool, device=x.device)
    for itf in interfaces:
        out |= itf.rim_distance(x) <= reach
    return out


@dataclass(frozen=True)
class Box:
    """An axis-aligned box ``[lo, hi]`` (the domain X): ``lo``, ``hi`` are length-d tuples."""

    lo: tuple[float, ...]
    hi: tuple[float, ...]

    @property
    def dim(self) -> int:
        return len(self.lo)

    def volume(self) -> float:
        v = 1.0
        for a, b in zip(self.lo, self.hi):
            v *= b - a
        return v

    def tensors(self, device=None, dtype=torch.float32) -> tuple[Tensor, Tensor]:
        return (torch.tensor(self.lo, device=device, dtype=dtype), torch.tensor(self.hi, device=device, dtype=dtype))

    def contains(self, x: Tensor) -> Tensor:
        lo, hi = self.tensors(x.device, x.dtype)
        return ((x >= lo) & (x <= hi)).all(dim=-1)
