"""What the topology losses share: a node grid over the domain, the mask of its nodes outside the
design region E, a recompute schedule and a versioned state.

:class:`GridTopologyLoss` is the base of the connectedness losses (surface network and persistent
homology, :class:`ConnectednessLossBase`) and of the loss toward target hole counts
(:class:`ginn.topology.holes.HoleCountLoss`). The field of every shape is sampled on the grid in
one batched pass (:meth:`GridTopologyLoss.grid_values`); nodes outside E are given a value above
every field value, so that a shape never reaches them. A loss recomputes what it penalises every
``every`` calls (:meth:`GridTopologyLoss.due`) and penalises the same points in between. Its state
(:meth:`state_dict`) carries a ``format`` number; a checkpoint written by an older version is
brought to the current format in one step (:meth:`migrate`) before it is loaded.
"""

from __future__ import annotations

import abc
from typing import Any, ClassVar

import numpy as np
import torch
from torch import Tensor

from ..config import ConnectednessConfig
from ..extract.grid import node_grid
from ..geometry.base import Box, Region
from .components import field_on_grid

__all__ = ["GridTopologyLoss", "ConnectednessLossBase"]


class GridTopologyLoss(abc.ABC):
    """A loss on the topology of every shape of a batch, read off a node grid over the domain.

    Arguments:
        domain: the box X (the grid spans it).
        region: the design region E (nodes outside it are outside every shape), or None.
        resolution: grid nodes along the longest axis of the domain.
        device, dtype: of the points the loss stores (the field's).
        every: recompute what is penalised every this many calls.

    Call ``loss(field, Z)`` with a field ``(x, z) -> (n,)`` and latents ``Z (S, k)`` or None; it
    returns a scalar tensor, differentiable w.r.t. the field's parameters. ``last_info`` holds
    diagnostics of the last call (plain numbers).
    """

    #: the version of :meth:`state_dict`'s layout
    FORMAT: ClassVar[int] = 1

    def __init__(self, domain: Box, region: Region | None, resolution: int, device=None,
                 dtype: torch.dtype = torch.float32, every: int = 1):
        self.domain, self.region = domain, region
        self.resolution, self.every = int(resolution), max(1, int(every))
        self.device = torch.device(device) if device is not None else torch.device("cpu")
        self.dtype = dtype
        self.calls = 0
        self.last_info: dict = {}
        self._nodes: Tensor | None = None
        self._outside: np.ndarray | None = None

    # --- the grid --------------------------------------------------------------------------------

    @property
    def nodes(self) -> Tensor:
        """The grid's node positions ``(n_1, ..., n_d, d)``."""
        if self._nodes is None:
            grid = node_grid(self.domain, self.resolution)
            self._nodes = grid.tensor_points(self.device, self.dtype).reshape(*grid.shape, -1)
        return self._nodes

    @property
    def spacing(self) -> np.ndarray:
        """Node spacing per axis ``(d,)``."""
        grid = node_grid(self.domain, self.resolution)
        return np.array([(h - lo) / (n - 1) for lo, h, n in zip(self.domain.lo, self.domain.hi, grid.shape)])

    @property
    def outside(self) -> np.ndarray | None:
        """The nodes outside E ``(n_1, ..., n_d)`` (bool), or None without a region."""
        if self._outside is None and self.region is not None:
            pts = self.nodes.reshape(-1, self.domain.dim)
            self._outside = ~self.region.contains(pts).reshape(self.nodes.shape[:-1]).cpu().numpy().astype(bool)
        return self._outside

    def grid_values(self, field, Z: Tensor | None, resolution: int | None = None) -> tuple[np.ndarray, float | None]:
        """Every shape's field on the grid ``(S, n_1, ..., n_d)`` (NumPy, one batched pass), with
        the nodes outside E set to the returned value above every field value (None without E)."""
        vals, _, _ = field_on_grid(field, Z, self.domain, resolution or self.resolution, self.device, self.dtype)
        if self.outside is None:
            return vals, None
        top = float(np.abs(vals).max()) + 1.0
        vals = vals.copy()
        vals[:, self.outside] = top
        return vals, top

    def due(self) -> bool:
        """Whether this call recomputes (every ``every``-th call, from the first)."""
        return self.calls % self.every == 0

    # --- state -----------------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """Everything the next call depends on, as tensors and plain numbers (checkpoints stay
        pickle-free), with the layout's ``format``."""
        return {"format": self.FORMAT, **self._state()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`, of this version or an older one (:meth:`migrate`). The
        state may come from a checkpoint mapped to any device: :meth:`_load` receives it on the
        host (its arrays become NumPy, its tensors move to :attr:`device` where they are used)."""
        state = _on_host(state)
        if int(state.get("format", 1)) != self.FORMAT:
            state = self.migrate(state)
        self._load(state)

    def _state(self) -> dict[str, Any]:
        return {"calls": self.calls}

    def _load(self, state: dict[str, Any]) -> None:
        self.calls = int(state.get("calls", 0))

    def migrate(self, state: dict[str, Any]) -> dict[str, Any]:
        """A state of an older format in the current one (none is older here)."""
        raise ValueError(f"{type(self).__name__}: no migration from state format {state.get('format')!r}")

    @abc.abstractmethod
    def __call__(self, field, Z: Tensor | None) -> Tensor:
        """The loss of every shape of the batch (mean over shapes), a scalar."""


class ConnectednessLossBase(GridTopologyLoss):
    """A connectedness loss for all shapes of a batch.

    Arguments:
        domain: the box X.
        design_region: the design region E, or None; ignored unless
            ``config.restrict_to_design_region``.
        config: the run's :class:`ginn.config.ConnectednessConfig`.
        device, dtype: of the points the loss stores (the field's).
        resolution: nodes of its grid along the longest axis (None: ``config.grid``).
    """

    def __init__(self, domain: Box, design_region: Region | None, config: ConnectednessConfig, device=None,
                 dtype: torch.dtype = torch.float32, resolution: int | None = None):
        region = design_region if config.restrict_to_design_region else None
        super().__init__(domain, region, resolution or config.grid, device, dtype, every=config.every)
        self.config = config


def _on_host(value: Any) -> Any:
    """``value`` with every tensor in it (through dicts, lists and tuples) on the CPU."""
    if isinstance(value, torch.Tensor):
        return value.cpu()
    if isinstance(value, dict):
        return {k: _on_host(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_on_host(v) for v in value)
    return value
