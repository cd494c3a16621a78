"""What the trainer trains: a task builds the model, returns its unweighted loss terms, and knows
how to evaluate, export and draw what it trained.

The trainer is generic (optimiser, schedule, balancing, checkpoints, logging); a task knows its
problem. Built-in tasks live in :mod:`ginn.tasks` (one registry table maps a kind to its class):
shape problems, the parabolic mirror and the Gray-Scott generative PINN. A new kind of task
subclasses :class:`Task`.
"""

from __future__ import annotations

import abc
from pathlib import Path
from typing import Any

import torch
from torch import Tensor, nn

from ..config import LossTerm, RunConfig
from ..errors import GinnError


class Task(abc.ABC):
    """One training problem.

    Arguments:
        cfg: the resolved run configuration.
        device, dtype: where tensors live.
    """

    kind: str = "task"

    def __init__(self, cfg: RunConfig, device: torch.device | str, dtype: torch.dtype):
        self.cfg = cfg
        self.device = torch.device(device)
        self.dtype = dtype

    @classmethod
    def from_spec(cls, spec, cfg: RunConfig) -> Task:
        """The task of a loaded problem spec (a :class:`ginn.problems.ProblemSpec`) under ``cfg``;
        tasks without geometry need only the config."""
        return cls(cfg, cfg.device, cfg.torch_dtype)

    # --- training --------------------------------------------------------------------------------

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
        """Restore :meth:`state_dict`."""

    def distribute(self, ctx) -> None:
        """Train only this rank's share under data parallelism (``ctx``: a
        :class:`ginn.train.distributed.DistContext`). Tasks that cannot be sharded refuse."""
        raise GinnError(f"task kind {self.kind!r} does not support distributed training")

    # --- results -----------------------------------------------------------------------------------

    def constraint_targets(self) -> dict[str, float]:
        """``{term: eps}``: the loss terms that are constraints ``term <= eps`` under
        ``balancing.method: adaptive`` (the rest are objectives); none by default."""
        return {}

    def constraint_terms(self) -> dict[str, tuple[str, ...]]:
        """``{constraint: (term, ...)}``: the loss terms that enforce each constraint of the
        feasibility verdict (``balancing.method: feasibility``); none by default."""
        return {}

    def bounded_objectives(self) -> tuple[str, ...]:
        """The constraints of :meth:`constraint_terms` that bound an objective from below (a
        minimum diversity): their multipliers also fall while the bound is met; none by default."""
        return ()

    def feasibility(self, model: nn.Module) -> dict | None:
        """Which shapes meet the problem's tolerances now (a cheap coarse-grid check;
        :func:`ginn.eval.feasibility.summarize`), or None for tasks without tolerances."""
        return None

    def finalize(self, model: nn.Module, run_dir: Path) -> list[Path]:
        """Write the run's result files (shapes, figures) at the end of training; return their paths."""
        return []

    def evaluate(self, model: nn.Module, resolution: int | None = None, out_dir: Path | None = None) -> dict:
        """The metrics of a trained model (what ``ginn eval`` writes to ``metrics.json``).

        Arguments:
            model: the trained model.
            resolution: grid resolution (None: the task's default).
            out_dir: the run directory, for tasks that write arrays beside the metrics.
        """
        raise GinnError(f"task kind {self.kind!r} has no evaluation")

    def format_metrics(self, metrics: dict) -> str:
        """A readable text of :meth:`evaluate`'s result for the terminal."""
        return "\n".join(f"{k}: {v}" for k, v in metrics.items())

    def export(self, model: nn.Module, latents: Tensor | list[list[float]] | None, out_dir: Path,
               resolution: int | None = None, mesh_format: str | None = None) -> list[Path]:
        """Meshes (3D) or contours (2D) of the model at ``latents`` (None: the trained ones) into
        ``out_dir``; returns the written paths."""
        raise GinnError(f"export works on shape runs; a {self.kind} run writes its results at the end of training")

    def plot(self, model: nn.Module, run_dir: Path, resolution: int | None = None) -> list[Path]:
        """The figures of a run (``ginn plot``); by default the result files of :meth:`finalize`."""
        return self.finalize(model, run_dir)
