"""Topology that a problem's geometry forces on every feasible shape (a target below it is refused).

In 2D, an interface circle whose inside is a part of X \\ E (a bolt hole, a pin) must be surrounded
by the shape: the shape's boundary runs along the circle and the shape cannot fill its inside, so
that part is a hole of every feasible shape. Distinct such parts are distinct holes, so their
number bounds ``topology.holes`` from below. Parts of X \\ E are found on a node grid of the domain
(diagonal neighbours joined, as the complement of a shape is counted by
:func:`ginn.topology.betti_numbers`); a part counts when it does not reach the domain's edge and
lies within its circle (to a cell's diagonal).

In 3D, an interface cylinder wall whose axis line crosses the whole domain outside E (a bolt hole
through the part, open above and below) is a channel every feasible shape surrounds: a tunnel.
Walls on lines that come within the sum of their radii of each other count once (a loop round
one channel could be slid to the other), so the count bounds ``topology.tunnels`` from below.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from scipy import sparse
from scipy.sparse import csgraph

from ..extract.grid import label_components, node_grid
from ..geometry.base import Box, Interface, Region
from ..geometry.interfaces import Circle, CylinderWall, InterfaceUnion

__all__ = ["forced_holes", "forced_tunnels"]


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
    labels, _ = label_components(outside, connectivity=2)
    edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    nodes = pts.cpu().numpy().reshape(*grid.shape, 2)
    found: dict[int, int] = {}
    for i, c in circles:
        centre = np.asarray(c.center, dtype=np.float64)
        at = np.clip(np.rint(grid.to_index(centre[None])[0]).astype(np.int64), 0, np.asarray(grid.shape) - 1)
        part = int(labels[tuple(at)])
        if part == 0 or part in edge or part in found:
            continue
        reach = np.linalg.norm(nodes[labels == part] - centre, axis=1).max()
        if reach <= c.radius + float(np.linalg.norm(grid.spacing)):
            found[part] = i
    return sorted(found.values())


def _walls(interfaces: Sequence[Interface]) -> list[tuple[int, CylinderWall]]:
    """The cylinder walls among ``interfaces`` (inside unions too), with the index of the spec
    interface each belongs to."""
    out = []

    def visit(i: int, f: Interface) -> None:
        if isinstance(f, CylinderWall):
            out.append((i, f))
        elif isinstance(f, InterfaceUnion):
            for part in f.parts:
                visit(i, part)

    for i, f in enumerate(interfaces):
        visit(i, f)
    return out


def _line_gap(a: CylinderWall, b: CylinderWall) -> float:
    """The distance between the two walls' axis lines."""
    n = torch.linalg.cross(a.axis, b.axis)
    w = b.center - a.center
    if float(n.norm()) < 1e-9:  # parallel
        return float((w - (w @ a.axis) * a.axis).norm())
    return float((w @ n).abs() / n.norm())


def forced_tunnels(domain: Box, design: Region | None, interfaces: Sequence[Interface],
                   resolution: int = 128) -> list[int]:
    """The interfaces that force a tunnel, one per tunnel (3D): indices into ``interfaces``.

    Arguments:
        domain: X (3D); design: E with the obstacles removed (None: no tunnel is forced).
        interfaces: the problem's interfaces, in spec order (cylinder walls are looked for inside
            groups too).
        resolution: points per longest side of the domain along each axis line.

    Returns:
        for each channel (walls whose lines meet, merged), the first interface it comes from (sorted).
    """
    walls = _walls(interfaces)
    if design is None or domain.dim != 3 or not walls:
        return []
    lo, hi = domain.tensors(dtype=torch.float64)
    step = float((hi - lo).max()) / resolution
    reach = float((hi - lo).norm())
    t = torch.arange(-reach, reach + step, step, dtype=torch.float64)
    through = []
    for i, w in walls:
        line = w.center + t[:, None] * w.axis
        line = line[((line >= lo) & (line <= hi)).all(-1)]
        through.append(len(line) > 0 and not bool(design.contains(line).any()))
    # channels: the components of the graph joining walls whose lines come within the sum of their radii
    n = len(walls)
    near = np.array([[_line_gap(a, b) < a.radius + b.radius for _, b in walls] for _, a in walls])
    _, channel = csgraph.connected_components(sparse.csr_matrix(near), directed=False)
    first = [i for i, _ in walls]
    return sorted(min(first[a] for a in range(n) if channel[a] == c) for c in np.unique(channel)
                  if all(through[a] for a in range(n) if channel[a] == c))
