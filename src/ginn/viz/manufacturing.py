"""Where a shape breaks its manufacturing tolerances: the solid thinner than ``min_thickness``
(what the opening by the ball removes), the gaps narrower than ``min_gap`` (what the closing fills)
and the overhanging boundary (the same definitions as the verdicts:
:mod:`ginn.constraints.feature_size`, :mod:`ginn.constraints.overhang`); drawn over a 2D panel, and
as the colours of a 3D mesh's faces (:func:`face_marks`)."""

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

__all__ = ["THIN_COLOR", "GAP_COLOR", "OVERHANG_COLOR", "MARK_COLORS", "has_marks", "violation_marks", "overhanging",
           "face_marks", "draw_violations_2d"]

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
        out["overhang"] = boundary.vertices[boundary.elements[overhanging(problem, boundary)]]
    return out


def overhanging(problem: Problem, boundary: Boundary) -> np.ndarray:
    """``(m,)`` bool: the elements of ``boundary`` that overhang beyond ``tolerances.overhang``, the
    exempt ones left out (the verdict's definition; all False without the tolerance)."""
    t = problem.tolerances.overhang
    if t is None or not boundary.n_elements:
        return np.zeros(boundary.n_elements, dtype=bool)
    up = np.asarray(t.up, dtype=np.float64)
    exempt = OverhangVerdict(problem).exempt(boundary)
    down = -(element_normals(boundary) @ (up / np.linalg.norm(up)))
    return (down > math.sin(math.radians(t.angle))) & ~exempt


#: the colours of :func:`face_marks`' codes 1, 2 and 3 (0: no mark)
MARK_COLORS = {1: THIN_COLOR, 2: GAP_COLOR, 3: OVERHANG_COLOR}


def face_marks(problem: Problem, inside: np.ndarray, grid: Grid, boundary: Boundary) -> np.ndarray:
    """What each face of a 3D mesh breaks, ``(m,)`` int8: 1 in a grid cell with a node of the thin
    solid, 2 of the narrow void (:func:`violation_marks`), 3 overhanging (which wins), 0 nothing;
    drawn in :data:`MARK_COLORS`.

    Arguments:
        inside: ``grid.shape`` bool, the shape's nodes; ``boundary``: its mesh on ``grid``.
    """
    marks = violation_marks(problem, inside, grid, boundary)
    m = boundary.n_elements
    out = np.zeros(m, dtype=np.int8)
    if not m:
        return out
    c = boundary.vertices[boundary.elements].mean(axis=1)  # (m, 3) the faces' centroids
    cell = np.clip(np.floor((c - grid.lo) / grid.spacing).astype(np.int64), 0, np.asarray(grid.shape) - 2)
    for code, key in ((1, "thin"), (2, "narrow")):
        if key not in marks or not marks[key].any():
            continue
        hit = np.zeros(m, dtype=bool)
        for off in np.ndindex(2, 2, 2):  # the cell's eight corners
            i = cell + np.asarray(off)
            hit |= marks[key][i[:, 0], i[:, 1], i[:, 2]]
        out[hit] = code
    out[overhanging(problem, boundary)] = 3
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
