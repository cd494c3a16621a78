"""The strain-energy density over the shapes of a structural problem.

2D (``figures/strain_energy.png``): each panel is one shape as
:class:`ginn.constraints.compliance.ComplianceReport` solves it (thresholded on the fine element
grid), coloured by the weighted strain-energy density of its load cases on a logarithmic scale
(void white), with the interfaces drawn and the compliance in the title.

3D (``figures/strain_energy_<i>.ply`` and ``figures/strain_energy.png``): each shape's boundary
mesh with vertex colours, every vertex taking the density of the nearest solid element of the
report's grid (logarithmic, one scale for all shapes), and a view of each coloured mesh titled with
its compliance.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import LogNorm
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from scipy.spatial import cKDTree

from ..constraints.compliance import ComplianceReport
from ..extract.export import shape_boundary, watertight_mesh
from ..problems.problem import Problem
from .figure import new_figure, save_figure
from .plot import DEFAULT_VIEWS, draw_problem_2d

__all__ = ["plot_strain_energy", "strain_energy_meshes", "vertex_energy"]

#: the colour map of the density (light: little energy, dark: much)
CMAP = "inferno_r"


def plot_strain_energy(model, Z: torch.Tensor | None, problem: Problem, path: Path, report: ComplianceReport | None = None) -> Path:
    """One panel per shape of ``Z`` (None: the single shape) into ``path``; returns ``path``."""
    rep = report or ComplianceReport(problem)
    grid, solver, w, _ = rep.fine()
    codes = [None] if Z is None else [Z[i] for i in range(Z.shape[0])]
    n = len(codes)
    cols = min(4, n)
    rows = math.ceil(n / cols)
    (lo, hi) = (np.asarray(problem.domain.lo), np.asarray(problem.domain.hi))
    aspect = (hi[1] - lo[1]) / (hi[0] - lo[0])
    fig = new_figure(4.2 * cols + 1.2, (4.2 * aspect + 0.8) * rows)
    fields = []
    for solid, U, density in rep.analyse_all(model, Z):
        c = float(w @ solver.work(U[None])[0].numpy())
        fields.append((np.where(solid, (torch.as_tensor(w)[:, None] * density).sum(0).numpy(), np.nan), c))
    finite = np.concatenate([f[np.isfinite(f) & (f > 0)] for f, _ in fields])
    norm = LogNorm(vmin=max(float(np.percentile(finite, 1)), 1e-12), vmax=float(finite.max())) if finite.size else None
    for k, (f, c) in enumerate(fields):
        ax = fig.add_subplot(rows, cols, k + 1)
        img = f.reshape(grid.shape).T  # (y, x)
        im = ax.imshow(img, origin="lower", extent=(lo[0], hi[0], lo[1], hi[1]), cmap="inferno_r", norm=norm,
                       interpolation="nearest")
        draw_problem_2d(ax, problem)
        ax.set_title(("" if codes[k] is None else f"shape {k}: ") + f"compliance {c:.4g}", fontsize=9)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
    fig.colorbar(im, ax=fig.axes, shrink=0.8, label="strain-energy density")
    return save_figure(fig, path)


def vertex_energy(report: ComplianceReport, solid: np.ndarray, energy: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """``(n_vertices,)``: at each point of ``vertices`` ``(n, 3)`` the density ``energy``
    ``(n_elements,)`` of the nearest element of the report's fine grid that ``solid`` holds
    (NaN without any)."""
    grid = report.fine()[0]
    if not solid.any() or len(vertices) == 0:
        return np.full(len(vertices), np.nan)
    idx = np.nonzero(solid)[0]
    _, near = cKDTree(grid.centres[idx]).query(vertices)
    return energy[idx[near]]


def strain_energy_meshes(model, Z: torch.Tensor | None, problem: Problem, out_dir: Path, resolution: int,
                         report: ComplianceReport | None = None) -> list[Path]:
    """The coloured meshes of a 3D structural problem's shapes (module docstring) into ``out_dir``
    (``strain_energy_<i>.ply``, and ``strain_energy.png`` with a view of each); returns the paths."""
    rep = report or ComplianceReport(problem)
    _, solver, w, _ = rep.fine()
    codes = [None] if Z is None else [Z[i] for i in range(Z.shape[0])]
    shapes = []
    for z, (solid, U, density) in zip(codes, rep.analyse_all(model, Z)):
        c = float(w @ solver.work(U[None])[0].numpy())
        energy = (torch.as_tensor(w)[:, None] * density).sum(0).numpy()
        mesh = watertight_mesh(shape_boundary(model, z, problem.domain, resolution)[0])
        shapes.append((mesh, vertex_energy(rep, solid, energy, np.asarray(mesh.vertices)), c))
    values = np.concatenate([e[np.isfinite(e) & (e > 0)] for _, e, _ in shapes] + [np.zeros(0)])
    norm = LogNorm(vmin=max(float(np.percentile(values, 1)), 1e-12), vmax=float(values.max())) if values.size else None
    cmap = colormaps[CMAP]
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    cols = min(4, len(shapes))
    rows = math.ceil(len(shapes) / cols)
    fig = new_figure(4.2 * cols + 1.2, 4.2 * rows)
    lo, hi = np.asarray(problem.domain.lo), np.asarray(problem.domain.hi)
    for k, (mesh, e, c) in enumerate(shapes):
        rgba = np.full((len(e), 4), 0.8)
        if norm is not None:
            ok = np.isfinite(e) & (e > 0)
            rgba[ok] = cmap(norm(e[ok]))
        mesh.visual.vertex_colors = (np.clip(rgba, 0, 1) * 255).astype(np.uint8)
        name = "strain_energy.ply" if codes[k] is None else f"strain_energy_{k:03d}.ply"
        mesh.export(out_dir / name, file_type="ply")
        paths.append(out_dir / name)
        ax = fig.add_subplot(rows, cols, k + 1, projection="3d")
        if len(mesh.faces):
            faces = np.asarray(mesh.faces)
            ax.add_collection3d(Poly3DCollection(np.asarray(mesh.vertices)[faces], facecolors=rgba[faces].mean(axis=1),
                                                 edgecolors="none", linewidths=0))
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
        ax.set_box_aspect(tuple(hi - lo))
        ax.view_init(elev=DEFAULT_VIEWS[0][0], azim=DEFAULT_VIEWS[0][1])
        ax.set_axis_off()
        ax.set_title(("" if codes[k] is None else f"shape {k}: ") + f"compliance {c:.4g}", fontsize=9)
    if norm is not None:
        fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=fig.axes, shrink=0.8, label="strain-energy density")
    paths.append(save_figure(fig, out_dir / "strain_energy.png"))
    return paths
