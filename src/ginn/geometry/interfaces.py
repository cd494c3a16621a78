"""Analytic interfaces: sets the shape's boundary must pass through, with prescribed normals.

Every class is an :class:`~ginn.geometry.base.Interface`: ``sample(n, generator, device, dtype)``
returns ``n`` points uniform by length/area and their unit prescribed normals (pointing *out of the
shape*; zeros when ``has_normals`` is False), ``measure()`` the length/area, ``distance(x)`` the
exact unsigned distance, ``n_components``/``component_of(x)`` the connected components.

* 2D and 3D curves: :class:`Segment`, :class:`Polyline` (open or closed; in 3D without normals,
  e.g. the Plateau boundary, whose vertices are exposed as ``corners``), :class:`Circle` (2D).
* 3D surfaces: :class:`CylinderWall` (finite tube without caps), :class:`Annulus` (flat ring).
* Combinators: :class:`InterfaceUnion` (several interfaces as one object, either keeping their
  components apart or merged into one component, e.g. a bolt hole's wall and its top ring) and
  :class:`TransformedInterface` (rigid motion).

``corners``: an interface may carry a ``(c, d)`` float64 tensor of corner points (the vertices of
a polyline) that the trainer can weight higher (paper A.2); it is ``None`` for smooth interfaces.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import Tensor

from ._tensor import as_f64, like, orthonormal_frame, rand, split_count, unit
from .base import Interface
from .csg import check_rotation


def _normal_mode(normals, allowed: Sequence[str]) -> str:
    mode = "none" if normals is None or normals is False else str(normals)
    if mode not in allowed:
        raise ValueError(f"normals must be one of {list(allowed)}, got {normals!r}")
    return mode


def _choose(weights: Tensor, n: int, gen) -> Tensor:
    """``n`` indices drawn with probabilities proportional to ``weights`` (CPU long tensor)."""
    gdev = gen.device if gen is not None else torch.device("cpu")
    w = weights.to(device=gdev, dtype=torch.float64)
    if n == 0:
        return torch.zeros(0, dtype=torch.long)
    return torch.multinomial(w, n, replacement=True, generator=gen).cpu()


def _segments_distance(x: Tensor, a: Tensor, b: Tensor) -> Tensor:
    """Distances ``(n, m)`` from points ``(n, d)`` to the segments ``a[j] b[j]`` ``(m, d)``."""
    ab = b - a
    ap = x[:, None, :] - a[None]
    t = ((ap * ab[None]).sum(-1) / (ab * ab).sum(-1).clamp_min(1e-300)).clamp(0, 1)
    return (ap - t[..., None] * ab[None]).norm(dim=-1)


class Polyline(Interface):
    """A polyline through ``points`` (``(k, d)``, d = 2 or 3), optionally closed.

    Arguments:
        points: the vertices in order.
        closed: join the last vertex back to the first.
        normal: prescribed normals: None (no normals), a vector ``(d,)`` (the same normal on every
            segment), a list of ``(m, d)`` vectors (one per segment), or in 2D ``"left"`` /
            ``"right"`` (the tangent turned by +90 / -90 degrees).

    Attributes:
        corners: ``(c, d)`` float64: all vertices, for corner weighting (the end points of an open
            polyline included: there the interface usually meets another constraint, e.g. the
            obstacle problem's segments end on the design region's boundary).
    """

    def __init__(self, points, closed: bool = False, normal=None):
        p = as_f64(points, "points")
        if p.dim() != 2 or p.shape[0] < 2 or p.shape[1] not in (2, 3):
            raise ValueError("a polyline needs at least 2 points of 2 or 3 coordinates")
        self.dim = p.shape[1]
        self.closed = bool(closed)
        self.points = p
        self.a = p if closed else p[:-1]
        self.b = torch.roll(p, -1, 0) if closed else p[1:]
        seg = self.b - self.a
        self.lengths = seg.norm(dim=-1)
        if (self.lengths <= 1e-14).any():
            raise ValueError("polyline has a zero-length segment")
        self.corners = p.clone()
        m = seg.shape[0]
        if normal is None:
            self.has_normals = False
            self.normals = torch.zeros(m, self.dim, dtype=torch.float64)
        elif isinstance(normal, str):
            if self.dim != 2 or normal not in ("left", "right"):
                raise ValueError("normal 'left'/'right' is only defined for 2D polylines")
            t = seg / self.lengths[:, None]
            left = torch.stack([-t[:, 1], t[:, 0]], dim=-1)
            self.normals = left if normal == "left" else -left
            self.has_normals = True
        else:
            nv = as_f64(normal, "normal")
            if nv.shape == (self.dim,):
                nv = nv.expand(m, self.dim).clone()
            if nv.shape != (m, self.dim):
                raise ValueError(f"normal must be one vector of {self.dim} coordinates or one per segment ({m})")
            nn = nv.norm(dim=-1, keepdim=True)
            if (nn <= 1e-12).any():
                raise ValueError("normal must be non-zero")
            self.normals = nv / nn
            self.has_normals = True

    def measure(self) -> float:
        return float(self.lengths.sum())

    def sample(self, n, generator=None, device=None, dtype=torch.float32):
        j = _choose(self.lengths, n, generator)
        t = rand(generator, (n, 1), "cpu", torch.float64)
        x = self.a[j] + t * (self.b[j] - self.a[j])
        return x.to(device=device, dtype=dtype), self.normals[j].to(device=device, dtype=dtype)

    def distance(self, x: Tensor) -> Tensor:
        return _segments_distance(x, like(self.a, x), like(self.b, x)).min(dim=-1).values

    def rim_distance(self, x: Tensor) -> Tensor:
        """To the nearest vertex (the end points and the corners)."""
        return torch.cdist(x, like(self.points, x)).min(dim=-1).values

    def bounds(self):
        return self.points.min(0).values, self.points.max(0).values


class Segment(Polyline):
    """The segment from ``a`` to ``b`` (2D or 3D) with an optional constant prescribed ``normal``."""

    def __init__(self, a, b, normal=None):
        super().__init__(torch.stack([as_f64(a, "a"), as_f64(b, "b")]), closed=False, normal=normal)


class Circle(Interface):
    """A 2D circle; ``normals`` ``"outward"`` (away from the centre), ``"inward"`` or ``"none"``.

    For a hole the shape must surround, the normal out of the shape points to the centre:
    ``"inward"``.
    """

    def __init__(self, center, radius: float, normals: str | None = "inward"):
        self.center = as_f64(center, "center", (2,))
        self.radius = float(radius)
        if not self.radius > 0:
            raise ValueError("radius must be > 0")
        self.mode = _normal_mode(normals, ("outward", "inward", "none"))
        self.has_normals = self.mode != "none"
        self.dim = 2

    def measure(self) -> float:
        return 2 * math.pi * self.radius

    def sample(self, n, generator=None, device=None, dtype=torch.float32):
        th = 2 * math.pi * rand(generator, (n,), "cpu", torch.float64)
        u = torch.stack([th.cos(), th.sin()], dim=-1)
        x = self.center + self.radius * u
        sign = {"outward": 1.0, "inward": -1.0, "none": 0.0}[self.mode]
        return x.to(device=device, dtype=dtype), (sign * u).to(device=device, dtype=dtype)

    def distance(self, x: Tensor) -> Tensor:
        return ((x - like(self.center, x)).norm(dim=-1) - self.radius).abs()

    def bounds(self):
        return self.center - self.radius, self.center + self.radius


class CylinderWall(Interface):
    """The lateral surface of a finite cylinder (no caps), 3D.

    Arguments:
        center: midpoint of the axis segment ``(3,)``.
        axis: axis direction ``(3,)`` (normalised here).
        radius, length: > 0; the wall spans ``t in [-length/2, length/2]`` along the axis.
        normals: ``"inward"`` (toward the axis: out of a solid that surrounds the hole; default),
            ``"outward"`` or ``"none"``.
    """

    def __init__(self, center, axis, radius: float, length: float, normals: str | None = "inward"):
        self.center = as_f64(center, "center", (3,))
        self.axis = unit(axis, "axis")
        self.radius, self.length = float(radius), float(length)
        if not (self.radius > 0 and self.length > 0):
            raise ValueError("radius and length must be > 0")
        self.mode = _normal_mode(normals, ("outward", "inward", "none"))
        self.has_normals = self.mode != "none"
        self.u, self.v = orthonormal_frame(self.axis)
        self.dim = 3

    def measure(self) -> float:
        return 2 * math.pi * self.radius * self.length

    def sample(self, n, generator=None, device=None, dtype=torch.float32):
        r = rand(generator, (n, 2), "cpu", torch.float64)
        th = 2 * math.pi * r[:, 0]
        t = (r[:, 1] - 0.5) * self.length
        radial = th.cos()[:, None] * self.u + th.sin()[:, None] * self.v
        x = self.center + t[:, None] * self.axis + self.radius * radial
        sign = {"outward": 1.0, "inward": -1.0, "none": 0.0}[self.mode]
        return x.to(device=device, dtype=dtype), (sign * radial).to(device=device, dtype=dtype)

    def distance(self, x: Tensor) -> Tensor:
        p = x - like(self.center, x)
        t = p @ like(self.axis, x)
        rho = (p - t[:, None] * like(self.axis, x)).norm(dim=-1)
        dt = (t.abs() - self.length / 2).clamp_min(0)
        return torch.sqrt((rho - self.radius) ** 2 + dt**2)

    def rim_distance(self, x: Tensor) -> Tensor:
        """To the nearer of the two end circles."""
        p = x - like(self.center, x)
        t = p @ like(self.axis, x)
        rho = (p - t[:, None] * like(self.axis, x)).norm(dim=-1)
        return torch.sqrt((rho - self.radius) ** 2 + (t.abs() - self.length / 2) ** 2)

    def bounds(self):
        a = self.axis
        ext = (a.abs() * self.length / 2) + self.radius * (1 - a * a).clamp_min(0).sqrt()
        return self.center - ext, self.center + ext


class Annulus(Interface):
    """A flat ring in 3D: points ``p`` with ``(p - center) . normal = 0`` and
    ``r_inner <= |p - center| <= r_outer``; the prescribed normal is ``normal`` (normalised).

    ``r_inner = 0`` gives a flat disk. ``normals="none"`` drops the prescribed normal.
    """

    def __init__(self, center, normal, r_inner: float, r_outer: float, normals: str | None = "given"):
        self.center = as_f64(center, "center", (3,))
        self.normal = unit(normal, "normal")
        self.r_inner, self.r_outer = float(r_inner), float(r_outer)
        if not (0 <= self.r_inner < self.r_outer):
            raise ValueError("annulus needs 0 <= r_inner < r_outer")
        self.mode = _normal_mode(normals, ("given", "none"))
        self.has_normals = self.mode == "given"
        self.u, self.v = orthonormal_frame(self.normal)
        self.dim = 3

    def measure(self) -> float:
        return math.pi * (self.r_outer**2 - self.r_inner**2)

    def sample(self, n, generator=None, device=None, dtype=torch.float32):
        r = rand(generator, (n, 2), "cpu", torch.float64)
        rad = torch.sqrt(self.r_inner**2 + r[:, 0] * (self.r_outer**2 - self.r_inner**2))
        th = 2 * math.pi * r[:, 1]
        x = self.center + rad[:, None] * (th.cos()[:, None] * self.u + th.sin()[:, None] * self.v)
        nrm = self.normal.expand(n, 3) * (1.0 if self.has_normals else 0.0)
        return x.to(device=device, dtype=dtype), nrm.to(device=device, dtype=dtype)

    def distance(self, x: Tensor) -> Tensor:
        p = x - like(self.center, x)
        h = p @ like(self.normal, x)
        rho = (p - h[:, None] * like(self.normal, x)).norm(dim=-1)
        dr = torch.maximum((self.r_inner - rho).clamp_min(0), (rho - self.r_outer).clamp_min(0))
        return torch.sqrt(h**2 + dr**2)

    def rim_distance(self, x: Tensor) -> Tensor:
        """To the nearer of its outer and (``r_inner > 0``) inner circle."""
        p = x - like(self.center, x)
        h = p @ like(self.normal, x)
        rho = (p - h[:, None] * like(self.normal, x)).norm(dim=-1)
        dr = (rho - self.r_outer).abs()
        if self.r_inner > 0:
            dr = torch.minimum(dr, (rho - self.r_inner).abs())
        return torch.sqrt(h**2 + dr**2)

    def bounds(self):
        ext = self.r_outer * (1 - self.normal**2).clamp_min(0).sqrt()
        return self.center - ext, self.center + ext


class InterfaceUnion(Interface):
    """Several interfaces handled as one.

    Arguments:
        parts: the interfaces (same dimension).
        merge: True: all parts form ONE component (e.g. a bolt hole = wall + top ring);
            False: the parts' components are listed one after another.

    ``sample`` splits ``n`` across the parts in proportion to their measure (exact total, largest
    remainder), part after part. Parts without normals return zero normals.
    """

    def __init__(self, parts: Sequence[Interface], merge: bool = False):
        self.parts = tuple(parts)
        if not self.parts:
            raise ValueError("an interface union needs at least one part")
        dims = {p.dim for p in self.parts}
        if len(dims) != 1:
            raise ValueError("interface parts have different dimensions")
        self.dim = dims.pop()
        self.merge = bool(merge)
        self.has_normals = all(p.has_normals for p in self.parts)
        cs = [p.corners for p in self.parts if getattr(p, "corners", None) is not None]
        self.corners = torch.cat(cs) if cs else None

    @property
    def n_components(self) -> int:
        return 1 if self.merge else sum(p.n_components for p in self.parts)

    def measure(self) -> float:
        return float(sum(p.measure() for p in self.parts))

    def split(self, n: int) -> list[int]:
        """How many of ``n`` samples each part gets."""
        return split_count(n, [p.measure() for p in self.parts])

    def sample(self, n, generator=None, device=None, dtype=torch.float32):
        xs, ns = [], []
        for p, k in zip(self.parts, self.split(n)):
            x, nr = p.sample(k, generator, device, dtype)
            xs.append(x)
            ns.append(nr)
        return torch.cat(xs), torch.cat(ns)

    def distance(self, x: Tensor) -> Tensor:
        return torch.stack([p.distance(x) for p in self.parts], dim=-1).min(dim=-1).values

    def rim_distance(self, x: Tensor) -> Tensor:
        return torch.stack([p.rim_distance(x) for p in self.parts], dim=-1).min(dim=-1).values

    def nearest(self, x: Tensor) -> tuple[Tensor, Tensor]:
        ds, qs = zip(*(p.nearest(x) for p in self.parts))
        j = torch.stack(ds, dim=-1).argmin(dim=-1)  # (n,)
        rows = torch.arange(x.shape[0], device=x.device)
        return torch.stack(ds, dim=-1)[rows, j], torch.stack(qs, dim=1)[rows, j]

    def component_of(self, x: Tensor) -> Tensor:
        if self.merge:
            return torch.zeros(x.shape[0], dtype=torch.long, device=x.device)
        d = torch.stack([p.distance(x) for p in self.parts], dim=-1)
        which = d.argmin(dim=-1)
        out = torch.zeros(x.shape[0], dtype=torch.long, device=x.device)
        offset = 0
        for i, p in enumerate(self.parts):
            m = which == i
            if m.any():
                out[m] = offset + p.component_of(x[m])
            offset += p.n_components
        return out

    def bounds(self):
        bs = [p.bounds() for p in self.parts]
        if any(b is None for b in bs):
            return None
        return torch.stack([b[0] for b in bs]).min(0).values, torch.stack([b[1] for b in bs]).max(0).values


class TransformedInterface(Interface):
    """An interface moved rigidly by ``x -> R x + t`` (normals rotated by ``R``)."""

    def __init__(self, interface: Interface, rotation=None, translation=None):
        self.interface = interface
        self.dim = interface.dim
        d = self.dim
        self.rotation = torch.eye(d, dtype=torch.float64) if rotation is None else check_rotation(rotation)
        self.translation = torch.zeros(d, dtype=torch.float64) if translation is None else as_f64(translation, "translation", (d,))
        self.has_normals = interface.has_normals
        c = getattr(interface, "corners", None)
        self.corners = None if c is None else c @ self.rotation.T + self.translation

    @property
    def n_components(self) -> int:
        return self.interface.n_components

    def _local(self, x: Tensor) -> Tensor:
        return (x - like(self.translation, x)) @ like(self.rotation, x)

    def measure(self) -> float:
        return self.interface.measure()

    def sample(self, n, generator=None, device=None, dtype=torch.float32):
        x, nr = self.interface.sample(n, generator, device, dtype)
        R, t = like(self.rotation, x), like(self.translation, x)
        return x @ R.T + t, nr @ R.T

    def distance(self, x: Tensor) -> Tensor:
        return self.interface.distance(self._local(x))

    def rim_distance(self, x: Tensor) -> Tensor:
        return self.interface.rim_distance(self._local(x))

    def nearest(self, x: Tensor) -> tuple[Tensor, Tensor]:
        d, q = self.interface.nearest(self._local(x))
        return d, q @ like(self.rotation, q).T + like(self.translation, q)

    def component_of(self, x: Tensor) -> Tensor:
        return self.interface.component_of(self._local(x))

    def bounds(self):
        b = self.interface.bounds()
        if b is None:
            return None
        lo, hi = b
        d = self.dim
        idx = torch.cartesian_prod(*[torch.tensor([0, 1])] * d).reshape(-1, d)
        w = torch.where(idx.bool(), hi, lo) @ self.rotation.T + self.translation
        return w.min(0).values, w.max(0).values
