"""Grids: the one node-grid type of ginn, its two constructors, and what is computed on node masks.

* :class:`Grid` holds ``cells[a] + 1`` nodes along axis ``a`` over a box, both faces included
  (a *vertex* grid; array axis ``a`` is coordinate ``a``, C order, ``indexing="ij"``).
* :func:`make_grid` sizes it by *cells* along the longest axis (extraction, metrics, figures; the
  other axes rounded to multiples of 8 so that adaptive sampling can coarsen them);
  :func:`node_grid` by *nodes* along the longest axis (the topology's seed and PH grids).
* :func:`periodic_points` is the periodic unit-square grid of the Gray-Scott task (``n`` points
  per axis, the last face left out because it is the first one's periodic image).
* :func:`label_components` labels face-connected components of a node mask (4 neighbours in 2D,
  6 in 3D: the 0- and 1-cells of the cubical complex of :mod:`ginn.topology.persistent`, and the
  saddle rule of marching squares in :mod:`ginn.extract.boundary`, so all three count alike).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from scipy import ndimage
from torch import Tensor

from ..errors import ConfigError
from ..geometry.base import Box

__all__ = [
    "Grid", "make_grid", "node_grid", "proportional_counts", "check_grid_memory", "periodic_points", "label_components",
    "interpolate", "grid_volume",
]


@dataclass(frozen=True)
class Grid:
    """A node grid over a box: ``cells[a] + 1`` nodes along axis ``a`` including both faces.

    Attributes:
        lo, hi: box corners, ``(d,)`` float64 arrays.
        cells: number of cells per axis.
    """

    lo: np.ndarray
    hi: np.ndarray
    cells: tuple[int, ...]

    @property
    def dim(self) -> int:
        return len(self.cells)

    @property
    def shape(self) -> tuple[int, ...]:
        """Nodes per axis."""
        return tuple(c + 1 for c in self.cells)

    @property
    def spacing(self) -> np.ndarray:
        return (self.hi - self.lo) / np.asarray(self.cells, dtype=np.float64)

    @property
    def n_nodes(self) -> int:
        return int(np.prod(self.shape))

    def axis_coords(self, a: int) -> np.ndarray:
        return np.linspace(self.lo[a], self.hi[a], self.cells[a] + 1)

    def points(self, flat_index: np.ndarray | None = None) -> np.ndarray:
        """Node positions ``(n, d)`` for flat (C-order) node indices (all nodes when None)."""
        if flat_index is None:
            flat_index = np.arange(self.n_nodes)
        idx = np.unravel_index(flat_index, self.shape)
        return np.stack([self.lo[a] + idx[a] * self.spacing[a] for a in range(self.dim)], axis=-1)

    def to_index(self, x: np.ndarray) -> np.ndarray:
        """World coordinates ``(n, d)`` to fractional node indices ``(n, d)``."""
        return (np.asarray(x, dtype=np.float64) - self.lo) / self.spacing

    def node_weights(self) -> np.ndarray:
        """Trapezoid quadrature weights ``(shape)`` (float32): ``sum = vol(box)``; a set's volume is
        the sum of the weights of its nodes."""
        w = np.float32(np.prod(self.spacing)) * np.ones((), dtype=np.float32)
        for a in range(self.dim):
            wa = np.ones(self.shape[a], dtype=np.float32)
            wa[0] = wa[-1] = 0.5
            w = np.multiply.outer(w, wa)
        return np.ascontiguousarray(w)

    def tensor_points(self, device=None, dtype=torch.float32) -> Tensor:
        """Node positions ``(n_nodes, d)`` as a tensor, C order of ``shape`` (``indexing="ij"``),
        each axis from ``torch.linspace(lo, hi, nodes)``."""
        axes = [torch.linspace(float(a), float(b), n, device=device, dtype=dtype) for a, b, n in zip(self.lo, self.hi, self.shape)]
        mesh = torch.meshgrid(*axes, indexing="ij")
        return torch.stack([m.reshape(-1) for m in mesh], dim=-1)

    def coarsened(self, levels: int) -> Grid:
        return Grid(self.lo, self.hi, tuple(c >> levels for c in self.cells))

    def extended(self, pad: int) -> Grid:
        """The grid with ``pad`` more nodes beyond every face, same spacing."""
        h = self.spacing
        return Grid(self.lo - pad * h, self.hi + pad * h, tuple(c + 2 * pad for c in self.cells))


def make_grid(domain: Box, resolution: int) -> Grid:
    """A grid over ``domain`` with ``resolution`` cells along its longest axis and about the same
    spacing along the others (their cell counts rounded to multiples of 8 when ``resolution >= 64``
    so that adaptive sampling can coarsen them)."""
    lo = np.asarray(domain.lo, dtype=np.float64)
    hi = np.asarray(domain.hi, dtype=np.float64)
    ext = hi - lo
    if np.any(ext <= 0):
        raise ValueError(f"degenerate domain {domain}")
    resolution = int(resolution)
    if resolution < 2:
        raise ValueError("resolution must be at least 2")
    m = 8 if resolution >= 64 else 1
    cells = []
    for e in ext:
        c = resolution * e / ext.max()
        cells.append(resolution if e == ext.max() else max(m, int(round(c / m)) * m))
    return Grid(lo, hi, tuple(cells))


def check_grid_memory(n_nodes: int, bytes_per_node: int, what: str) -> None:
    """Refuse a grid whose arrays would need more than half of this machine's memory.

    Raises:
        ConfigError: one line naming ``what`` (e.g. ``resolution 100000000``), the estimate and
            the memory there is.
    """
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # no sysconf: nothing to compare with
        return
    need = float(n_nodes) * bytes_per_node
    if need > total / 2:
        raise ConfigError(f"{what}: a grid of {float(n_nodes):.3g} nodes needs about {need / 2**30:.3g} GiB; "
                          f"this machine has {total / 2**30:.3g} GiB")


def proportional_counts(box: Box, n: int) -> tuple[int, ...]:
    """``n`` along the longest axis of ``box`` and proportionally fewer (at least 2) along the others."""
    ext = np.asarray(box.hi, dtype=float) - np.asarray(box.lo, dtype=float)
    return tuple(max(2, int(round(int(n) * e / ext.max()))) for e in ext)


def node_grid(box: Box, resolution: int | Sequence[int]) -> Grid:
    """A grid over ``box`` with ``resolution`` *nodes* along the longest axis (the others get
    proportionally fewer, at least 2, so cells are nearly square), or an explicit per-axis
    sequence of node counts."""
    if isinstance(resolution, (int, np.integer)):
        nodes = proportional_counts(box, resolution)
    else:
        nodes = tuple(int(n) for n in resolution)
        if len(nodes) != box.dim:
            raise ValueError(f"resolution has {len(nodes)} entries for a {box.dim}-dimensional box")
    return Grid(np.asarray(box.lo, dtype=np.float64), np.asarray(box.hi, dtype=np.float64), tuple(n - 1 for n in nodes))


def periodic_points(n: int, offset: Tensor | None = None, dtype: torch.dtype = torch.float32, device=None) -> Tensor:
    """Points of the (translated) periodic unit-square grid, ``(n, n, 2)``, ``x[i, j] = ((i, j) + offset) / n``.

    Arguments:
        n: points per axis.
        offset: translation in grid units, shape ``(2,)`` (None: 0).
    """
    i = torch.arange(n, dtype=dtype, device=device)
    if offset is None:
        offset = torch.zeros(2, dtype=dtype, device=device)
    offset = offset.to(dtype=dtype, device=device)
    x0 = (i[:, None].expand(n, n) + offset[0]) / n
    x1 = (i[None, :].expand(n, n) + offset[1]) / n
    return torch.stack([x0, x1], dim=-1)


def label_components(mask: np.ndarray, connectivity: int = 1) -> tuple[np.ndarray, int]:
    """Label the connected components of a boolean node mask.

    Arguments:
        mask: boolean array of any dimension (2D and 3D in practice).
        connectivity: 1 for face neighbours (default), ``mask.ndim`` for all neighbours including diagonals.

    Returns:
        ``labels`` (int array of ``mask.shape``; 0 outside, ``1..n`` for the components) and ``n``.
    """
    mask = np.asarray(mask, dtype=bool)
    structure = ndimage.generate_binary_structure(mask.ndim, connectivity)
    labels, n = ndimage.label(mask, structure=structure)
    return labels, int(n)


def interpolate(values: np.ndarray, grid: Grid, x: np.ndarray) -> np.ndarray:
    """Multilinear interpolation of node ``values`` at points ``x (n, d)`` (clamped to the box)."""
    idx = grid.to_index(x)
    idx = np.clip(idx, 0, np.asarray(grid.cells, dtype=np.float64))
    return ndimage.map_coordinates(values, idx.T, order=1, mode="nearest")


def grid_volume(mask: np.ndarray, grid: Grid, weights: np.ndarray | None = None) -> float:
    """Trapezoid-rule volume of a node mask ``(grid.shape)``."""
    w = grid.node_weights() if weights is None else weights
    return float(w[mask].sum(dtype=np.float64))
