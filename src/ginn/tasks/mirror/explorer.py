"""``ginn view`` of a mirror run: its profile against the exact parabola (one self-contained HTML
file; the page machinery is :mod:`ginn.viz.explorer`'s)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from torch import nn

from ...config import MirrorParams
from ...viz.explorer import NOTE_MARGIN, ExplorerLatents, note, write_page
from .optics import profile

__all__ = ["write_mirror_view"]


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
    fig.update_layout(title={"text": title}, height=560, margin={"r": NOTE_MARGIN},
                      annotations=[note(f"<b>mirror</b><br>max |h - exact| {err:.3g}<br>focus height {params.focus:g}")],
                      yaxis={"scaleanchor": "x", "scaleratio": 1})
    lat = ExplorerLatents([None], ["the mirror"], [True])
    return write_page(fig, lat, ["0"], path, title)
