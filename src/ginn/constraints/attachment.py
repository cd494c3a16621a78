"""Attachment: the shape holds the nodes where its loads act and its interface supports hold it.

A load on nodes the shape leaves void pushes on the ersatz material (modulus 1e-6) and the
compliance is a million times that of a held load; a support the shape never reaches holds
nothing. The interface term cannot see this: ``f = 0`` on an interface at the domain's edge is met
just as well by a shape on the far side of it as by one that carries the load. So every node of
:func:`ginn.problems.structural.held_nodes` (the nodes of every load, and of every support placed
on interfaces) must touch a solid element of E.

Loss: over the held nodes and the shapes, the mean of ``relu(m + w / 2) / w``, ``m`` the smallest
field value at the centres of the node's elements in E and ``w`` the step width of the
compliance's continuation (:mod:`ginn.constraints.compliance`) on this grid: from half the design
region's depth geometrically down to half an element side by half the run, then zero once one of
the elements is solid by a quarter element. Early on, while the wide step lets the compliance
itself reach the loads, the term pushes as gently as the step is wide; with the final width from
the first step it decided the half MBB beam's topology early (seed 0: compliance 164.3 against
147.0 without the term). The nodes and elements are those of the verdict's
grid (below), so the term asks for what the verdict judges: on the training grid, whose element
centres lie twice as far from a node, a shape rounded off at a pad's end held the training grid's
elements and left the end nodes of the report grid on void (``docs/structural.md``). With the sharp
step of the late run the compliance has no gradient at an element several elements from the
boundary, so without the term a generative model kept shapes whose boundary met a load pad from
outside the domain.

Verdict (``attachment``): on the report's grid (the default element grid refined twice), the
share of the held nodes that no solid element (``f <= 0`` at its centre) of E touches,
``unheld_nodes``, must be 0.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from torch import Tensor

from ..problems.problem import Problem
from ..problems.structural import held_elements, void_elements
from .base import Constraint, Setting, Stage
from .batch import Batch
from .compliance import continuation, narrowed, report_grid, solid_elements, start_width
from .verdict import Verdict, Violation, number_text

__all__ = ["Attachment", "AttachmentVerdict", "POINTS"]

#: the key of the field values at the held nodes' element centres in a step
#: (:meth:`ginn.constraints.batch.Batch.field_at`)
POINTS = "attachment"


class AttachmentVerdict(Verdict):
    """Every held node touches the thresholded shape on the report's grid (module docstring)."""

    name = "attachment"

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("unheld_nodes",)
        self._grid: tuple | None = None

    def grid(self) -> tuple:
        """``(grid, void, held)`` of the report's grid, built at the first use."""
        if self._grid is None:
            grid = report_grid(self.problem)
            self._grid = (grid, void_elements(self.problem, grid), held_elements(self.problem, grid))
        return self._grid

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        grid, void, held = self.grid()
        if held.shape[0] == 0:
            return {"unheld_nodes": None}
        solid = np.append(solid_elements(field, z, grid, void), False)  # index -1: no element
        return {"unheld_nodes": float(1.0 - solid[held].any(axis=1).mean())}

    def violation(self, metrics: Mapping) -> Violation | None:
        v = metrics.get("unheld_nodes")
        return None if v is None or v <= 0 else Violation(float(v), 0.0)

    def ratio(self, metrics: Mapping) -> float | None:
        """0 when every node is held, else 1 plus the unheld share (above 1: violated)."""
        v = metrics.get("unheld_nodes")
        if v is None:
            return None
        return 0.0 if v <= 0 else 1.0 + float(v)

    @classmethod
    def describe(cls, v: Violation) -> str:
        return f"attachment: {number_text(v.value)} of the load and support nodes off the shape"


class Attachment(Constraint):
    """The held nodes touch solid elements (module docstring)."""

    name = "attachment"
    stage = Stage.FIELD

    def __init__(self, setting: Setting):
        super().__init__(setting)
        p, dev = setting.problem, setting.device
        grid = report_grid(p)
        held = held_elements(p, grid)  # (n_held, 2^d), -1: none
        used = np.unique(held[held >= 0])
        self.points = torch.as_tensor(grid.centres[used], dtype=setting.dtype, device=dev)  # (n_used, d)
        self.elements = torch.as_tensor(np.searchsorted(used, np.maximum(held, 0)), device=dev)  # into points
        self.present = torch.as_tensor(held >= 0, device=dev)
        self.final_width = 0.5 * float(grid.h.min())
        self.start_width = start_width(p, grid)
        self._verdict = AttachmentVerdict(p)

    def width(self, step: int) -> float:
        """``w`` at iteration ``step`` (module docstring)."""
        return narrowed(self.start_width, self.final_width, continuation(step, self.setting.cfg.training.iterations))

    @property
    def verdict(self) -> AttachmentVerdict:
        return self._verdict

    def loss(self, batch: Batch) -> Tensor | None:
        if self.elements.shape[0] == 0:
            return None
        f = batch.field_at(POINTS, self.points)  # (S, n_used)
        around = f[:, self.elements]  # (S, n_held, 2^d)
        m = torch.where(self.present, around, torch.full_like(around, torch.inf)).amin(dim=-1)
        w = self.width(batch.step)
        return torch.relu(m + 0.5 * w).mean() / w
