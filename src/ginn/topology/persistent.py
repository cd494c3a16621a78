"""Connectedness by 0-dimensional cubical persistent homology (the alternative to Appendix C).

For every shape the field is sampled on a vertex grid over the domain (one batched forward pass,
no derivatives) and the sublevel-set filtration of that grid is handed to ``cripser``
(``computePH(values, maxdim=0)``; V-construction: grid nodes are the 0-cells, face neighbours
are joined by 1-cells, so components are counted with face connectivity, as in
:mod:`ginn.topology.components`). Each row of its output is
``(dim, birth, death, birth coordinates (3), death coordinates (3))`` in array indices.

The components of ``{f <= 0}`` are the pairs with ``birth <= 0 < death``; one of them is the
essential class (``death`` infinite). Each of the others dies at a grid node whose value is the
level at which it merges with an older component: the discrete analogue of the saddle that
separates it from the rest. The loss pushes ``f`` down at those *death points*:

``loss = sum_k p_k f(x_k)``, ``p_k ∝ 1 / (2 f_k + eps)`` normalised to sum 1 per shape, where
``f_k`` is the death value (``2 f_k`` is the gap between the two components for an SDF, the same
``d`` as in the surface-network loss), and ``x_k`` (the death node, optionally refined by a few
Newton steps to the continuous saddle) is held fixed. The batch loss is the mean over shapes.

With a design region (``restrict_to_design_region``), nodes outside it are given a value above
the grid maximum so they never join the shape (:meth:`ginn.topology.base.GridTopologyLoss.grid_values`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from ..geometry.base import Box, Region
from .base import ConnectednessLossBase
from .critical import cell_size, latents_of, newton_refine


@dataclass(frozen=True)
class PersistenceOptions:
    """Settings of :class:`PersistentHomologyLoss`.

    Attributes:
        resolution: grid nodes along the longest axis (None: ``config.grid``).
        refine_steps: Newton steps moving each death node to the nearby continuous saddle
            (0: penalise the grid node itself).
    """

    resolution: int | None = None
    refine_steps: int = 0


@dataclass
class DeathPoints:
    """The merge events of the components of ``{f <= 0}`` of one shape.

    Attributes:
        index: grid indices of the death nodes ``(q, d)`` (int).
        value: death values ``(q,)`` (the grid values there, all > 0).
        birth: birth values of the dying components ``(q,)`` (all <= 0).
        n_components: b0 of ``{f <= 0}`` on the grid (= q + 1, or 0 for an empty shape).
    """

    index: np.ndarray
    value: np.ndarray
    birth: np.ndarray
    n_components: int


def death_points(values: np.ndarray, level: float = 0.0) -> DeathPoints:
    """Death nodes of the components of ``{values <= level}`` beyond the first (cripser).

    Arguments:
        values: grid values of one shape, 2D or 3D.
        level: the iso-level.

    Returns:
        :class:`DeathPoints`.
    """
    import cripser

    d = values.ndim
    ph = np.asarray(cripser.computePH(np.ascontiguousarray(values, dtype=np.float64), maxdim=0))
    if ph.size == 0:
        return DeathPoints(np.zeros((0, d), np.int64), np.zeros(0), np.zeros(0), 0)
    ph = ph[ph[:, 0] == 0]
    birth, death = ph[:, 1], ph[:, 2]
    alive = (birth <= level) & (death > level)
    finite = death < np.finfo(np.float64).max / 2
    dying = alive & finite
    idx = ph[dying][:, 6 : 6 + d].astype(np.int64)
    return DeathPoints(idx, death[dying], birth[dying], int(alive.sum()))


class PersistentHomologyLoss(ConnectednessLossBase):
    """Cubical-PH connectedness loss for all shapes of a batch (see :class:`ConnectednessLossBase`).

    Arguments:
        domain, design_region, config, device, dtype: see :class:`ConnectednessLossBase` (uses
            ``config.grid``, ``config.eps``, ``config.restrict_to_design_region``).
        options: :class:`PersistenceOptions`.
    """

    def __init__(
        self,
        domain: Box,
        design_region: Region | None,
        config,
        device=None,
        dtype=torch.float32,
        options: PersistenceOptions | None = None,
    ):
        options = options or PersistenceOptions()
        super().__init__(domain, design_region, config, device, dtype, resolution=options.resolution)
        self.options = options
        self.last_points: tuple[Tensor, Tensor, Tensor] | None = None

    def __call__(self, field, Z: Tensor | None) -> Tensor:
        t0 = time.perf_counter()
        S = 1 if Z is None else int(Z.shape[0])
        Zd = None if Z is None else Z.detach().to(self.device, self.dtype)
        vals, _ = self.grid_values(field, Zd)
        self.calls += 1
        xs, ss, ps, comps = [], [], [], []
        for s in range(S):
            dp = death_points(vals[s])
            comps.append(dp.n_components)
            if len(dp.value) == 0:
                continue
            w = 1.0 / (2.0 * dp.value + self.config.eps)
            xs.append(self.nodes[tuple(torch.from_numpy(dp.index).T)])
            ss.append(torch.full((len(w),), s, dtype=torch.long))
            ps.append(w / w.sum())
        if xs:
            x = torch.cat(xs).to(self.device)
            sh = torch.cat(ss).to(self.device)
            p = torch.from_numpy(np.concatenate(ps))
            if self.options.refine_steps > 0:
                h = cell_size(self.domain, self.resolution)
                r = newton_refine(
                    field, x, latents_of(Zd, sh), self.domain, steps=self.options.refine_steps,
                    tol=1e-6, max_step=h, min_step=1e-4 * h,
                )
                x = torch.where(r.converged[:, None], r.x, x)
        else:
            x = self.nodes.reshape(-1, self.domain.dim)[:0]
            sh = torch.zeros(0, dtype=torch.long, device=self.device)
            p = torch.zeros(0, dtype=torch.float64)
        f = field(x.detach(), latents_of(Z, sh))
        p = p.to(device=f.device, dtype=f.dtype)
        loss = (p * f).sum() / S
        self.last_points = (x.detach(), sh, p.detach())
        self.last_info = {
            "time": time.perf_counter() - t0,
            "update": "full",
            "n_components": comps,
            "n_disconnected_shapes": int(sum(c > 1 for c in comps)),
            "n_penalised": int(len(p)),
        }
        return loss
