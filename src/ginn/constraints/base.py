"""The constraint protocol: one object per term of a shape problem.

A :class:`Constraint` states what it reads, how it turns one shared evaluation of the field into a
loss, and what it promises about the result:

* ``samples``: the :class:`~ginn.constraints.samples.SampleSet` s it reads; a step draws the sets
  its active constraints read, and evaluates them all in one batched pass
  (:class:`~ginn.constraints.batch.Batch`);
* ``stage``: when it is evaluated (:class:`Stage`: from the main pass, from the surface samples,
  or by evaluating the field at points of its own), which fixes the order of the passes through
  the network and so makes a step reproducible to the last bit;
* ``loss(batch)``: the unweighted scalar (``None``: no term this step, e.g. no samples);
* ``term(cfg)``: its weight and first iteration (``losses.<name>`` of the run's config);
* ``target()``: the loss value the problem's tolerance allows (``balancing.method: adaptive``);
* ``verdict``: the :class:`~ginn.constraints.verdict.Verdict` it enforces (the metric and bound
  that ``ginn eval`` and the checks during training judge), or None for an objective;
* ``state_dict`` / ``load_state_dict``: what a checkpoint keeps of it.

A new kind of constraint is a subclass in a module of its own; a task assembles a list of them
(:func:`ginn.constraints.shape_constraints`) and the trainer knows nothing of their kinds.
"""

from __future__ import annotations

import abc
import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import torch
from torch import Tensor

from ..config import LossTerm, RunConfig
from ..geometry.base import Region
from ..geometry.lookup import fastest_membership
from ..problems.derived import length_scale
from ..problems.problem import Problem

if TYPE_CHECKING:
    from .batch import Batch
    from .samples import SampleSet
    from .verdict import Verdict

__all__ = ["Stage", "Setting", "Constraint"]


class Stage(enum.IntEnum):
    """When a constraint is evaluated within a step (then in the order of the task's list)."""

    #: from the values and gradients of the main pass at its sample sets
    SAMPLES = 0
    #: may read the points on ``f = 0`` and the Hessians there (computed when first asked for)
    SURFACE = 1
    #: evaluates the field at points of its own (saddles, grid cells, surface samples outside E)
    FIELD = 2


@dataclass
class Setting:
    """What every constraint of one shape problem shares: the problem, the run's configuration,
    where tensors live, and the design region's fastest membership test.

    Attributes:
        problem: the geometry and tolerances.
        cfg: the resolved run configuration.
        device, dtype: of the samples and the stored state.
    """

    problem: Problem
    cfg: RunConfig
    device: torch.device
    dtype: torch.dtype
    _membership: Region | None = field(default=None, repr=False)

    @property
    def dim(self) -> int:
        return self.problem.dim

    @property
    def scale(self) -> float:
        """The problem's length scale (half the longest side of its domain)."""
        return length_scale(self.problem)

    @property
    def membership(self) -> Region | None:
        """The design region E, or its grid lookup where that answers ``contains`` faster with the
        same answers (:func:`ginn.geometry.lookup.fastest_membership`); None without E. Built at
        the first question and shared by the samplers, the containment term and the
        connectedness paths."""
        if self._membership is None and self.problem.design_region is not None:
            self._membership = fastest_membership(self.problem.design_region, self.problem.domain, device=self.device)
        return self._membership

    def half_tolerance(self) -> float:
        """``d``: half the interface tolerance in the problem's units (the field's value on an
        interface is its distance there only up to ``|grad f|``)."""
        return 0.5 * self.problem.tolerances.interface * self.problem.unit_scale


class Constraint(abc.ABC):
    """One term of a shape problem (see the module docstring).

    Arguments:
        setting: the problem, configuration, device and dtype the term works in.

    Subclasses set the class attributes ``name`` (the loss term's name, also its key in
    ``losses.<name>`` and in ``metrics.jsonl``), ``stage``, ``samples`` and, for a constraint of
    the verdict, ``verdict``.
    """

    name: ClassVar[str]
    stage: ClassVar[Stage] = Stage.SAMPLES
    samples: ClassVar[tuple[SampleSet, ...]] = ()
    #: an objective whose minimisers need not meet the constraints: under ``balancing.method:
    #: feasibility`` it acts in proportion to how closely the constraint terms meet their targets
    #: (:mod:`ginn.train.balancing`, "gated objective")
    gated: ClassVar[bool] = False

    def __init__(self, setting: Setting):
        self.setting = setting

    @property
    def verdict(self) -> Verdict | None:
        """The verdict this term enforces (None: an objective)."""
        return None

    def term(self, cfg: RunConfig) -> LossTerm:
        """Weight and first iteration: ``losses.<name>`` of ``cfg``."""
        return getattr(cfg.losses, self.name)

    @abc.abstractmethod
    def loss(self, batch: Batch) -> Tensor | None:
        """The unweighted scalar loss of this step, or None when there is nothing to measure."""

    def target(self) -> float | None:
        """The value of :meth:`loss` that the problem's tolerance allows (``balancing.method:
        adaptive`` holds the term at or below it); None: an objective."""
        return None

    def checked(self, ratios: Mapping[str, float | None]) -> None:
        """A feasibility check's verdict on the reported shapes: each constraint's worst value over
        its bound (:attr:`ginn.eval.results.FeasibilitySummary.ratios`). A term whose loss
        estimates a verdict's metric can calibrate itself on the verdict's measurement; most
        ignore it."""

    def state_dict(self) -> dict[str, Any]:
        """What a checkpoint keeps (tensors and plain data); empty for a stateless term."""
        return {}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"
