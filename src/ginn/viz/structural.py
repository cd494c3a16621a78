"""The strain-energy density over the shapes of a 2D structural problem (``figures/strain_energy.png``).

Each panel is one shape as :class:`ginn.constraints.compliance.ComplianceReport` solves it
(thresholded on the fine element grid), coloured by the weighted strain-energy density of its
load cases on a logarithmic scale (void white), with the interfaces drawn and the compliance in
the title.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch
from matplotlib.colors import LogNorm

from ..constraints.compliance import ComplianceReport
from ..problems.problem import Problem
from .figure import new_figure, save_figure
from .plot import draw_problem_2d

__all__ = ["plot_strain_energy"]


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
    for z in codes:
        solid, U, density = rep.analyse(model, z)
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
