"""The connectedness constraint: every shape is one piece inside E that reaches every interface.

Loss: the surface-network loss of Appendix C (or its cubical persistent-homology alternative,
``connectedness.method``; :mod:`ginn.topology`), which lowers the field at the saddles that
separate the pieces. With ``connectedness.margin`` it sees the shape ``{f <= -margin}``, so that
connections thinner than about twice the margin count as gaps. Its critical points and surface
network persist across steps and in checkpoints.

Verdict (``tolerances.connected``, the default): ``b0_in_design_region == 1`` and
``connected_interfaces_share == 1``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from torch import Tensor

from .. import fields
from ..problems.problem import Problem
from ..topology import ConnectednessLossBase, make_connectedness_loss
from .base import Constraint, Setting, Stage
from .batch import Batch
from .verdict import Verdict, Violation

__all__ = ["Connectedness", "Connected"]


class Connected(Verdict):
    """One piece inside E reaching every interface component."""

    name = "connected"

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("b0_in_design_region", "connected_interfaces_share")

    def violation(self, metrics: Mapping) -> Violation | None:
        pieces = metrics.get("b0_in_design_region")
        share = metrics.get("connected_interfaces_share")
        if pieces == 1 and (share is None or share >= 1.0 - 1e-12):
            return None
        return Violation(int(pieces) if pieces is not None else 0, 1, None if share is None else float(share))

    def ratio(self, metrics: Mapping) -> float:
        """The number of pieces inside E, or the inverse share of interface components its pieces
        reach if that is larger (1 when met; no piece: ``inf``)."""
        pieces = metrics.get("b0_in_design_region")
        share = metrics.get("connected_interfaces_share")
        if not pieces:
            return math.inf
        missed = 1.0 / share if share is not None and share > 0 else (math.inf if share is not None else 1.0)
        return max(float(pieces), missed)

    @classmethod
    def describe(cls, v: Violation) -> str:
        text = f"connected: {v.value} piece{'' if v.value == 1 else 's'} inside E"
        if v.interfaces is not None and v.interfaces < 1:
            text += f", {100 * v.interfaces:.0f} % of the interfaces reached by one piece"
        return text


class Connectedness(Constraint):
    """One piece (see the module docstring); the loss object is built at its first use."""

    name = "connectedness"
    stage = Stage.FIELD

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = Connected(setting.problem) if setting.problem.tolerances.connected else None
        self._fn: ConnectednessLossBase | None = None

    @property
    def verdict(self) -> Connected | None:
        return self._verdict

    @property
    def fn(self) -> ConnectednessLossBase:
        """The loss object of ``connectedness.method`` (:func:`ginn.topology.make_connectedness_loss`)."""
        if self._fn is None:
            s = self.setting
            restrict = s.cfg.connectedness.restrict_to_design_region
            self._fn = make_connectedness_loss(s.problem.domain, s.problem.design_region if restrict else None,
                                               s.cfg.connectedness, s.device, s.dtype,
                                               membership=s.membership if restrict else None)
        return self._fn

    def loss(self, batch: Batch) -> Tensor:
        margin = self.setting.cfg.connectedness.margin
        field = batch.model if margin == 0 else fields.Shifted(batch.model, margin)
        return self.fn(field, batch.Z)

    def target(self) -> float | None:
        """0 (no penalised saddle) where the problem must be connected."""
        return 0.0 if self._verdict is not None else None

    def state_dict(self) -> dict:
        return self._fn.state_dict() if self._fn is not None else {}

    def load_state_dict(self, state: dict) -> None:
        if state:
            self.fn.load_state_dict(state)
