"""Topology that a problem's geometry forces on every feasible shape (a target below it is refused).

In 2D, an interface circle whose inside is a part of X \\ E (a bolt hole, a pin) must be surrounded
by the shape: the shape's boundary runs along the circle and the shape cannot fill its inside, so
that part is a hole of every feasible shape. Distinct such parts are distinct holes, so their
number bounds ``topology.holes`` from below. Parts of X \\ E are found on a node grid of the domain
(diagonal neighbours joined, as the complement of a shape is counted by
:func:`ginn.topology.betti_numbers`); a part counts when it does not reach the domain's edge and
lies within its circle (to a cell's diagonal).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from scipy import ndimage

from ..extract.grid import node_grid
from ..geometry.base import Box, Interface, Region
from ..geometry.interfaces import Circle

__all__ = ["forced_holes"]


def forced_holes(domain: Box, design: Region | None, interfaces: Sequence[Interface],
                 resolution: int = 256) -> list[int]:
    """The interfaces that force a hole, one per hole (2D): indices into ``interfaces``.

    Arguments:
        domain: X (2D); design: E with the obstacles removed (None: no hole is forced).
        interfaces: the problem's interfaces, in spec order.
        resolution: grid nodes along the longest axis.

    Returns:
        the index of the first interface circle round each part of X \\ E it encloses (sorted).
    """
    circles = [(i, f) for i, f in enumerate(interfaces) if isinstance(f, Circle)]
    if design is None or domain.dim != 2 or not circles:
        return []
    grid = node_grid(domain, resolution)
    pts = grid.tensor_points(dtype=torch.float64)
    outside = ~design.contains(pts).reshape(grid.shape).cpu().numpy().astype(bool)
    labels, _ = ndimage.label(outside, structure=np.ones((3, 3), dtype=bool))
    edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    lo = np.asarray(domain.lo, dtype=np.float64)
    spacing = (np.asarray(domain.hi, dtype=np.float64) - lo) / (np.asarray(grid.shape) - 1)
    nodes = pts.cpu().numpy().reshape(*grid.shape, 2)
    found: dict[int, int] = {}
    for i, c in circles:
        centre = np.asarray(c.center, dtype=np.float64)
        at = tuple(np.clip(np.rint((centre - lo) / spacing).astype(np.int64), 0, np.asarray(grid.shape) - 1))
        part = int(labels[at])
        if part == 0 or part in edge or part in found:
            continue
        reach = np.linalg.norm(nodes[labels == part] - centre, axis=1).max()
        if reach <= c.radius + float(np.linalg.norm(spacing)):
            found[part] = i
    return sorted(found.values())
