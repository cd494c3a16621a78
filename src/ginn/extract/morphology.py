"""Least feature sizes measured on a shape's node grid: what the morphological opening (the solid) or
closing (the void) by a ball removes or adds.

A shape has thickness at least ``t`` where a ball of diameter ``t`` inside it covers every point:
the opening by the ball (erosion, then dilation) keeps the whole shape. What the opening removes
is what is thinner: necks, plates and sharp tips (a right-angled corner loses ``(1 - pi / 4) r^2``
of area, ``r = t / 2``). The void has width at least ``t`` where the closing (the opening of the
complement) adds nothing: gaps, slots and holes narrower than the ball are filled.

Both operations use two Euclidean distance transforms on the grid's nodes
(:func:`scipy.ndimage.distance_transform_edt` with the grid spacing): the erosion keeps the nodes
farther than ``r`` from the nearest node outside, the dilation adds the nodes within ``r`` of the
nearest kept node. The cost does not depend on ``r``. The grid is extended beyond the domain by
repeating its faces, so a shape cut by a face of the domain is opened as if it went on: a cut is
not a thin feature.

The values are shares of the shape's volume (trapezoid node weights); on a grid of spacing ``h``
the boundary is known to about ``h / 2``, so a feature within about a cell of the size is judged
by the grid.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

__all__ = ["opening", "opening_removed", "closing_added"]


def _padded(mask: np.ndarray, spacing: np.ndarray, r: float) -> tuple[np.ndarray, int]:
    pad = int(math.ceil(r / float(np.min(spacing)))) + 1
    return np.pad(mask, pad, mode="edge"), pad


def opening(mask: np.ndarray, spacing: np.ndarray, size: float) -> np.ndarray:
    """The morphological opening of the node mask ``mask (n_1, ..., n_d)`` by a ball of diameter
    ``size`` (world units; ``spacing (d,)`` between nodes along each axis), as a mask of the same
    shape (module docstring)."""
    r = 0.5 * float(size)
    big, pad = _padded(np.asarray(mask, dtype=bool), np.asarray(spacing, dtype=np.float64), r)
    if not big.any():
        return np.zeros_like(mask, dtype=bool)
    if big.all():
        return np.ones_like(mask, dtype=bool)
    depth = ndimage.distance_transform_edt(big, sampling=spacing)  # to the nearest node outside
    core = depth > r
    if not core.any():
        return np.zeros_like(mask, dtype=bool)
    reach = ndimage.distance_transform_edt(~core, sampling=spacing)  # to the nearest core node
    inner = tuple(slice(pad, -pad) for _ in range(big.ndim))
    return (reach <= r)[inner] & np.asarray(mask, dtype=bool)


def opening_removed(inside: np.ndarray, spacing: np.ndarray, size: float, weights: np.ndarray,
                    left_out: np.ndarray | None = None) -> float | None:
    """The share of the shape's volume (nodes ``inside``, trapezoid ``weights``) that the opening
    by a ball of diameter ``size`` removes: 0 when every part is at least ``size`` thick, 1 when
    none is (None for an empty shape). Removed nodes of the mask ``left_out`` are not counted."""
    total = float(weights[inside].sum(dtype=np.float64))
    if total <= 0:
        return None
    gone = inside & ~opening(inside, spacing, size)
    if left_out is not None:
        gone &= ~left_out
    return float(weights[gone].sum(dtype=np.float64)) / total


def closing_added(inside: np.ndarray, spacing: np.ndarray, size: float, weights: np.ndarray,
                  left_out: np.ndarray | None = None) -> float | None:
    """The volume the closing by a ball of diameter ``size`` adds to the shape (the void that the
    ball does not fit into), as a share of the shape's volume (None for an empty shape). Added
    nodes of the mask ``left_out`` are not counted."""
    total = float(weights[inside].sum(dtype=np.float64))
    if total <= 0:
        return None
    void = ~np.asarray(inside, dtype=bool)
    added = void & ~opening(void, spacing, size)
    if left_out is not None:
        added &= ~left_out
    return float(weights[added].sum(dtype=np.float64)) / total
