"""The structured finite-element grid over a box: nodes, elements and their degrees of freedom.

Elements and nodes are numbered in C order over their grid indices (the last axis fastest);
node ``n`` carries the degrees of freedom ``dim n + k`` (``k`` the displacement component).

Public names: :class:`ElementGrid`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .elements import corner_offsets

__all__ = ["ElementGrid"]


@dataclass(frozen=True, eq=False)
class ElementGrid:
    """``shape`` elements (``(n_x, n_y[, n_z])``) over the box ``[lo, hi]``.

    Attributes:
        lo, hi: ``(dim,)`` corners of the box.
        shape: elements per axis.
    """

    lo: tuple[float, ...]
    hi: tuple[float, ...]
    shape: tuple[int, ...]

    def __post_init__(self) -> None:
        if not (len(self.lo) == len(self.hi) == len(self.shape)) or len(self.shape) not in (2, 3):
            raise ValueError("ElementGrid: lo, hi and shape need 2 or 3 entries each")
        if any(n < 1 for n in self.shape) or any(h <= lo for lo, h in zip(self.lo, self.hi)):
            raise ValueError("ElementGrid: an empty box or no elements along an axis")

    @classmethod
    def over(cls, lo, hi, cells_along_longest: int) -> ElementGrid:
        """Elements as close to cubes as the box allows, ``cells_along_longest`` along its longest side."""
        lo = np.asarray(lo, dtype=np.float64)
        hi = np.asarray(hi, dtype=np.float64)
        size = hi - lo
        n = np.maximum(1, np.rint(cells_along_longest * size / size.max())).astype(int)
        return cls(tuple(map(float, lo)), tuple(map(float, hi)), tuple(int(k) for k in n))

    @property
    def dim(self) -> int:
        return len(self.shape)

    @cached_property
    def h(self) -> np.ndarray:
        """``(dim,)`` element side lengths."""
        return (np.asarray(self.hi) - np.asarray(self.lo)) / np.asarray(self.shape)

    @property
    def node_shape(self) -> tuple[int, ...]:
        return tuple(n + 1 for n in self.shape)

    @property
    def n_elements(self) -> int:
        return int(np.prod(self.shape))

    @property
    def n_nodes(self) -> int:
        return int(np.prod(self.node_shape))

    @property
    def n_dofs(self) -> int:
        return self.dim * self.n_nodes

    @property
    def element_volume(self) -> float:
        return float(np.prod(self.h))

    @cached_property
    def element_nodes(self) -> np.ndarray:
        """``(n_elements, 2^dim)`` node numbers of each element's corners (local numbering of
        :mod:`ginn.physics.elements`)."""
        idx = np.indices(self.shape).reshape(self.dim, -1)  # (d, ne)
        off = corner_offsets(self.dim)  # (n, d)
        corners = idx[:, :, None] + off.T[:, None, :]  # (d, ne, n)
        return np.ravel_multi_index(tuple(corners), self.node_shape)

    @cached_property
    def node_elements(self) -> np.ndarray:
        """``(n_nodes, 2^dim)`` the elements around each node, ``-1`` past the grid's edge: slot
        ``k`` is the element whose corner ``k`` the node is."""
        out = np.full((self.n_nodes, 2**self.dim), -1, dtype=np.int64)
        for k in range(out.shape[1]):
            out[self.element_nodes[:, k], k] = np.arange(self.n_elements)
        return out

    @cached_property
    def element_dofs(self) -> np.ndarray:
        """``(n_elements, dim 2^dim)`` degrees of freedom of each element, corner-major."""
        d = self.dim
        return (d * self.element_nodes[:, :, None] + np.arange(d)[None, None, :]).reshape(self.n_elements, -1)

    @cached_property
    def nodes(self) -> np.ndarray:
        """``(n_nodes, dim)`` node coordinates."""
        idx = np.indices(self.node_shape).reshape(self.dim, -1).T
        return np.asarray(self.lo) + idx * self.h

    @cached_property
    def centres(self) -> np.ndarray:
        """``(n_elements, dim)`` element centres."""
        idx = np.indices(self.shape).reshape(self.dim, -1).T
        return np.asarray(self.lo) + (idx + 0.5) * self.h

    def refined(self, factor: int = 2) -> ElementGrid:
        """The same box with ``factor`` times as many elements along each axis."""
        return ElementGrid(self.lo, self.hi, tuple(factor * n for n in self.shape))
