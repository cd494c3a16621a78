"""Figures (matplotlib on Agg canvases): shapes over their problem, superpositions, latent
interpolations, 3D views, loss curves, and the figures of the mirror, Plateau and Gray-Scott runs;
the latent-space explorer (plotly, one self-contained HTML file)."""

from .explorer import write_explorer
from .gray_scott import write_patterns
from .mirror import plot_mirror
from .plateau import render_plateau, write_plateau_results
from .plot import plot_interpolation, plot_loss_curves, plot_run, plot_shapes, plot_superposition, plot_views

__all__ = [
    "plot_run", "plot_superposition", "plot_shapes", "plot_interpolation", "plot_loss_curves", "plot_views",
    "plot_mirror", "render_plateau", "write_plateau_results", "write_patterns", "write_explorer",
]
