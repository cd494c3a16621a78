"""The parabolic mirror's figure (the paper's Figure 1, top row)."""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from ...config import MirrorParams
from ...fields import evaluate
from .optics import profile, reflected_direction

__all__ = ["plot_mirror"]


def plot_mirror(model: nn.Module, params: MirrorParams, path: Path) -> Path:
    """Figure 1 (top row): the mirror, incoming vertical rays and their reflections, and the focus."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = params
    x, h = profile(model, p, 400)
    par = next(model.parameters())
    xr = torch.linspace(p.x_min, p.x_max, p.n_rays_plot + 2, dtype=par.dtype, device=par.device)[1:-1]
    v = evaluate(model, xr[:, None], None, grad=True, create_graph=False)
    hr = v.f.cpu().double().numpy()
    r = reflected_direction(v.grad[:, 0]).cpu().double().numpy()
    xr_np = xr.cpu().double().numpy()
    top = max(p.focus * 1.6, float(h.max()) + 0.5)

    fig, ax = plt.subplots(figsize=(5, 5))
    for xi, hi, ri in zip(xr_np, hr, r):
        ax.plot([xi, xi], [top, hi], color="0.6", lw=0.8)
        # reflected ray, continued until it passes the focus height (or a fixed length)
        t = (p.focus - hi) / ri[1] * 1.3 if ri[1] > 1e-6 else 2.0 * p.focus
        ax.plot([xi, xi + t * ri[0]], [hi, hi + t * ri[1]], color="tab:orange", lw=0.8)
    ax.plot(x, x * x / (4 * p.focus), "k--", lw=0.8, label="exact $x^2/4F$")
    ax.plot(x, h, color="tab:blue", lw=2, label="GINN mirror")
    ax.plot([0], [p.focus], "r*", ms=10, label="focus")
    ax.set_aspect("equal")
    ax.set_xlim(p.x_min - 0.1, p.x_max + 0.1)
    ax.set_ylim(min(float(h.min()), 0.0) - 0.1, top)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=3, fontsize=8, frameon=False)
    ax.set_title("parabolic mirror")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
