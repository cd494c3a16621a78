"""What the trainer trains: a task builds the model, returns its unweighted loss terms, and hands
the trainer its plug-ins; its :class:`Results` know what to do with a trained model.

The trainer is generic (optimiser, schedule, balancing, checkpoints, logging); a task knows its
problem. Built-in tasks live in :mod:`ginn.tasks`, one package per kind (one registry table maps
a kind to its class): shape problems, the parabolic mirror and the Gray-Scott generative PINN. A
new kind of task subclasses :class:`Task` and :class:`Results`.
"""

from __future__ import annotations

import abc
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import torch
from torch import Tensor, nn

from ..config import LossTerm, RunConfig
from ..errors import GinnError
from .balancing import Balance

if TYPE_CHECKING:
    from .callbacks import Callback
    from .distributed import DistContext

__all__ = ["Task", "Results", "Evaluation", "Metrics"]


class Evaluation(Protocol):
    """The metrics of a trained model: ``to_json()`` is what ``ginn eval`` writes to
    ``metrics.json``, ``text()`` what it prints."""

    def to_json(self) -> dict: ...

    def text(self) -> str: ...


class Metrics(dict):
    """An :class:`Evaluation` that is a plain dict of metrics (printed one per line)."""

    def to_json(self) -> dict:
        return dict(self)

    def text(self) -> str:
        return "\n".join(f"{k}: {v}" for k, v in self.items())


class Results(abc.ABC):
    """What a task does with a trained model: the result files of a run, ``ginn eval``,
    ``ginn export``, ``ginn plot`` and ``ginn view``. A kind implements those it supports."""

    kind: str = "task"

    def __init__(self, kind: str | None = None):
        if kind is not None:
            self.kind = kind

    def finalize(self, model: nn.Module, run_dir: Path) -> list[Path]:
        """Write the run's result files (shapes, figures) at the end of training; return their paths."""
        return []

    def evaluate(self, model: nn.Module, resolution: int | None = None, out_dir: Path | None = None) -> Evaluation:
        """The metrics of a trained model.

        Arguments:
            model: the trained model.
            resolution: grid resolution (None: the task's default).
            out_dir: the run directory, for tasks that write arrays beside the metrics.
        """
        raise GinnError(f"task kind {self.kind!r} has no evaluation")

    def export(self, model: nn.Module, latents: Tensor | list[list[float]] | None, out_dir: Path,
               resolution: int | None = None, mesh_format: str | None = None) -> list[Path]:
        """Meshes (3D) or contours (2D) of the model at ``latents`` (None: the trained ones) into
        ``out_dir``; returns the written paths."""
        raise GinnError(f"export works on shape runs; a {self.kind} run writes its results at the end of training")

    def plot(self, model: nn.Module, run_dir: Path, resolution: int | None = None) -> list[Path]:
        """The figures of a run (``ginn plot``); by default the result files of :meth:`finalize`."""
        return self.finalize(model, run_dir)

    def view(self, model: nn.Module, path: Path, steps: int = 64, title: str = "") -> Path:
        """The latent-space explorer of a trained model (``ginn view``): one HTML file at ``path``."""
        raise GinnError(f"ginn view has no view for a {self.kind} problem (`ginn plot` draws its figures)")


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

    @abc.abstractmethod
    def build_model(self) -> nn.Module:
        """A freshly initialised model (the trainer seeds torch before calling this)."""

    @abc.abstractmethod
    def terms(self) -> dict[str, LossTerm]:
        """Every loss term this task can produce, with its weight and start iteration."""

    @abc.abstractmethod
    def loss_terms(self, model: nn.Module, step: int, active: set[str], gen: torch.Generator) -> dict[str, Tensor]:
        """Unweighted scalar losses for the names in ``active`` (fresh samples from ``gen``); the
        balancer sums them in this order. A task may also return diagnostics whose names start
        with ``_`` (logged, not optimised)."""

    @property
    def results(self) -> Results:
        """The evaluation, export, figures and explorer of this kind (none by default)."""
        return Results(self.kind)

    def latents(self) -> Tensor | None:
        """Trained latent codes ``(S, k)``, or None for a single-shape model."""
        return None

    def state_dict(self) -> dict[str, Any]:
        """Persistent task state (e.g. critical points) saved in checkpoints: tensors and plain data."""
        return {}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""

    def distribute(self, ctx: DistContext) -> None:
        """Train only this rank's share under data parallelism (``ctx``: a
        :class:`ginn.train.distributed.DistContext`). Tasks that cannot be sharded refuse."""
        raise GinnError(f"task kind {self.kind!r} does not support distributed training")

    def balance(self) -> Balance:
        """The targets and verdict groups of the terms for the balancer (none by default: every
        term is an objective)."""
        return Balance()

    def callbacks(self, dist: DistContext | None = None) -> list[Callback]:
        """The task's plug-ins of the training loop (e.g. feasibility checks); none by default."""
        return []
