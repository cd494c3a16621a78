"""Attachment: the shape holds the nodes where its loads act and its interface supports hold it.

A load on nodes the shape leaves void pushes on the ersatz material (modulus 1e-6) and the
compliance is a million times that of a held load; a support the shape never reaches holds
nothing. The interface term cannot see this: ``f = 0`` on an interface at the domain's edge is met
just as well by a shape on the far side of it as by one that carries the load. So every node of
:func:`ginn.problems.structural.held_nodes` (the nodes of every load, and of every support placed
on interfaces) must touch a solid element of E.

The grids: a node is judged on two grids, the default element grid (the compliance's own, unless
``structural.cells`` sets another) and the report's (the default grid refined twice), and must be
held on both. The report's grid, whose element centres lie half as far from a node, catches a shape
rounded off at a pad's end: on the default grid alone two of the 16 cantilever shapes held its
elements with the field at ``-h / 4`` and left 4 of the report grid's 26 pad nodes on void. The
default grid catches a pad backed by a skin thinner than half its element: on the report's grid
alone 11 of the 16 shapes of a cantilever run held a pad by a wall about 0.006 thick between the
pad and a small hole behind it, so that the shapes thresholded on the default grid (as an
independent solver of that resolution would fill them) left pad nodes on void, with compliances
up to 150 times SIMP's (``python benchmarks/structural.py grids RUN``, ``docs/structural.md``).

Loss: over the held nodes of both grids and the shapes, the mean of ``relu(m + w / 2) / w``, ``m``
the smallest field value at the centres of the node's elements in E and ``w`` the step width of the
compliance's continuation (:mod:`ginn.constraints.compliance`) on the node's grid: from half the
design region's depth geometrically down to half an element side by half the run, then zero once
one of the elements is solid by a quarter element. Early on, while the wide step lets the
compliance itself reach the loads, the term pushes as gently as the step is wide; with the final
width from the first step it decided the half MBB beam's topology early (seed 0: compliance 164.3
against 147.0 without the term). With the sharp step of the late run the compliance has no
gradient at an element several elements from the boundary, so without the term a generative model
kept shapes whose boundary met a load pad from outside the domain.

Verdict (``attachment``): the share of the held nodes of both grids that no solid element
(``f <= 0`` at its centre) of E touches, ``unheld_nodes``, must be 0.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from torch import Tensor

from ..physics.grid import ElementGrid
from ..problems.derived import smallest_feature
from ..problems.problem import Problem
from ..problems.structural import held_elements, structural_grid, void_elements
from .base import Constraint, Setting, Stage
from .batch import Batch
from .compliance import continuation, narrowed, solid_elements, start_width
from .verdict import Verdict, Violation, number_text

__all__ = ["Attachment", "AttachmentVerdict", "POINTS", "attachment_grids"]

#: the key of the field values at the held nodes' element centres in a step
#: (:meth:`ginn.constraints.batch.Batch.field_at`)
POINTS = "attachment"


def attachment_grids(problem: Problem) -> tuple[ElementGrid, ElementGrid]:
    """The grids the held nodes are judged on: the default element grid and the report's (the
    default grid refined twice)."""
    base = structural_grid(problem, 0, smallest_feature(problem))
    return base, base.refined(2)


class AttachmentVerdict(Verdict):
    """Every held node touches the thresholded shape on both grids (module docstring)."""

    name = "attachment"

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("unheld_nodes",)
        self._grids: list | None = None

    def grids(self) -> list[tuple]:
        """``(grid, void, held)`` of each of :func:`attachment_grids`, built at the first use."""
        if self._grids is None:
            p = self.problem
            self._grids = [(g, void_elements(p, g), held_elements(p, g)) for g in attachment_grids(p)]
        return self._grids

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        unheld, total = 0, 0
        for grid, void, held in self.grids():
            if held.shape[0] == 0:
                continue
            solid = np.append(solid_elements(field, z, grid, void), False)  # index -1: no element
            unheld += int((~solid[held].any(axis=1)).sum())
            total += held.shape[0]
        return {"unheld_nodes": float(unheld / total) if total else None}

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
        points, elements, present, self.grid_of = [], [], [], []
        self.start_widths, self.final_widths = [], []
        n_points = 0
        for k, grid in enumerate(attachment_grids(p)):
            held = held_elements(p, grid)  # (n_held, 2^d), -1: none
            used = np.unique(held[held >= 0])
            points.append(grid.centres[used])
            elements.append(n_points + np.searchsorted(used, np.maximum(held, 0)))
            present.append(held >= 0)
            self.grid_of += [k] * held.shape[0]
            n_points += used.size
            self.final_widths.append(0.5 * float(grid.h.min()))
            self.start_widths.append(start_width(p, grid))
        self.points = torch.as_tensor(np.concatenate(points), dtype=setting.dtype, device=dev)  # (n_used, d)
        self.elements = torch.as_tensor(np.concatenate(elements), device=dev)  # (n_held, 2^d) into points
        self.present = torch.as_tensor(np.concatenate(present), device=dev)
        self.grid_of = torch.as_tensor(self.grid_of, device=dev)  # (n_held,) the node's grid
        self._verdict = AttachmentVerdict(p)

    def width(self, step: int, grid: int = 1) -> float:
        """``w`` at iteration ``step`` on attachment grid ``grid`` (0: the default, 1: the report's;
        module docstring)."""
        a = continuation(step, self.setting.cfg.training.iterations)
        return narrowed(self.start_widths[grid], self.final_widths[grid], a)

    @property
    def verdict(self) -> AttachmentVerdict:
        return self._verdict

    def loss(self, batch: Batch) -> Tensor | None:
        if self.elements.shape[0] == 0:
            return None
        f = batch.field_at(POINTS, self.points)  # (S, n_used)
        around = f[:, self.elements]  # (S, n_held, 2^d)
        m = torch.where(self.present, around, torch.full_like(around, torch.inf)).amin(dim=-1)  # (S, n_held)
        w = torch.tensor([self.width(batch.step, k) for k in range(len(self.final_widths))],
                         dtype=m.dtype, device=m.device)[self.grid_of]
        return (torch.relu(m + 0.5 * w) / w).mean()
