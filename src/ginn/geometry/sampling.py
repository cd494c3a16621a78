"""Monte Carlo point samplers with an explicit ``torch.Generator``, device and dtype.

Random numbers are drawn on the generator's device and moved to ``device`` (so a CPU generator
works for CUDA points, and runs are reproducible for a given generator state). Every sampler
returns *exactly* the requested number of points.

* :func:`sample_box`: uniform in the domain box X.
* :func:`sample_inside` / :func:`sample_outside`: uniform in ``region ∩ X`` / ``X \\ region`` by
  batched rejection.
* :func:`sample_interfaces`: on the interfaces, split across them by measure, with normals.
* :func:`sample_band`: a denser band around the interfaces (paper A.5).
* :func:`interface_corners`: the corner points of the interfaces (Plateau corner weighting).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor

from ._tensor import rand, randn
from .base import Box, Interface, Region
from .interfaces import InterfaceUnion


def sample_box(box: Box, n: int, gen: torch.Generator | None, device=None, dtype=torch.float32) -> Tensor:
    """``n`` points uniform in ``box``, ``(n, d)``."""
    lo, hi = box.tensors(device, dtype)
    u = rand(gen, (n, box.dim), device, dtype)
    return lo + u * (hi - lo)


def _rejection(
    keep, box: Box, n: int, gen, device, dtype, max_rounds: int, what: str
) -> Tensor:
    out: list[Tensor] = []
    have = 0
    batch = max(64, n)
    for _ in range(max_rounds):
        if have >= n:
            break
        x = sample_box(box, batch, gen, device, dtype)
        x = x[keep(x)]
        out.append(x)
        have += x.shape[0]
        # grow the batch to the estimated need (acceptance rate so far)
        rate = have / (batch * len(out)) if have else 0.0
        need = n - have
        batch = int(min(max(64, 1.2 * need / rate + 64), 4_000_000)) if rate > 0 else min(batch * 4, 4_000_000)
    if have < n:
        raise ValueError(f"could not sample {n} points {what} in {max_rounds} rounds (is it empty within the domain?)")
    return torch.cat(out)[:n]


def sample_inside(
    region: Region, box: Box, n: int, gen: torch.Generator | None, device=None, dtype=torch.float32, max_rounds: int = 64
) -> Tensor:
    """``n`` points uniform in ``region ∩ box``, ``(n, d)`` (every one satisfies ``region.contains``).

    Raises:
        ValueError: the region has (almost) no volume inside the box.
    """
    if n == 0:
        return torch.zeros(0, box.dim, device=device, dtype=dtype)
    return _rejection(region.contains, box, n, gen, device, dtype, max_rounds, "inside the region")


def sample_outside(
    region: Region, box: Box, n: int, gen: torch.Generator | None, device=None, dtype=torch.float32, max_rounds: int = 64
) -> Tensor:
    """``n`` points uniform in ``box \\ region``, ``(n, d)`` (none satisfies ``region.contains``)."""
    if n == 0:
        return torch.zeros(0, box.dim, device=device, dtype=dtype)
    return _rejection(lambda x: ~region.contains(x), box, n, gen, device, dtype, max_rounds, "outside the region")


def _as_union(interfaces: Interface | Sequence[Interface]) -> Interface:
    if isinstance(interfaces, Interface):
        return interfaces
    parts = tuple(interfaces)
    return parts[0] if len(parts) == 1 else InterfaceUnion(parts, merge=False)


def sample_interfaces(
    interfaces: Interface | Sequence[Interface], n: int, gen: torch.Generator | None, device=None, dtype=torch.float32
) -> tuple[Tensor, Tensor]:
    """``n`` points on the interfaces and their unit prescribed normals, ``(n, d)`` each.

    ``n`` is split across the interfaces in proportion to their measure (length/area; exact
    total), each sampled uniformly. Interfaces without normals give zero rows.
    """
    return _as_union(interfaces).sample(n, gen, device, dtype)


def sample_interfaces_with_components(
    interfaces: Interface | Sequence[Interface], n: int, gen: torch.Generator | None, device=None, dtype=torch.float32
) -> tuple[Tensor, Tensor, Tensor]:
    """Like :func:`sample_interfaces`, plus the global component index of each point ``(n,)``
    (components numbered interface after interface, ``0 .. sum(n_components) - 1``)."""
    u = _as_union(interfaces)
    x, nr = u.sample(n, gen, device, dtype)
    return x, nr, u.component_of(x)


def sample_band(
    interfaces: Interface | Sequence[Interface],
    n: int,
    width: float,
    gen: torch.Generator | None,
    device=None,
    dtype=torch.float32,
    box: Box | None = None,
) -> Tensor:
    """``n`` points in a band of half-width ``width`` around the interfaces (paper A.5).

    Each point is an interface sample plus a displacement uniform in the ball of radius
    ``width``, so the density is highest near the interfaces. With ``box`` given, points falling
    outside it are replaced (exact count, all inside ``box``).

    Returns:
        ``(n, d)`` points; every one is within ``width`` of an interface.
    """
    u = _as_union(interfaces)
    d = u.dim
    if n == 0:
        return torch.zeros(0, d, device=device, dtype=dtype)
    if not width > 0:
        raise ValueError("band width must be > 0")
    out: list[Tensor] = []
    have = 0
    for _ in range(64):
        m = max(n - have, 16) if box is None else int(1.5 * (n - have)) + 16
        p, _ = u.sample(m, gen, device, dtype)
        g = randn(gen, (m, d), device, dtype)
        g = g / g.norm(dim=-1, keepdim=True).clamp_min(1e-12)
        r = width * rand(gen, (m, 1), device, dtype) ** (1.0 / d)
        x = p + r * g
        if box is not None:
            x = x[box.contains(x)]
        out.append(x)
        have += x.shape[0]
        if have >= n:
            break
    if have < n:
        raise ValueError("could not sample the interface band inside the domain")
    return torch.cat(out)[:n]


def interface_corners(interfaces: Interface | Sequence[Interface], device=None, dtype=torch.float32) -> Tensor:
    """All corner points of the interfaces (their ``corners`` attributes), ``(c, d)``; ``c`` may be 0."""
    u = _as_union(interfaces)
    c = getattr(u, "corners", None)
    if c is None:
        return torch.zeros(0, u.dim, device=device, dtype=dtype)
    return c.to(device=device, dtype=dtype)
