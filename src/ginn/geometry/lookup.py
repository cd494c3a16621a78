"""Fast exact membership of a region, answered from its signed distance sampled on a grid.

For a region whose ``sdf`` has the exact sign and is 1-Lipschitz (``region.lipschitz``), the sign
cannot change within ``|sdf(y)|`` of a point ``y``. :class:`RegionLookup` samples the SDF once on
the nodes of a grid over a box; a query point ``x`` takes the sign of its nearest node ``y``
whenever ``|x - y| < |sdf(y)|`` (a sure answer), and asks the region itself for the few points
closer to the boundary than that. The answer equals ``region.contains(x)`` for every point, at
the cost of an index lookup for most of them: the connectedness loss asks the design region
about every point of every integral path at every tracing step.
"""

from __future__ import annotations

import time

import torch
from torch import Tensor

from .base import Box, Region

__all__ = ["RegionLookup", "fast_membership", "fastest_membership"]


class RegionLookup(Region):
    """``region``'s membership from a grid of its SDF (see the module docstring).

    Arguments:
        region: a region with ``region.lipschitz`` True.
        box: where queries are expected (points outside it ask the region).
        cells: grid cells along the box's longest axis (the others proportionally).
        device: where the grid lives (the queries' device).
        chunk: points per SDF evaluation while the grid is built.
    """

    def __init__(self, region: Region, box: Box, cells: int = 128, device=None, chunk: int = 1 << 18):
        if not region.lipschitz:
            raise ValueError("RegionLookup needs a region whose sdf is 1-Lipschitz with the exact sign")
        self.region = region
        self.dim = region.dim
        self.lipschitz = True
        self.device = torch.device(device) if device is not None else torch.device("cpu")
        lo = torch.tensor(box.lo, dtype=torch.float64)
        hi = torch.tensor(box.hi, dtype=torch.float64)
        ext = hi - lo
        counts = [max(2, round(int(cells) * float(e) / float(ext.max()))) for e in ext]
        self.shape = tuple(c + 1 for c in counts)
        self.lo, self.h = lo, ext / torch.tensor(counts, dtype=torch.float64)
        axes = [lo[a] + self.h[a] * torch.arange(n, dtype=torch.float64) for a, n in enumerate(self.shape)]
        nodes = torch.stack([m.reshape(-1) for m in torch.meshgrid(*axes, indexing="ij")], dim=-1)
        with torch.no_grad():
            values = torch.cat([region.sdf(nodes[s:s + chunk]).to(torch.float64) for s in range(0, len(nodes), chunk)])
        self.values = values.to(self.device)
        self._lo, self._h = lo.to(self.device), self.h.to(self.device)
        self._strides = torch.tensor([int(torch.tensor(self.shape[a + 1:]).prod()) for a in range(self.dim)],
                                     device=self.device)
        self._top = torch.tensor([n - 1 for n in self.shape], device=self.device)

    def sdf(self, x: Tensor) -> Tensor:
        return self.region.sdf(x)

    def contains(self, x: Tensor) -> Tensor:
        """Boolean ``(n,)``, equal to ``region.contains(x)``."""
        xd = x.detach().to(self.device, torch.float64)
        t = (xd - self._lo) / self._h
        idx = t.round().long()
        inside_box = ((idx >= 0) & (idx <= self._top)).all(dim=-1)
        idx = torch.minimum(idx.clamp_min(0), self._top)
        v = self.values[(idx * self._strides).sum(-1)]
        node = self._lo + idx.to(torch.float64) * self._h
        dist = (xd - node).norm(dim=-1)
        sure = inside_box & (v.abs() > dist * (1 + 1e-9) + 1e-12)
        out = v <= 0
        unsure = ~sure
        if bool(unsure.any()):
            out = out.clone()
            out[unsure] = self.region.contains(x[unsure]).to(self.device)
        return out.to(x.device)

    def bounds(self):
        return self.region.bounds()


def fast_membership(region: Region | None, box: Box, cells: int = 128, device=None) -> Region | None:
    """``region`` wrapped in a :class:`RegionLookup` when its SDF allows it, else ``region`` itself."""
    if region is None or not region.lipschitz:
        return region
    return RegionLookup(region, box, cells, device)


def _seconds(region: Region, x: Tensor, repeats: int) -> float:
    sync = torch.cuda.synchronize if x.device.type == "cuda" else (lambda: None)
    best = float("inf")
    for _ in range(repeats):
        sync()
        t0 = time.perf_counter()
        region.contains(x)
        sync()
        best = min(best, time.perf_counter() - t0)
    return best


def fastest_membership(region: Region | None, box: Box, cells: int = 128, device=None, n: int = 4096,
                       repeats: int = 3) -> Region | None:
    """Whichever of ``region`` and its :class:`RegionLookup` answers ``contains`` faster on ``n``
    uniform points of ``box`` (best of ``repeats``). Both give the same answers, so the choice
    changes the time, never a result: a CSG of many parts or a mesh is slower than the lookup's
    fixed dozen operations; a rectangle minus a disk is faster."""
    lookup = fast_membership(region, box, cells, device)
    if lookup is region:
        return region
    lo, hi = box.tensors(lookup.device, torch.float32)
    x = lo + (hi - lo) * torch.rand(n, box.dim, generator=torch.Generator().manual_seed(0)).to(lookup.device)
    _seconds(lookup, x, 1)  # first calls pay for allocation
    return lookup if _seconds(lookup, x, repeats) < _seconds(region, x, repeats) else region
