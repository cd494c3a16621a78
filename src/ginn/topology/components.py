"""Connected components of a shape ``{f <= 0}`` sampled on a regular grid (the Betti number b0).

This is the component counter shared by the connectedness diagnostics and the metrics
(Appendix B.1: ``b0(Omega)``, ``b0(Omega ∩ E)``, volumes of disconnected components).

Conventions:

* Grids are *vertex* grids: ``n_i`` nodes per axis from ``lo_i`` to ``hi_i`` inclusive
  (``numpy.linspace``), array axis ``i`` is coordinate ``i`` (``indexing="ij"``).
* Connectivity is *face* connectivity (4 neighbours in 2D, 6 in 3D), the same as the 0-cells
  and 1-cells of the cubical complex used by :mod:`ginn.topology.persistent` (cripser's
  V-construction), so that both count the same components.
* A node belongs to the shape when ``value <= level`` (and, with a region, when the node lies in
  the region).

Public API (all NumPy in, NumPy/int out, except :func:`b0` which evaluates a field):

* the grid is :func:`ginn.extract.grid.node_grid` and the labelling
  :func:`ginn.extract.grid.label_components`.
* :func:`b0_of_mask` ``(mask) -> int``.
* :func:`component_sizes` ``(labels, n) -> sizes``.
* :func:`count_components` ``(values, level=0, region_mask=None) -> int``.
* :func:`b0` ``(field, Z, box, resolution, region=None) -> np.ndarray (S,)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor

from ..extract.grid import label_components, node_grid
from ..fields import Field, value
from ..geometry.base import Box, Region


def b0_of_mask(mask: np.ndarray, connectivity: int = 1) -> int:
    """Number of connected components of a boolean grid (0 for an empty mask)."""
    return label_components(mask, connectivity)[1]


def component_sizes(labels: np.ndarray, n: int) -> np.ndarray:
    """Number of grid nodes of each component ``1..n``, shape ``(n,)`` (multiply by the cell
    volume for areas/volumes)."""
    return np.bincount(labels.reshape(-1), minlength=n + 1)[1:]


def count_components(
    values: np.ndarray, level: float = 0.0, region_mask: np.ndarray | None = None, connectivity: int = 1
) -> int:
    """b0 of ``{values <= level}`` (optionally intersected with ``region_mask``) on a grid.

    Arguments:
        values: field values on a grid, any shape (one shape, not a batch).
        level: the iso-level (0 for the shape ``{f <= 0}``).
        region_mask: optional boolean array of the same shape (e.g. the design region E).
    """
    mask = np.asarray(values) <= level
    if region_mask is not None:
        mask = mask & np.asarray(region_mask, dtype=bool)
    return b0_of_mask(mask, connectivity)


def field_on_grid(
    field: Field,
    Z: Tensor | None,
    box: Box,
    resolution: int | Sequence[int],
    device=None,
    dtype=torch.float32,
    chunk: int = 65536,
) -> tuple[np.ndarray, Tensor, tuple[int, ...]]:
    """Values of every shape of a batch on the grid of ``box``, in one batched evaluation.

    Arguments:
        field: ``(x, z) -> (n,)``.
        Z: latent codes ``(S, k)`` or None (one shape).

    Returns:
        values ``(S, *shape)`` (NumPy), the grid points ``(G, d)`` and ``shape``.
    """
    if Z is not None:
        device, dtype = Z.device, (Z.dtype if Z.is_floating_point() else dtype)
    grid = node_grid(box, resolution)
    pts, shape = grid.tensor_points(device, dtype), grid.shape
    G = pts.shape[0]
    if Z is None:
        vals = value(field, pts, None, chunk=chunk).reshape(1, *shape)
    else:
        S = Z.shape[0]
        x = pts.repeat(S, 1)
        z = Z.repeat_interleave(G, dim=0)
        vals = value(field, x, z, chunk=chunk).reshape(S, *shape)
    return vals.detach().cpu().double().numpy(), pts, shape


def b0(
    field: Field,
    Z: Tensor | None,
    box: Box,
    resolution: int | Sequence[int],
    region: Region | None = None,
    level: float = 0.0,
    connectivity: int = 1,
) -> np.ndarray:
    """b0 of ``{f <= level}`` (optionally ``∩ region``) for every shape, counted on a grid.

    Arguments:
        field: ``(x, z) -> (n,)``.
        Z: latent codes ``(S, k)`` or None.
        box: the domain X (grid extent).
        resolution: nodes along the longest axis, or per axis.
        region: optional region (e.g. the design region E) to intersect with.

    Returns:
        integer array ``(S,)`` (``(1,)`` when ``Z`` is None).
    """
    vals, pts, shape = field_on_grid(field, Z, box, resolution)
    rmask = None
    if region is not None:
        rmask = region.contains(pts).reshape(shape).cpu().numpy()
    return np.array([count_components(v, level, rmask, connectivity) for v in vals], dtype=np.int64)
