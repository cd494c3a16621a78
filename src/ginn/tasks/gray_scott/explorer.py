"""``ginn view`` of a Gray-Scott run: the pattern ``v`` along a latent slider (one self-contained HTML
file; the page machinery is :mod:`ginn.viz.explorer`'s)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from torch import Tensor, nn

from ...config import GSParams
from ...viz.explorer import NOTE_MARGIN, ExplorerLatents, add_sliders, explorer_latents, note, write_page
from .checks import Thresholds, sample_fields
from .solver import relative_residual

__all__ = ["write_pattern_explorer"]


def write_pattern_explorer(model: nn.Module, Z: Tensor, params: GSParams, path: str | Path, *, steps: int = 64,
                           resolution: int = 96, title: str = "") -> Path:
    """The pattern ``v`` of each slider position (a heatmap over the periodic unit square) with its
    two cheap checks: the residual relative to the reaction terms and the spread of ``v``
    (:mod:`ginn.tasks.gray_scott.checks`; stationarity under time integration and diversity are
    ``ginn eval``'s)."""
    import plotly.graph_objects as go

    th = Thresholds()
    lat: ExplorerLatents = explorer_latents(Z, steps)
    codes = [c.reshape(1, -1) for c in lat.codes]
    W = np.concatenate([sample_fields(model, c, resolution) for c in codes])  # (n, 2, r, r)
    lo, hi = float(W[:, 1].min()), float(W[:, 1].max())
    axis = np.arange(resolution) / resolution
    frames, names = [], []
    for i, w in enumerate(W):
        rr = relative_residual(w[0], w[1], params)
        std = float(w[1].std())
        text = (f"<b>latent {lat.labels[i]}</b><br>residual {rr['rel']:.3g} ({'<=' if rr['rel'] <= th.residual_max else '>'} "
                f"{th.residual_max})<br>std(v) {std:.3g} ({'>=' if std >= th.std_min else '<'} {th.std_min})"
                "<br>stationarity, diversity: ginn eval")
        trace = go.Heatmap(x=axis, y=axis, z=w[1].T.astype(np.float32), zmin=lo, zmax=hi, colorscale="Viridis",
                           colorbar={"title": {"text": "v"}}, hoverinfo="skip")
        name = str(i) if lat.grid is None else f"{i // lat.grid[1]},{i % lat.grid[1]}"
        frames.append(go.Frame(name=name, data=[trace], traces=[0], layout={"annotations": [note(text)]}))
        names.append(name)
    fig = go.Figure(data=[frames[0].data[0]], frames=frames if len(frames) > 1 else None)
    layout: dict = {"title": {"text": title}, "annotations": [note(frames[0].layout.annotations[0].text)],
                    "margin": {"r": NOTE_MARGIN}, "height": 620, "xaxis": {"range": [0, 1], "constrain": "domain"},
                    "yaxis": {"range": [0, 1], "scaleanchor": "x", "scaleratio": 1}}
    add_sliders(layout, lat, names)
    fig.update_layout(**layout)
    return write_page(fig, lat, names, path, title)
