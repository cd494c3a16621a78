"""Attachment: the shape holds the nodes where its loads act and its interface supports hold it.

A load on nodes the shape leaves void pushes on the ersatz material (modulus 1e-6) and the
compliance is a million times that of a held load; a support the shape never reaches holds
nothing. The interface term cannot see this: ``f = 0`` on an interface at the domain's edge is met
just as well by a shape on the far side of it as by one that carries the load. So every node of
:func:`ginn.problems.structural.held_nodes` (the nodes of every load, and of every support placed
on interfaces) must touch a solid element of E, at four depths:

* on the report's grid (the default element grid refined twice): one of the node's elements in E
  solid at its centre, half a report element from the node along each axis. On the default grid
  alone, whose centres lie twice as far from a node, a shape rounded off at a pad's end held the
  default grid's elements and left the end nodes of the report grid on void;
* at the default grid's depth: one of the elements of the default grid's size with a corner at
  the node (:func:`ginn.problems.structural.held_corners`) that lie in E solid at its centre, half
  a default element from the node along each axis. On the report's grid alone a pad backed by a
  wall a third of a default element thick, in front of a small hole, was held, and a solver of
  the default grid's resolution that fills its elements by their centres left the pad's nodes on
  void (``docs/structural.md``, "On other grids");
* at the depths of grids two and four times as fine as the report's: one of the elements of that
  size with a corner at the node solid at its centre, a quarter and an eighth of a report element
  from the node. Held at the report's and the default's depths alone, a pad whose boundary was
  rounded off at its end (the field a report element's worth positive at the end node) or ran a
  little inside the pad left those nodes on void on a grid twice as fine as the report's.

A depth with no element of that size in E at the node falls back on the report's elements. A
point beyond a held interface (on the side its prescribed normals point to, where the shape must be
void: inside a bolt hole whose rim is the interface) counts as outside E
(:func:`ginn.problems.structural.held_corners`): the held nodes lie on the shape's side of such an
interface, but a node near the rim has some of its finer depths' points inside the hole, and asking
them for material pulled the shape into it against the interface term (a hub whose disk E does not
cut its bolt holes out ended with nodes there unheld).

Loss: over the held nodes, the depths and the shapes, the mean of ``relu(m + a w / 2) / w``, ``m``
the smallest field value at the centres of the node's elements at that depth, ``a`` 1 at the
report's and the default grid's depths and the depth over the report's depth (1/2, 1/4) at the
finer ones, so that a boundary through the node at a right angle meets the finer depths as it meets
the report's, and ``w`` the step width of the compliance's continuation
(:mod:`ginn.constraints.compliance`) on the report's grid: from half the design region's depth
geometrically down to half a report element side by half the run; from then on zero at the report's
depth once one of the elements is solid by a quarter of a report element. Early on, while the wide
step lets the compliance itself reach the loads, the term pushes as gently as the step is wide;
with the final width from the first step it decided the half MBB beam's topology early (seed 0:
compliance 164.3 against 147.0 without the term). With the sharp step of the late run the
compliance has no gradient at an element several elements from the boundary, so without the term a
generative model kept shapes whose boundary met a load pad from outside the domain.

Verdict (``attachment``): the share of the held nodes of the report's grid that are not held at
every depth (``f <= 0`` at the centre of one of the node's elements in E, at each),
``unheld_nodes``, must be 0.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from torch import Tensor

from ..problems.problem import Problem
from ..problems.structural import held_corners, held_elements, void_elements
from .base import Constraint, Setting, Stage
from .batch import Batch
from .compliance import continuation, narrowed, report_grid, solid_at, start_width
from .verdict import Verdict, Violation, number_text

__all__ = ["Attachment", "AttachmentVerdict", "DEPTHS", "POINTS"]

#: the depths besides the report grid's own elements: ``(side, a)``, the side of the elements with
#: a corner at the node in report elements, and the share ``a`` of the margin ``w / 2`` (module docstring)
DEPTHS = ((2.0, 1.0), (0.5, 0.5), (0.25, 0.25))

#: the key of the field values at the held nodes' element centres in a step
#: (:meth:`ginn.constraints.batch.Batch.field_at`)
POINTS = "attachment"


class AttachmentVerdict(Verdict):
    """Every held node touches the thresholded shape on the report's grid and at the depth of the
    default grid (module docstring)."""

    name = "attachment"

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("unheld_nodes",)
        self._grid: tuple | None = None

    def grid(self) -> tuple:
        """``(grid, void, held, depths)`` of the report's grid, built at the first use: ``held``
        ``(n_held, 2^d)`` the node's elements in E (-1: none), ``depths`` one ``(corners, present)``
        per entry of :data:`DEPTHS`, the centres ``(n_held, 2^d, d)`` of the elements of that side
        with a corner at the node and whether each lies in E ``(n_held, 2^d)``."""
        if self._grid is None:
            p = self.problem
            grid = report_grid(p)
            depths = [held_corners(p, grid, side * grid.h) for side, _ in DEPTHS]
            self._grid = (grid, void_elements(p, grid), held_elements(p, grid), depths)
        return self._grid

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        grid, _, held, depths = self.grid()
        if held.shape[0] == 0:
            return {"unheld_nodes": None}
        used = np.unique(held[held >= 0])  # the report grid's elements at a held node, all in E
        points = np.concatenate([grid.centres[used]] + [c.reshape(-1, grid.dim) for c, _ in depths])
        inside = solid_at(field, z, points)  # one pass over the nodes' elements of every depth
        solid = np.zeros(grid.n_elements + 1, dtype=bool)  # index -1: no element
        solid[used] = inside[: used.size]
        ok = solid[held].any(axis=1)
        for (_, present), at in zip(depths, np.split(inside[used.size:], len(depths))):
            deep = (at.reshape(present.shape) & present).any(axis=1)
            ok &= deep | ~present.any(axis=1)  # no corner in E: judged on the report's grid alone
        return {"unheld_nodes": float(1.0 - ok.mean())}

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
        self._verdict = AttachmentVerdict(p)
        grid, _, held, depths = self._verdict.grid()  # held (n_held, 2^d), -1: none
        used = np.unique(held[held >= 0])
        near = np.searchsorted(used, np.maximum(held, 0))
        points, elements, present, start = [grid.centres[used]], [near], [held >= 0], used.size
        for corners, inside in depths:  # corners (n_held, 2^d, d), inside (n_held, 2^d)
            deep = start + np.arange(inside.size).reshape(inside.shape)
            inside = inside.copy()
            none = ~inside.any(axis=1)  # no corner in E: the node is judged on the report's grid alone
            deep[none], inside[none] = near[none], (held >= 0)[none]
            points.append(corners.reshape(-1, grid.dim))
            elements.append(deep)
            present.append(inside)
            start += inside.size
        self.points = torch.as_tensor(np.concatenate(points), dtype=setting.dtype, device=dev)  # (n_used + D n_held 2^d, d)
        self.elements = torch.as_tensor(np.stack(elements), device=dev)  # (1 + D, n_held, 2^d), into points
        self.present = torch.as_tensor(np.stack(present), device=dev)
        share = [1.0] + [a for _, a in DEPTHS]
        self.share = torch.as_tensor(share, dtype=setting.dtype, device=dev)[:, None]  # (1 + D, 1): a
        self.final_width = 0.5 * float(grid.h.min())
        self.start_width = start_width(p, grid)

    def width(self, step: int) -> float:
        """``w`` at iteration ``step`` (module docstring)."""
        return narrowed(self.start_width, self.final_width, continuation(step, self.setting.cfg.training.iterations))

    @property
    def verdict(self) -> AttachmentVerdict:
        return self._verdict

    def loss(self, batch: Batch) -> Tensor | None:
        if self.elements.shape[1] == 0:
            return None
        f = batch.field_at(POINTS, self.points)  # (S, n_points)
        around = f[:, self.elements]  # (S, 1 + D, n_held, 2^d)
        m = torch.where(self.present, around, torch.full_like(around, torch.inf)).amin(dim=-1)  # (S, 1 + D, n_held)
        w = self.width(batch.step)
        return torch.relu(m + 0.5 * w * self.share).mean() / w
