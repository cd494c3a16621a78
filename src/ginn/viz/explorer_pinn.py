"""``ginn view`` for the problems without a geometry: the Gray-Scott patterns along a latent slider,
and the mirror's profile against the exact parabola (one self-contained HTML file each; the page
machinery is :mod:`ginn.viz.explorer`'s)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from torch import Tensor, nn

from ..config import GSParams, MirrorParams
from ..eval.gray_scott import Thresholds, sample_fields
from ..eval.mirror import profile
from ..eval.reference.gray_scott import relative_residual
from .explorer import ExplorerLatents, add_sliders, explorer_latents, note, write_page

__all__ = ["write_pattern_explorer", "write_mirror_view"]


def write_pattern_explorer(model: nn.Module, Z: Tensor, params: GSParams, path: str | Path, *, steps: int = 64,
                           resolution: int = 96, title: str = "") -> Path:
    """The pattern ``v`` of each slider position (a heatmap over the periodic unit square) with its
    two cheap checks: the residual relative to the reaction terms and the spread of ``v``
    (:mod:`ginn.eval.gray_scott`; stationarity under time integration and diversity are
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
                    "margin": {"r": 300}, "height": 620, "xaxis": {"range": [0, 1], "constrain": "domain"},
                    "yaxis": {"range": [0, 1], "scaleanchor": "x", "scaleratio": 1}}
    add_sliders(layout, lat, names)
    fig.update_layout(**layout)
    return write_page(fig, lat, names, path, title)


def write_mirror_view(model: nn.Module, params: MirrorParams, path: str | Path, title: str = "") -> Path:
    """The trained mirror ``h(x)`` against the exact parabola ``x^2 / (4 F)``, with the focus and
    the largest deviation."""
    import plotly.graph_objects as go

    x, h = profile(model, params, 400)
    exact = x * x / (4 * params.focus)
    err = float(np.abs(h - exact).max())
    fig = go.Figure(data=[
        go.Scatter(x=x, y=h, mode="lines", name="GINN mirror", line={"width": 3}),
        go.Scatter(x=x, y=exact, mode="lines", name="exact x^2 / 4F", line={"dash": "dash", "color": "black"}),
        go.Scatter(x=[0.0], y=[params.focus], mode="markers", name="focus", marker={"symbol": "star", "size": 14}),
    ])
    fig.update_layout(title={"text": title}, height=560, margin={"r": 300},
                      annotations=[note(f"<b>mirror</b><br>max |h - exact| {err:.3g}<br>focus height {params.focus:g}")],
                      yaxis={"scaleanchor": "x", "scaleratio": 1})
    lat = ExplorerLatents([None], ["the mirror"], [True])
    return write_page(fig, lat, ["0"], path, title)
