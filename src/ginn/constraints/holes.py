"""Hole targets: the Betti numbers the spec's ``topology:`` states (holes in 2D, tunnels and
cavities in 3D), by cubical persistent homology (:class:`ginn.topology.holes.HoleCountLoss`).

The loss term is ``topology`` (``losses.topology``). Verdict: ``b1_in_design_region`` and
``b2_in_design_region`` equal to the targets.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from torch import Tensor

from ..problems.problem import Problem
from ..topology.holes import HoleCountLoss
from .base import Constraint, Setting, Stage
from .batch import Batch
from .verdict import Verdict, Violation

__all__ = ["HoleTargets", "TopologyTargets", "BETTI_METRICS"]

#: The metric of each target Betti number.
BETTI_METRICS = {1: "b1_in_design_region", 2: "b2_in_design_region"}


def betti_names(dim: int) -> dict[int, str]:
    """What a Betti number counts in ``dim`` dimensions: ``{1: holes}`` or ``{1: tunnels, 2: cavities}``."""
    return {1: "holes"} if dim == 2 else {1: "tunnels", 2: "cavities"}


class TopologyTargets(Verdict):
    """Every target Betti number met."""

    name = "topology"

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = tuple(BETTI_METRICS[k] for k in sorted(problem.topology.targets))

    def _off(self, metrics: Mapping) -> dict[str, tuple[int | None, int]]:
        """``{name: (measured, target)}`` for each target the shape misses."""
        names = betti_names(self.problem.dim)
        out = {}
        for k, target in sorted(self.problem.topology.targets.items()):
            got = metrics.get(BETTI_METRICS[k])
            if got is None or int(got) != target:
                out[names[k]] = (None if got is None else int(got), target)
        return out

    def violation(self, metrics: Mapping) -> Violation | None:
        off = self._off(metrics)
        if not off:
            return None
        return Violation({k: v[0] for k, v in off.items()}, {k: v[1] for k, v in off.items()})

    def ratio(self, metrics: Mapping) -> float:
        """1 plus the total miss of the targets (``inf`` where a count is undefined)."""
        off = self._off(metrics).values()
        return math.inf if any(g is None for g, _ in off) else 1.0 + sum(abs(g - t) for g, t in off)

    @classmethod
    def describe(cls, v: Violation) -> str:
        singular = {"holes": "hole", "tunnels": "tunnel", "cavities": "cavity"}
        return "topology: " + ", ".join(
            f"{n if n is not None else 'undefined'} {singular[k] if n == 1 else k} (want {v.bound[k]})"
            for k, n in v.value.items())


class HoleTargets(Constraint):
    """Toward the target Betti numbers (see the module docstring); the loss object is built at
    its first use."""

    name = "topology"
    stage = Stage.FIELD

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = TopologyTargets(setting.problem)
        self._fn: HoleCountLoss | None = None

    @property
    def verdict(self) -> TopologyTargets:
        return self._verdict

    @property
    def fn(self) -> HoleCountLoss:
        if self._fn is None:
            s, t = self.setting, self.setting.cfg.topology
            self._fn = HoleCountLoss(s.problem.domain, s.problem.design_region, s.problem.topology.targets,
                                     t.grid, t.every, s.device, s.dtype)
        return self._fn

    def loss(self, batch: Batch) -> Tensor:
        return self.fn(batch.model, batch.Z)

    def state_dict(self) -> dict:
        return self._fn.state_dict() if self._fn is not None else {}

    def load_state_dict(self, state: dict) -> None:
        if state:
            self.fn.load_state_dict(state)
