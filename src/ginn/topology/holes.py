"""Hole counts toward targets by cubical persistent homology (holes in 2D, tunnels and cavities in 3D).

The field of every shape is sampled on a vertex grid over the domain and its sublevel-set
filtration handed to ``cripser`` (``computePH(values, maxdim=d - 1)``, V-construction: the same
cells as :mod:`ginn.topology.persistent` and :func:`ginn.topology.betti_numbers`). A feature of
dimension ``k`` (``k = 1``: a hole in 2D, a tunnel in 3D; ``k = 2``: a cavity) is *born* at the
level ``b`` where it closes, at its birth cell, and *dies* at the level ``d`` where it fills, at
its death cell. The features of the shape ``{f <= 0}`` are those with ``b <= 0 < d``. Nodes outside
E get a value above every field value, so a hole round an obstacle (or any part of X \\ E) dies
only at that value: it can be opened but not filled.

For a target ``t_k`` and the ``n_k`` features alive at 0, with a margin ``m`` (one cell of the
grid: a feature must be wider than the grid to be seen, a gap too):

* **surplus** (``n_k > t_k``): the ``n_k - t_k`` features cheapest to remove go, each the cheaper
  way: *open* it (``f`` at the birth cell up to ``+m``: a change of ``m - b``) or *fill* it (``f``
  at the death cell down to ``-m``: ``d + m``; not for a death cell outside E);
* **missing** (``n_k < t_k``): among the features not alive at 0 whose persistence ``d - b``
  exceeds ``2 m`` (room for the margin on both sides), the ``t_k - n_k`` cheapest to bring to
  life: one born above 0 gets ``f`` at its birth cell down to ``-m``, one that died at or below 0
  gets ``f`` at its death cell up to ``+m``;
* **seeded** (holes in 2D, cavities in 3D, ``k = d - 1``): when the diagram offers fewer such
  features than are missing (a solid part has none: its field has no interior maximum), the rest
  are opened at the centres of the largest disjoint balls inscribed in ``{f <= -m}``: the deepest
  node, then the deepest node whose ball (radius ``-f``) is disjoint from the balls already chosen,
  and so on; ``f`` there goes up to ``+m`` (cost ``m - f``) and the nodes ``2 m`` to
  ``(2 + sqrt(d)) m`` from it go down to ``-m`` (:func:`ring_cells`): a hole of width about
  ``2 m`` in a wall a cell's diagonal thick, the most material round it, and where the part is
  thinner than that the wall thickens it instead of the raised node cutting it in two. A seed
  stays where it was put while its node is still inside the shape (``f < 0``) and its shape still
  misses features: the push makes that node shallower, so choosing the deepest node afresh at
  every recomputation would move the seed away from the dent it has started and no hole would
  ever open. A tunnel in 3D (``k = 1 < d - 1``) needs a passage through the part, not a point:
  every node on the line through the centre toward the nearest point outside the shape, both ways until
  ``f >= m``, goes up to ``+m`` (:func:`pierce_cells`; through a plate this is its normal, the
  shortest way through);
* **kept**: the other features alive at 0 are held with ``b <= -m`` and ``d >= m``.

Each move is a hinge on the field at a fixed cell centre (``relu(m - f(x))`` to raise,
``relu(f(x) + m)`` to lower), so the loss is zero once every shape has its target Betti numbers
with the margin; the batch loss is the sum of a shape's hinges, averaged over the shapes.

The persistence diagram is recomputed every ``every`` calls; in between the same cells are
penalised with the field's current values, each at the latent code of its shape at the last
recomputation (when the step's codes move, the cells belong to those codes); the grid, the nodes
outside E and the schedule are :class:`ginn.topology.base.GridTopologyLoss`'s.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from dataclasses import field as dataclass_field

import numpy as np
import torch
from torch import Tensor

from ..geometry.base import Box, Region
from .base import GridTopologyLoss
from .critical import latents_of

__all__ = ["FeatureMoves", "feature_moves", "seed_cells", "ring_cells", "pierce_cells", "HoleCountLoss"]


@dataclass
class FeatureMoves:
    """The cells one shape's field is pushed at, and which way.

    Attributes:
        index: grid indices of the cells ``(q, d)`` (int).
        raise_: ``(q,)`` bool, True: push ``f`` up to ``+m`` there; False: down to ``-m``.
        counts: the Betti numbers of ``{f <= 0}`` on the grid, ``{k: n_k}``.
        seeds: the seed centres opened, ``{k: (q_k, d)}`` grid indices (for the next recomputation).
    """

    index: np.ndarray
    raise_: np.ndarray
    counts: dict[int, int]
    seeds: dict[int, np.ndarray] = dataclass_field(default_factory=dict)


def _pairs(values: np.ndarray, maxdim: int) -> np.ndarray:
    import cripser

    return np.asarray(cripser.computePH(np.ascontiguousarray(values, dtype=np.float64), maxdim=maxdim))


def seed_cells(values: np.ndarray, count: int, margin: float, spacing: np.ndarray,
               keep: np.ndarray | None = None) -> np.ndarray:
    """Centres of up to ``count`` disjoint largest balls inscribed in ``{f <= -margin}``.

    Greedy: the deepest node (largest ``-f``) first, then the deepest node whose ball of radius
    ``-f`` does not meet the balls already chosen. ``-f`` is the depth for a distance-like field;
    nodes outside E (set above every field value) are never chosen.

    Arguments:
        values: grid values of one shape ``(n_1, ..., n_d)``.
        count: how many centres at most.
        margin: ``m``: a node must lie deeper than ``m``.
        spacing: node spacing per axis ``(d,)``.
        keep: earlier centres ``(p, d)``: those still inside the shape (``f < 0``) come first,
            the ones nearest to opening (highest ``f``) first, and the new balls avoid theirs.

    Returns:
        grid indices ``(q, d)``, ``q <= count``: the kept centres, then the new ones deepest first.
    """
    spacing = np.asarray(spacing, dtype=np.float64)
    kept = np.zeros((0, values.ndim), np.int64) if keep is None else np.asarray(keep, np.int64).reshape(-1, values.ndim)
    if len(kept):
        kept = kept[values[tuple(kept.T)] < 0.0]
        kept = kept[np.argsort(-values[tuple(kept.T)], kind="stable")][:max(count, 0)]
    depth = -values
    deep = depth > margin
    cells = np.argwhere(deep)
    r = depth[deep]
    pos = cells * spacing
    free = np.ones(len(r), dtype=bool)
    for c in kept:
        free &= np.linalg.norm(pos - c * spacing, axis=1) >= r - values[tuple(c)]
    chosen = list(kept)
    while len(chosen) < count and free.any():
        i = int(np.flatnonzero(free)[np.argmax(r[free])])
        chosen.append(cells[i])
        free &= np.linalg.norm(pos - pos[i], axis=1) >= r + r[i]
    return np.stack(chosen).astype(np.int64) if chosen else np.zeros((0, values.ndim), np.int64)


def ring_cells(shape: tuple[int, ...], centre: np.ndarray, margin: float, spacing: np.ndarray) -> np.ndarray:
    """The nodes at distance ``[2 m, (2 + sqrt(d)) m)`` from ``centre``: the wall a seeded hole
    (cavity) is given. Held at ``f <= -m`` while the centre goes to ``+m``, they make the seed a
    hole of width about ``2 m`` inside a wall, so that a seed in a part thinner than that thickens
    it round the hole instead of cutting it. A shell a cell's diagonal thick (``m`` is the largest
    spacing) closes in the grid: its nodes alone enclose the centre (a loop in 2D, a closed
    surface in 3D; one a cell thick leaves gaps in 3D).

    Arguments:
        shape: the grid's shape ``(n_1, ..., n_d)``; centre: a grid index ``(d,)``; margin: ``m``;
        spacing: node spacing per axis ``(d,)``.

    Returns:
        grid indices ``(q, d)`` inside the grid.
    """
    spacing = np.asarray(spacing, dtype=np.float64)
    outer = (2.0 + np.sqrt(len(shape))) * margin
    reach = np.ceil(outer / spacing).astype(np.int64)
    offsets = np.stack(np.meshgrid(*[np.arange(-r, r + 1) for r in reach], indexing="ij"), -1).reshape(-1, len(shape))
    dist = np.linalg.norm(offsets * spacing, axis=1)
    cells = np.asarray(centre, np.int64) + offsets[(dist >= 2.0 * margin) & (dist < outer)]
    return cells[((cells >= 0) & (cells < np.asarray(shape))).all(1)]


def pierce_cells(values: np.ndarray, centre: np.ndarray, margin: float, spacing: np.ndarray) -> np.ndarray:
    """The nodes of a straight passage through the part at ``centre``: along the line from the
    centre toward the nearest node outside the shape (``f > 0``), both ways, up to the first node
    on each side where ``f >= margin`` (or the edge of the grid).

    Arguments:
        values: grid values of one shape ``(n_1, ..., n_d)``; centre: a grid index ``(d,)``;
        margin: ``m``; spacing: node spacing per axis ``(d,)``.

    Returns:
        the distinct grid indices of the passage ``(q, d)`` (empty when no node lies outside).
    """
    spacing = np.asarray(spacing, dtype=np.float64)
    out = np.argwhere(values > 0)
    if len(out) == 0:
        return np.zeros((0, values.ndim), np.int64)
    c = np.asarray(centre, dtype=np.float64) * spacing
    gap = out * spacing - c
    n = gap[np.argmin((gap**2).sum(1))]
    n = n / np.linalg.norm(n)
    step = 0.5 * spacing.min()
    reach = float(np.linalg.norm((np.asarray(values.shape) - 1) * spacing))
    t = np.arange(0.0, reach + step, step)
    shape = np.asarray(values.shape)
    sides = []
    for sign in (1.0, -1.0):
        cells = np.rint((c + sign * t[:, None] * n) / spacing).astype(np.int64)
        inside = (cells >= 0).all(1) & (cells < shape).all(1)
        cells = cells[: int(np.argmin(inside)) if not inside.all() else len(cells)]
        stop = values[tuple(cells.T)] >= margin
        sides.append(cells[: int(np.argmax(stop)) if stop.any() else len(cells)])
    return np.unique(np.concatenate(sides), axis=0)


def feature_moves(values: np.ndarray, targets: dict[int, int], margin: float,
                  outside: np.ndarray | None = None, outside_value: float | None = None,
                  spacing: np.ndarray | None = None, seeds: dict[int, np.ndarray] | None = None) -> FeatureMoves:
    """The cells and directions of the module docstring for one shape.

    Arguments:
        values: grid values of one shape, 2D or 3D, with the nodes outside E already set to
            ``outside_value`` (above every field value).
        targets: ``{k: t_k}`` for ``k`` in 1..d-1.
        margin: ``m``, in the units of ``values``.
        outside: boolean grid of the nodes outside E (their cells cannot be moved), or None.
        outside_value: the value given to those nodes.
        spacing: node spacing per axis ``(d,)`` (for the seeds' distances; None: ``m`` on every axis).
        seeds: the seed centres of the previous recomputation, ``{k: (p, d)}`` (:attr:`FeatureMoves.seeds`).
    """
    d = values.ndim
    spacing = np.full(d, margin) if spacing is None else np.asarray(spacing, dtype=np.float64)
    ph = _pairs(values, max(targets)) if targets else np.zeros((0, 9))
    idx: list[np.ndarray] = []
    up: list[bool] = []
    counts: dict[int, int] = {}
    used: dict[int, np.ndarray] = {}

    def movable(cell: np.ndarray) -> bool:
        return outside is None or not bool(outside[tuple(cell)])

    def push(cell: np.ndarray, raise_: bool):
        if movable(cell):
            idx.append(cell)
            up.append(raise_)

    for k, target in sorted(targets.items()):
        rows = ph[ph[:, 0] == k] if ph.size else ph
        birth, death = rows[:, 1], rows[:, 2]
        bcell = rows[:, 3:3 + d].astype(np.int64)
        dcell = rows[:, 6:6 + d].astype(np.int64)
        fillable = np.ones(len(rows), dtype=bool)
        if outside is not None and len(rows):
            fillable &= ~outside[tuple(dcell.T)]
        if outside_value is not None:
            fillable &= death < outside_value
        alive = (birth <= 0.0) & (death > 0.0)
        counts[k] = int(alive.sum())
        live = np.flatnonzero(alive)
        # the cost of removing each live feature: open (birth up to +m) or fill (death down to -m)
        open_cost = margin - birth[live]
        fill_cost = np.where(fillable[live], death[live] + margin, np.inf)
        ranked = np.argsort(np.minimum(open_cost, fill_cost), kind="stable")  # positions in live
        surplus = max(0, len(live) - target)
        for j, pos in enumerate(ranked):
            i = live[pos]
            if j < surplus:  # the cheapest to remove
                fill = fill_cost[pos] < open_cost[pos]
                push(dcell[i] if fill else bcell[i], raise_=not fill)
            else:  # kept: hold the margin on both sides
                if birth[i] > -margin:
                    push(bcell[i], raise_=False)
                if fillable[i] and death[i] < margin:
                    push(dcell[i], raise_=True)
        missing = max(0, target - len(live))
        if missing:
            cand = np.flatnonzero(~alive & (death - birth > 2.0 * margin) & (death < np.finfo(np.float64).max / 2))
            # born above 0: lower the birth cell (cost b + m); died at or below 0: raise the death cell (m - d)
            born_late = birth[cand] > 0.0
            cost = np.where(born_late, birth[cand] + margin, np.where(fillable[cand], margin - death[cand], np.inf))
            for i, late, c in sorted(zip(cand, born_late, cost), key=lambda t: t[2])[:missing]:
                if np.isfinite(c):
                    push(bcell[i] if late else dcell[i], raise_=not late)
                    missing -= 1
            used[k] = seed_cells(values, missing, margin, spacing, (seeds or {}).get(k))
            for cell in used[k]:
                if k == d - 1:
                    push(cell, raise_=True)
                    for c in ring_cells(values.shape, cell, margin, spacing):
                        push(c, raise_=False)
                else:
                    for c in pierce_cells(values, cell, margin, spacing):
                        push(c, raise_=True)
    index = np.stack(idx).astype(np.int64) if idx else np.zeros((0, d), np.int64)
    return FeatureMoves(index, np.asarray(up, dtype=bool), counts, used)


class HoleCountLoss(GridTopologyLoss):
    """The loss of the module docstring for all shapes of a batch.

    Arguments:
        domain: the box X (the grid spans it).
        design_region: E (nodes outside it are outside every shape), or None.
        targets: ``{k: t_k}``, ``k`` in 1..d-1 (:attr:`ginn.problems.problem.Topology.targets`).
        resolution: grid nodes along the longest axis.
        every: recompute the persistence diagram every this many calls.
        device, dtype: of the grid points.

    Call ``loss(field, Z)`` with ``Z (S, k)`` or None; returns a scalar. ``last_info`` holds the
    Betti numbers of the last recomputation (``counts``: one dict per shape) and the number of
    penalised cells.
    """

    def __init__(self, domain: Box, design_region: Region | None, targets: dict[int, int], resolution: int = 64,
                 every: int = 1, device=None, dtype=torch.float32):
        super().__init__(domain, design_region, resolution, device, dtype, every)
        self.targets = dict(targets)
        self.margin = float(self.spacing.max())
        self._cells: tuple[Tensor, Tensor, Tensor] | None = None  # points (q, d), shape index (q,), sign (q,)
        self._seeds: list[dict[int, np.ndarray]] = []  # per shape: the seed centres in use, {k: (q, d)}
        self._held: Tensor | None = None  # the codes of the last recomputation (the cells belong to them)

    def _state(self) -> dict:
        cells = None if self._cells is None else [t.cpu() for t in self._cells]
        seeds = [{int(k): v.tolist() for k, v in sd.items()} for sd in self._seeds]
        held = None if self._held is None else self._held.detach().cpu()
        return {"calls": self.calls, "cells": cells, "seeds": seeds, "latents": held}

    def _load(self, state: dict) -> None:
        self.calls = int(state.get("calls", 0))
        cells = state.get("cells")
        self._cells = None if cells is None else tuple(t.to(self.device) for t in cells)
        d = self.domain.dim
        self._seeds = [{int(k): np.asarray(v, np.int64).reshape(-1, d) for k, v in sd.items()}
                       for sd in state.get("seeds", [])]
        held = state.get("latents")
        self._held = None if held is None else held.to(self.device, self.dtype)

    def _recompute(self, field, Z: Tensor | None) -> None:
        S = 1 if Z is None else int(Z.shape[0])
        Zd = None if Z is None else Z.detach().to(self.device, self.dtype)
        self._held = Zd
        vals, top = self.grid_values(field, Zd)
        xs, ss, signs, counts = [], [], [], []
        previous = self._seeds if len(self._seeds) == S else [{} for _ in range(S)]
        self._seeds = []
        for s in range(S):
            mv = feature_moves(vals[s], self.targets, self.margin, self.outside, top, self.spacing, previous[s])
            counts.append(mv.counts)
            self._seeds.append(mv.seeds)
            if len(mv.index):
                xs.append(self.nodes[tuple(torch.from_numpy(mv.index).T)])
                ss.append(torch.full((len(mv.index),), s, dtype=torch.long))
                signs.append(torch.from_numpy(np.where(mv.raise_, 1.0, -1.0)))
        if xs:
            self._cells = (torch.cat(xs), torch.cat(ss).to(self.device), torch.cat(signs).to(self.device))
        else:
            self._cells = (self.nodes.reshape(-1, self.domain.dim)[:0], torch.zeros(0, dtype=torch.long, device=self.device),
                           torch.zeros(0, device=self.device, dtype=torch.float64))
        self.last_info = {"counts": counts}

    def __call__(self, field, Z: Tensor | None) -> Tensor:
        t0 = time.perf_counter()
        S = 1 if Z is None else int(Z.shape[0])
        if self._held is None and Z is not None and self._cells is not None:  # a state without its codes
            self._held = Z.detach().to(self.device, self.dtype)
        if self._cells is None or self.due() or (Z is not None and self._held.shape != Z.shape):
            self._recompute(field, Z)
        self.calls += 1
        x, sh, sign = self._cells
        # the cells belong to the codes of the last recomputation: judged there until the next one
        f = field(x.detach(), latents_of(None if Z is None else self._held.to(Z.dtype), sh))
        sign = sign.to(device=f.device, dtype=f.dtype)
        # raise (sign +1): relu(m - f); lower (sign -1): relu(f + m)
        loss = torch.relu(self.margin - sign * f).sum() / S
        self.last_info.update({"time": time.perf_counter() - t0, "n_penalised": int(len(sign))})
        return loss
