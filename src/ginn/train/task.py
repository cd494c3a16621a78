"""What the trainer trains: a task builds the model and returns its unweighted loss terms.

The trainer is generic (optimiser, schedule, balancing, checkpoints, logging); a task knows its
problem. Built-in tasks: shape problems (:class:`ginn.train.shape_task.ShapeTask`), the parabolic
mirror and the Gray-Scott generative PINN. A new kind of task subclasses :class:`Task`.
"""

from __future__ import annotations

import abc
from pathlib import Path
from typing import Any

import torch
from torch import Tensor, nn

from .config import LossTerm, RunConfig


class Task(abc.ABC):
    """One training problem.

    Arguments:
        cfg: the resolved run configuration.
        device, dtype: where tensors live.
    """

    kind: str = "task"

    def __init__(self, cfg: RunConfig, device: torch.device, dtype: torch.dtype):
        self.cfg = cfg
        self.device = torch.device(device)
        self.dtype = dtype

    @abc.abstractmethod
    def build_model(self) -> nn.Module:
        """A freshly initialised model (the trainer seeds torch before calling this)."""

    @abc.abstractmethod
    def terms(self) -> dict[str, LossTerm]:
        """Every loss term this task can produce, with its weight and start iteration."""

    @abc.abstractmethod
    def loss_terms(self, model: nn.Module, step: int, active: set[str], gen: torch.Generator) -> dict[str, Tensor]:
        """Unweighted scalar losses for the names in ``active`` (fresh samples from ``gen``).

        A task may also return extra diagnostics whose names start with ``_`` (logged, not optimised).
        """

    def latents(self) -> Tensor | None:
        """Trained latent codes ``(S, k)``, or None for a single-shape model."""
        return None

    def state_dict(self) -> dict[str, Any]:
        """Persistent task state (e.g. critical points) saved in checkpoints: tensors and plain data."""
        return {}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        pass

    def finalize(self, model: nn.Module, run_dir: Path) -> list[Path]:
        """Write the run's result files (shapes, figures) and return their paths."""
        return []
