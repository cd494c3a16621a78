"""Topology subsystem: critical points, surface network, the topology losses on one grid base
(connectedness, hole counts), b0 and Betti numbers on grids.

Front door for the trainer::

    loss_fn = make_connectedness_loss(problem.domain, problem.design_region, config.connectedness,
                                      device=device, dtype=dtype)
    l = loss_fn(model, Z)          # scalar tensor; loss_fn.last_info holds diagnostics
    state = loss_fn.state_dict()   # tensors and numbers; load_state_dict(state) continues exactly

See docs/connectedness.md.
"""

from __future__ import annotations

import torch

from ..config import ConnectednessConfig
from ..geometry.base import Box, Region
from .base import ConnectednessLossBase, GridTopologyLoss
from .betti import betti_numbers, enclosed_components, mesh_genus
from .components import b0, b0_of_mask, component_sizes, count_components, field_on_grid
from .connectedness import ConnectednessLoss, SurfaceNetworkLossOptions
from .critical import (
    MAXIMUM,
    MINIMUM,
    SADDLE,
    CriticalPointOptions,
    CriticalPoints,
    find_critical_points,
    newton_refine,
)
from .penalties import Penalties, ShapeGraph, saddle_penalties, shape_components
from .persistent import DeathPoints, PersistenceOptions, PersistentHomologyLoss, death_points
from .surface_network import PathOptions, SurfaceNetwork, trace_surface_network


def make_connectedness_loss(
    domain: Box,
    design_region: Region | None,
    config: ConnectednessConfig,
    device=None,
    dtype=torch.float32,
    options=None,
    membership: Region | None = None,
) -> ConnectednessLossBase:
    """The connectedness loss selected by ``config.method``.

    Arguments:
        domain: the box X.
        design_region: the design region E, or None.
        config: :class:`ginn.config.ConnectednessConfig`.
        device, dtype: of the field.
        options: :class:`SurfaceNetworkLossOptions` or :class:`PersistenceOptions` (defaults
            when None).
        membership: ``design_region`` answering ``contains`` faster with the same answers (a
            :class:`ginn.geometry.lookup.RegionLookup` the caller already has), or None.

    Returns:
        a callable ``loss_fn(field, Z) -> scalar tensor`` with ``state_dict``,
        ``load_state_dict`` and ``last_info``.
    """
    if config.method == "surface-network":
        return ConnectednessLoss(domain, design_region, config, device, dtype, options, membership)
    if config.method == "persistent-homology":
        return PersistentHomologyLoss(domain, design_region, config, device, dtype, options)
    raise ValueError(f"unknown connectedness method {config.method!r}")


__all__ = [
    "make_connectedness_loss",
    "GridTopologyLoss",
    "ConnectednessLossBase",
    "ConnectednessLoss",
    "PersistentHomologyLoss",
    "SurfaceNetworkLossOptions",
    "PersistenceOptions",
    "CriticalPointOptions",
    "PathOptions",
    "CriticalPoints",
    "SurfaceNetwork",
    "Penalties",
    "ShapeGraph",
    "DeathPoints",
    "MINIMUM",
    "SADDLE",
    "MAXIMUM",
    "find_critical_points",
    "newton_refine",
    "trace_surface_network",
    "saddle_penalties",
    "shape_components",
    "death_points",
    "b0_of_mask",
    "component_sizes",
    "count_components",
    "field_on_grid",
    "b0",
    "betti_numbers",
    "mesh_genus",
    "enclosed_components",
]
