"""Figures of shape runs (matplotlib on Agg canvases): shapes over their problem, superpositions,
latent interpolations, 3D views, loss curves, Plateau's comparison with its minimal surface; the
latent-space explorer (plotly, one self-contained HTML file), whose page machinery the other
kinds' views reuse. The mirror's and Gray-Scott's figures live in their task packages."""

from .curves import plot_loss_curves
from .explorer import write_explorer
from .plateau import render_plateau, write_plateau_results
from .plot import plot_interpolation, plot_run, plot_shapes, plot_superposition, plot_views

__all__ = [
    "plot_run", "plot_superposition", "plot_shapes", "plot_interpolation", "plot_loss_curves", "plot_views",
    "render_plateau", "write_plateau_results", "write_explorer",
]
