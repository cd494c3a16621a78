"""Where a 2D shape breaks its manufacturing tolerances, drawn over its panel: the solid thinner
than ``min_thickness`` (what the opening by the ball removes), the gaps narrower than ``min_gap``
(what the closing fills) and the overhanging boundary (the same definitions as the verdicts:
:mod:`ginn.constraints.feature_size`, :mod:`ginn.constraints.overhang`)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.collections import LineCollection

from ..constraints.feature_size import MinGapVerdict, MinThicknessVerdict
from ..constraints.overhang import OverhangVerdict
from ..extract.boundary import Boundary
from ..extract.grid import Grid
from ..extract.morphology import opening
from ..extract.overhang import element_normals
from ..problems.problem import Problem

__all__ = ["THIN_COLOR", "GAP_COLOR", "OVERHANG_COLOR", "has_marks", "violation_marks", "draw_violations_2d"]

THIN_COLOR = "#d62728"
GAP_COLOR = "#ff7f0e"
OVERHANG_COLOR = "#e377c2"


def has_marks(problem: Problem) -> bool:
    """Whether the problem states a tolerance this module draws."""
    t = problem.tolerances
    return any(v is not None for v in (t.min_thickness, t.min_gap, t.overhang))


def violation_marks(problem: Problem, inside: np.ndarray, grid: Grid, boundary: Boundary) -> dict[str, np.ndarray]:
    """``thin``, ``narrow``: node masks ``(grid.shape)`` of the solid the opening removes and of the
    void the closing fills; ``overhang``: the overhanging boundary segments ``(m, 2, d)``; each only
    where the problem states its tolerance."""
    t = problem.tolerances
    out: dict[str, np.ndarray] = {}
    if t.min_thickness is not None:
        rims = MinThicknessVerdict(problem).rims(grid)
        out["thin"] = inside & ~opening(inside, grid.spacing, t.min_thickness.size) & ~rims
    if t.min_gap is not None:
        rims = MinGapVerdict(problem).rims(grid)
        out["narrow"] = ~inside & ~opening(~inside, grid.spacing, t.min_gap.size) & ~rims
    if t.overhang is not None and boundary.n_elements:
        up = np.asarray(t.overhang.up, dtype=np.float64)
        exempt = OverhangVerdict(problem).exempt(boundary)
        down = -(element_normals(boundary) @ (up / np.linalg.norm(up)))
        bad = (down > math.sin(math.radians(t.overhang.angle))) & ~exempt
        out["overhang"] = boundary.vertices[boundary.elements[bad]]
    return out


def draw_violations_2d(ax, problem: Problem, inside: np.ndarray, grid: Grid, boundary: Boundary) -> None:
    """Draw :func:`violation_marks` on ``ax`` (module docstring)."""
    marks = violation_marks(problem, inside, grid, boundary)
    x, y = grid.axis_coords(0), grid.axis_coords(1)
    for key, color in (("thin", THIN_COLOR), ("narrow", GAP_COLOR)):
        if key in marks and marks[key].any():
            ax.contourf(x, y, marks[key].T.astype(float), levels=[0.5, 1.5], colors=[color], alpha=0.8, zorder=4)
    if "overhang" in marks and len(marks["overhang"]):
        ax.add_collection(LineCollection(marks["overhang"], colors=OVERHANG_COLOR, linewidths=1.6, zorder=6))
