"""The grid nodes near interfaces or their rims, for the verdicts that leave those neighbourhoods
out (the volume outside E, the least feature sizes)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from ..geometry.base import Interface
from .grid import Grid

__all__ = ["nodes_near"]


def nodes_near(interfaces: Sequence[Interface], grid: Grid, among: np.ndarray, reach: float, rims: bool = False,
               chunk: int = 1 << 18) -> np.ndarray:
    """``(grid.shape)`` bool: the nodes of the mask ``among`` within ``reach`` of one of
    ``interfaces`` (:meth:`~ginn.geometry.base.Interface.distance`) or, with ``rims``, of one of
    their rims (:meth:`~ginn.geometry.base.Interface.rim_distance`). Distances are computed only for
    the nodes inside each interface's bounding box widened by ``reach``; an interface without a
    distance marks none."""
    out = np.zeros(grid.shape, dtype=bool)
    flat = out.reshape(-1)
    coords = [grid.axis_coords(a) for a in range(grid.dim)]
    for itf in interfaces:
        b = itf.bounds()
        box = np.ones(grid.shape, dtype=bool)
        if b is not None:
            lo, hi = b[0].double().cpu().numpy() - reach, b[1].double().cpu().numpy() + reach
            for a in range(grid.dim):
                sel = (coords[a] >= lo[a]) & (coords[a] <= hi[a])
                box &= sel.reshape([-1 if i == a else 1 for i in range(grid.dim)])
        idx = np.flatnonzero((box & among & ~out).reshape(-1))
        for s in range(0, idx.size, chunk):
            part = idx[s : s + chunk]
            x = torch.as_tensor(np.stack([coords[a][i] for a, i in enumerate(np.unravel_index(part, grid.shape))], axis=1),
                                dtype=torch.float64)
            try:
                with torch.no_grad():
                    d = (itf.rim_distance(x) if rims else itf.distance(x)).double().cpu().numpy()
            except NotImplementedError:
                break
            flat[part[d <= reach]] = True
    return out
