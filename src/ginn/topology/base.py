"""The interface both connectedness losses share (surface network and persistent homology)."""

from __future__ import annotations

import abc

import torch
from torch import Tensor

from ..config import ConnectednessConfig
from ..geometry.base import Box, Region


class ConnectednessLossBase(abc.ABC):
    """A connectedness loss for all shapes of a batch.

    Arguments:
        domain: the box X.
        design_region: the design region E, or None; ignored unless
            ``config.restrict_to_design_region``.
        config: the run's :class:`ginn.config.ConnectednessConfig`.
        device, dtype: of the points the loss stores (the field's).

    Call ``loss_fn(field, Z)`` with a field ``(x, z) -> (n,)`` and latents ``Z`` ``(S, k)`` or
    None; it returns a scalar tensor, differentiable with respect to the field's parameters. After
    each call ``last_info`` holds diagnostics (plain Python numbers). ``state_dict`` holds what a
    checkpoint must keep (tensors and plain data only).
    """

    def __init__(self, domain: Box, design_region: Region | None, config: ConnectednessConfig, device=None,
                 dtype: torch.dtype = torch.float32):
        self.domain = domain
        self.region = design_region if config.restrict_to_design_region else None
        self.config = config
        self.device = torch.device(device) if device is not None else torch.device("cpu")
        self.dtype = dtype
        self.last_info: dict = {}

    @abc.abstractmethod
    def __call__(self, field, Z: Tensor | None) -> Tensor:
        """The loss of every shape of the batch (mean over shapes), a scalar."""

    def state_dict(self) -> dict[str, Tensor]:
        """Persistent state (none by default)."""
        return {}

    def load_state_dict(self, state: dict[str, Tensor]) -> None:
        """Restore :meth:`state_dict`."""
        return None
