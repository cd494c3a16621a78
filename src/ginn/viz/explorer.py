"""The latent-space explorer of a shape run: one self-contained HTML file (``ginn view``).

The page embeds plotly's JavaScript, so it opens without a network. A slider walks through the
latent space: the trained latents plus ``steps`` evenly spaced values between the smallest and the
largest (1D latents; a trained one is marked ``trained`` in the slider's label), or an
``n x n`` grid (two sliders; ``n = ceil(sqrt(steps))``) over the first two axes of the latent set
when its box is given, else over the plane through the trained latents' mean spanned by their two
principal directions. For each value the page shows

* 2D: the filled shape over the domain, the design region's outline, the obstacles (grey) and the
  interfaces with their prescribed normals; below, every trained shape's outline superposed
  (the paper's Figure 1);
* 3D: the extracted mesh, the design region as a translucent surface and the interface samples
  (Plateau's problem: also the reference minimal surface, translucent);

A 2D structural problem (``physics:``) also shows each position's strain-energy density over the
shape as :class:`ginn.constraints.compliance.ComplianceReport` solves it (thresholded on the fine
element grid, averaged over blocks of 2 x 2 elements for the page, logarithmic colours on one
scale for every position) and its compliance beside the verdict.

Beside the picture: the shape's feasibility verdict (``ginn.eval.feasibility``) with its CD1, volume
outside E and number of pieces, and the share of its bound that each other verdict uses (not the
topology's counts): with a ``judge`` (what shape runs pass: ``ginn eval``'s,
:class:`ginn.eval.latent_space.LatentJudge`) the verdict ``ginn eval`` gives that code, else an
estimate on the picture's own grid, marked as such.

The URL fragment ``#step=K`` (or ``#step=I,J`` for a latent plane) opens the page at that slider
position.
"""

from __future__ import annotations

import json
import math
import re
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from ..constraints.compliance import ComplianceReport
from ..eval.feasibility import FEASIBILITY_METRICS, FeasibilityCheck, judged_volume_outside, ratios, shape_violations, verdict_text
from ..eval.metrics import extract_shape, prepare_context, shape_metrics
from ..eval.reference.minimal_surface import plateau_reference
from ..eval.results import ShapeMetrics
from ..extract.boundary import extract_boundary
from ..extract.grid import make_grid
from ..fields import Field
from ..problems.problem import Problem
from .manufacturing import MARK_COLORS, THIN_COLOR, face_marks, has_marks, violation_marks

__all__ = ["ExplorerLatents", "explorer_latents", "write_explorer", "strain_energy", "write_page", "add_sliders", "note",
           "EXPLORER_RESOLUTION"]

#: Grid cells along the longest domain axis of the pictures (and of the metrics beside them).
EXPLORER_RESOLUTION = {2: 128, 3: 40}

SHAPE_COLOR = "#3b75af"


@dataclass
class ExplorerLatents:
    """The latent values the sliders reach.

    Attributes:
        codes: ``(n, k)`` latents, or ``[None]`` for a latent-free single shape.
        labels: one slider label per code.
        trained: whether each code is a trained latent.
        grid: ``(n_i, n_j)`` for a latent plane (two sliders), None for one slider.
    """

    codes: list[Tensor | None]
    labels: list[str]
    trained: list[bool]
    grid: tuple[int, int] | None = None


def explorer_latents(Z: Tensor | None, steps: int, box: tuple[float, float] | None = None) -> ExplorerLatents:
    """The slider positions for trained latents ``Z (S, k)`` (None: one shape) and ``steps`` values
    (with the latent ``box`` and two or more dimensions: a grid over its first two axes)."""
    if Z is None or Z.shape[1] == 0:
        return ExplorerLatents([None if Z is None else Z[0]], ["the shape" if Z is None else "the pattern"], [True])
    Z = Z.detach().double().cpu()
    if box is not None and Z.shape[1] >= 2:
        n = max(2, math.ceil(math.sqrt(steps)))
        t = torch.linspace(box[0], box[1], n, dtype=torch.float64)
        centre = torch.full((Z.shape[1],), 0.5 * (box[0] + box[1]), dtype=torch.float64)
        codes, labels = [], []
        for i in range(n):
            for j in range(n):
                c = centre.clone()
                c[0], c[1] = t[i], t[j]
                codes.append(c)
                labels.append(f"z1 {float(t[i]):.3g}, z2 {float(t[j]):.3g}")
        return ExplorerLatents(codes, labels, [False] * len(codes), (n, n))
    if Z.shape[1] == 1:
        z = Z[:, 0]
        lo, hi = float(z.min()), float(z.max())
        even = torch.linspace(lo, hi, steps, dtype=torch.float64) if steps > 1 and hi > lo else torch.tensor([lo])
        tol = 1e-9 * max(1.0, abs(lo), abs(hi))
        extra = [v for v in even.tolist() if not bool(((z - v).abs() <= tol).any())]
        values = sorted([(v, True) for v in z.tolist()] + [(v, False) for v in extra])
        return ExplorerLatents([torch.tensor([v]) for v, _ in values],
                               [f"{v:.4g}" + (" trained" if t else "") for v, t in values], [t for _, t in values])
    mean = Z.mean(0)
    centred = Z - mean
    _, s, Vh = torch.linalg.svd(centred, full_matrices=False) if Z.shape[0] > 1 else (None, torch.zeros(0), None)
    k = Z.shape[1]
    axes = [Vh[i] if i < len(s) and float(s[i]) > 1e-12 else torch.eye(k, dtype=torch.float64)[i] for i in range(2)]
    n = max(2, math.ceil(math.sqrt(steps)))
    ranges = []
    for u in axes:
        proj = centred @ u
        a, b = float(proj.min()), float(proj.max())
        if b - a < 1e-12:
            a, b = a - 1.0, b + 1.0
        ranges.append(torch.linspace(a, b, n, dtype=torch.float64))
    codes, labels = [], []
    for i in range(n):
        for j in range(n):
            codes.append(mean + ranges[0][i] * axes[0] + ranges[1][j] * axes[1])
            labels.append(f"{float(ranges[0][i]):.3g}, {float(ranges[1][j]):.3g}")
    return ExplorerLatents(codes, labels, [False] * len(codes), (n, n))


#: the verdicts :func:`_verdict` does not list by the share of their bound: those it shows with their
#: own lines, and the topology, a count against a target (its violation names the counts)
NOT_LISTED = ("interface", "volume_outside", "connected", "volume_fraction", "topology")


def _verdict(m: ShapeMetrics, problem: Problem, judge: FeasibilityCheck | None = None) -> str:
    verdicts = None if judge is None else judge.verdicts
    lines = verdict_text(shape_violations(m, problem, verdicts), verdicts or ()).replace(", ", "; ").split("; ")
    cd1, vol, b0 = m.get("interface_cd1"), judged_volume_outside(m), m.get("b0_in_design_region")
    if cd1 is not None and problem.interfaces:
        lines.append(f"CD1 {cd1:.2e} (bound {problem.tolerances.interface * problem.unit_scale:.2e})")
    if vol is not None:
        lines.append(f"volume outside E off the interfaces {vol:.2e} (bound {problem.tolerances.volume_outside:.2e})")
    if b0 is not None:
        lines.append(f"pieces inside E {int(b0)}")
    bounds, frac = problem.tolerances.volume_fraction, m.get("volume_fraction")
    if bounds is not None and frac is not None:
        lines.append(f"volume fraction of E {frac:.3f} (bounds {bounds.min if bounds.min is not None else 0:g} to "
                     f"{bounds.max if bounds.max is not None else 1:g})")
    # the other verdicts (thickness, overhang, faces, Plateau's reference, ...): how much of the bound is used
    for name, r in ratios(m, problem, verdicts).items():
        if name not in NOT_LISTED:
            lines.append(f"{name}: {100 * r:.0f} % of its bound" if math.isfinite(r) else f"{name}: undefined")
    return "<br>".join(lines)


def _contours(values: np.ndarray, grid, pad: int = 0) -> list[np.ndarray]:
    """The zero contours of node ``values`` (2D; ``pad`` extra nodes on every side) in world coordinates."""
    from skimage import measure

    return [grid.lo + (c - pad) * grid.spacing for c in measure.find_contours(values, 0.0)]


def _lines(polylines: list[np.ndarray], d: int) -> list[np.ndarray]:
    """Coordinate arrays of several polylines joined with NaN separators (one plotly trace)."""
    if not polylines:
        return [np.zeros(0) for _ in range(d)]
    parts = [np.vstack([p, np.full((1, d), np.nan)]) for p in polylines]
    xy = np.vstack(parts)
    return [xy[:, i] for i in range(d)]


def _problem_traces(problem: Problem, resolution: int) -> list:
    """Static traces: the design region, the obstacles and the interfaces (with their normals)."""
    import plotly.graph_objects as go

    d = problem.dim
    grid = make_grid(problem.domain, resolution)
    pts = torch.as_tensor(grid.points(), dtype=torch.float64)
    traces = []
    gen = torch.Generator().manual_seed(0)
    if d == 2:
        for ob in problem.obstacles:
            with torch.no_grad():
                v = ob.sdf(pts).numpy().reshape(grid.shape)
            x, y = _lines([np.vstack([c, c[:1]]) for c in _contours(v, grid)], 2)
            traces.append(go.Scatter(x=x, y=y, mode="lines", fill="toself", fillcolor="rgba(150,150,150,0.5)",
                                     line={"color": "#888888", "width": 1}, name="obstacle", hoverinfo="skip"))
        if problem.design_region is not None:
            with torch.no_grad():
                v = problem.design_region.sdf(pts).numpy().reshape(grid.shape)
            x, y = _lines(_contours(v, grid), 2)
            traces.append(go.Scatter(x=x, y=y, mode="lines", line={"color": "#444444", "width": 1, "dash": "dash"},
                                     name="design region", hoverinfo="skip"))
        span = float(max(h - lo for lo, h in zip(problem.domain.lo, problem.domain.hi)))
        for i, itf in enumerate(problem.interfaces):
            x, n = itf.sample(200, generator=gen, dtype=torch.float64)
            x, n = x.numpy(), n.numpy()
            traces.append(go.Scatter(x=x[:, 0], y=x[:, 1], mode="markers", marker={"size": 3, "color": "black"},
                                     name="interfaces", legendgroup="interfaces", showlegend=i == 0, hoverinfo="skip"))
            if itf.has_normals:
                sel = slice(None, None, 10)
                segs = [np.stack([a, a + 0.04 * span * b]) for a, b in zip(x[sel], n[sel])]
                sx, sy = _lines(segs, 2)
                traces.append(go.Scatter(x=sx, y=sy, mode="lines", line={"color": "#d62728", "width": 1},
                                         name="normals", legendgroup="normals", showlegend=i == 0, hoverinfo="skip"))
        return traces
    if problem.design_region is not None:
        with torch.no_grad():
            v = problem.design_region.sdf(pts).numpy().reshape(grid.shape)
        env = extract_boundary(v, grid, close=True)
        V, F = env.vertices.astype(np.float32), env.elements.astype(np.int32)
        traces.append(go.Mesh3d(x=V[:, 0], y=V[:, 1], z=V[:, 2], i=F[:, 0], j=F[:, 1], k=F[:, 2], opacity=0.12,
                                color="#999999", name="design region", hoverinfo="skip", showlegend=True))
    if problem.reference == "minimal-surface":  # Plateau's problem: the discrete minimal surface to compare with
        ref = plateau_reference(rings=16)
        V, F = ref.V.astype(np.float32), ref.F.astype(np.int32)
        traces.append(go.Mesh3d(x=V[:, 0], y=V[:, 1], z=V[:, 2], i=F[:, 0], j=F[:, 1], k=F[:, 2], opacity=0.35,
                                color="#e07b39", name="reference minimal surface", hoverinfo="skip", showlegend=True))
    ip = [itf.sample(300, generator=gen, dtype=torch.float64)[0].numpy() for itf in problem.interfaces]
    if ip:
        x = np.concatenate(ip).astype(np.float32)
        traces.append(go.Scatter3d(x=x[:, 0], y=x[:, 1], z=x[:, 2], mode="markers", name="interfaces",
                                   marker={"size": 1.5, "color": "#d62728"}, hoverinfo="skip"))
    return traces


def _shape_trace(shape, grid, d: int, filled: bool = True, marks: np.ndarray | None = None):
    """The shape: in 2D its filled outline (``filled`` False: the outline alone, over a map beneath
    it), in 3D its mesh, with ``marks (m,)`` (:func:`ginn.viz.manufacturing.face_marks`) the faces
    that break a manufacturing tolerance in their colours."""
    import plotly.graph_objects as go

    if d == 2:
        # closed outlines (the values padded with "outside"); holes run the other way round, so
        # the nonzero fill rule of one SVG path leaves them empty
        x, y = _lines(_contours(np.pad(shape.values, 1, constant_values=1.0), grid, pad=1), 2)
        fill = {"fill": "toself", "fillcolor": SHAPE_COLOR, "opacity": 0.85} if filled else {}
        return go.Scatter(x=x, y=y, mode="lines", line={"color": "#1f4e79", "width": 1}, name="shape", hoverinfo="skip",
                          **fill)
    b = shape.boundary
    V, F = b.vertices.astype(np.float32), b.elements.astype(np.int32)
    if len(F) == 0:
        V, F = np.zeros((3, 3), np.float32), np.zeros((0, 3), np.int32)
        marks = None
    look = {"flatshading": False, "lighting": {"ambient": 0.45, "diffuse": 0.7, "specular": 0.1}, "name": "shape",
            "hoverinfo": "skip"}
    if marks is None:
        return go.Mesh3d(x=V[:, 0], y=V[:, 1], z=V[:, 2], i=F[:, 0], j=F[:, 1], k=F[:, 2], color=SHAPE_COLOR, **look)
    # a code per face, drawn through a stepped colour scale (a byte per face in the page, where a
    # colour string per face would take twenty)
    colors = [SHAPE_COLOR] + [MARK_COLORS[k] for k in sorted(MARK_COLORS)]
    n = len(colors)
    scale = [[s, c] for i, c in enumerate(colors) for s in (i / n, (i + 1) / n)]
    return go.Mesh3d(x=V[:, 0], y=V[:, 1], z=V[:, 2], i=F[:, 0], j=F[:, 1], k=F[:, 2],
                     intensity=marks.astype(np.uint8), intensitymode="cell", colorscale=scale, cmin=-0.5,
                     cmax=n - 0.5, showscale=False, **look)


def strain_energy(report: ComplianceReport, field: Field, z: Tensor | None) -> tuple[np.ndarray, float]:
    """The weighted strain-energy density of the shape at ``z`` on the report's fine grid averaged
    over blocks of 2 x 2 elements, ``(n_x / 2, n_y / 2)`` (NaN where the block has no solid), and the
    shape's weighted compliance."""
    grid, solver, w, _ = report.fine()
    solid, U, density = report.analyse(field, z)
    c = float(w @ solver.work(U[None])[0].numpy())
    energy = (torch.as_tensor(w)[:, None] * density).sum(0).numpy()
    nx, ny = grid.shape
    e = np.where(solid, energy, 0.0).reshape(nx // 2, 2, ny // 2, 2).sum(axis=(1, 3))
    k = solid.reshape(nx // 2, 2, ny // 2, 2).sum(axis=(1, 3))
    return np.where(k > 0, e / np.maximum(k, 1), np.nan), c


def _energy_trace(energy: np.ndarray, problem: Problem, scale: tuple[float, float]):
    """A heatmap of ``log10`` of a block-averaged strain-energy density (:func:`strain_energy`) over
    the domain, void transparent, on the colour range ``scale``."""
    import plotly.graph_objects as go

    lo, hi = problem.domain.lo, problem.domain.hi
    nx, ny = energy.shape
    x = lo[0] + (np.arange(nx) + 0.5) * (hi[0] - lo[0]) / nx
    y = lo[1] + (np.arange(ny) + 0.5) * (hi[1] - lo[1]) / ny
    with np.errstate(divide="ignore"):
        z = np.where(energy > 0, np.log10(np.where(energy > 0, energy, 1.0)), np.nan).T.astype(np.float32)
    return go.Heatmap(x=x, y=y, z=z, zmin=scale[0], zmax=scale[1], colorscale="Inferno", reversescale=True,
                      colorbar={"title": {"text": "log10 strain-energy density"}, "x": 1.0, "len": 0.5, "y": 0.25},
                      name="strain-energy density", hoverinfo="skip")


def _marks_trace(problem: Problem, shape, grid):
    """The outlines of the thin solid and the narrow void and the overhanging boundary of a 2D
    shape (:func:`ginn.viz.manufacturing.violation_marks`), as one line trace."""
    import plotly.graph_objects as go

    marks = violation_marks(problem, shape.values <= 0, grid, shape.boundary)
    lines: list[np.ndarray] = []
    for key in ("thin", "narrow"):
        if key in marks and marks[key].any():
            lines += _contours(np.pad(0.5 - marks[key].astype(np.float64), 1, constant_values=0.5), grid, pad=1)
    lines += [seg for seg in marks.get("overhang", [])]
    x, y = _lines(lines, 2)
    return go.Scatter(x=x, y=y, mode="lines", line={"color": THIN_COLOR, "width": 2},
                      name="thin, narrow or overhanging", hoverinfo="skip")


def _slider(latents: ExplorerLatents, names: list[str], prefix: str, axis: int | None = None) -> dict:
    if axis is None:
        steps = [{"label": lab, "method": "animate",
                  "args": [[name], {"mode": "immediate", "frame": {"duration": 0, "redraw": True}, "transition": {"duration": 0}}]}
                 for lab, name in zip(latents.labels, names)]
    else:
        n = latents.grid[axis]
        steps = [{"label": str(i), "method": "skip", "args": []} for i in range(n)]
    return {"active": 0, "steps": steps, "currentvalue": {"prefix": prefix}, "pad": {"t": 40 + (50 if axis == 1 else 0)}}


_SCRIPT = """
(function() {
  var gd = document.getElementById('{plot_id}');
  var grid = %(grid)s;
  function show(name, active) {
    Plotly.animate(gd, [name], {mode: 'immediate', frame: {duration: 0, redraw: true}, transition: {duration: 0}});
    var upd = {};
    for (var s = 0; s < active.length; s++) { upd['sliders[' + s + '].active'] = active[s]; }
    Plotly.relayout(gd, upd);
  }
  if (grid) {
    gd.on('plotly_sliderchange', function() {
      var a = gd.layout.sliders[0].active, b = gd.layout.sliders[1].active;
      Plotly.animate(gd, [a + ',' + b], {mode: 'immediate', frame: {duration: 0, redraw: true}, transition: {duration: 0}});
    });
  }
  var m = /step=([0-9]+)(?:,([0-9]+))?/.exec(window.location.hash);
  if (m) {
    if (grid) { var i = +m[1], j = +(m[2] || 0); show(i + ',' + j, [i, j]); }
    else { var k = +m[1]; show(%(names)s[k], [k]); }
  }
  document.body.setAttribute('data-explorer-ready', '1');
})();
"""


def write_explorer(field: Field, Z: Tensor | None, problem: Problem, path: str | Path, *, steps: int = 64,
                   resolution: int | None = None, title: str = "", judge: FeasibilityCheck | None = None,
                   box: tuple[float, float] | None = None) -> Path:
    """Write the explorer page of the shapes ``{field(., z) <= 0}`` to ``path``; returns it.

    Arguments:
        field: the trained field; Z: its trained latents ``(S, k)`` or None.
        steps: evenly spaced latent values besides the trained ones (a plane: about that many).
        resolution: grid cells along the longest domain axis (default :data:`EXPLORER_RESOLUTION`).
        judge: what gives each position's verdict (``ginn eval``'s: :class:`ginn.eval.latent_space.LatentJudge`);
            None: the metrics of the picture's own grid, marked as an estimate on that grid.
        box: the latent set ``[low, high]^k``: two or more latent dimensions get a grid over its
            first two axes (the others at its centre) instead of the plane through the trained codes.
    """
    import plotly.graph_objects as go

    d = problem.dim
    res = resolution or EXPLORER_RESOLUTION[d]
    ctx = prepare_context(problem, res, n_design_boundary_samples=0, seed=0)
    lat = explorer_latents(Z, steps, box)
    if isinstance(field, torch.nn.Module):
        field.eval()
    dev = next(field.parameters()).device if isinstance(field, torch.nn.Module) else torch.device("cpu")
    dt = next(field.parameters()).dtype if isinstance(field, torch.nn.Module) else torch.float32
    frames, names, shapes = [], [], []
    marked = d == 2 and has_marks(problem)
    marked3 = d == 3 and has_marks(problem)
    report = ComplianceReport(problem) if d == 2 and problem.physics is not None else None
    energies: list[np.ndarray] = []
    for idx, z in enumerate(lat.codes):
        zz = None if z is None else z.to(dev, dt)
        shape = extract_shape(field, zz, ctx.grid)
        if judge is None:
            m = shape_metrics(shape, ctx, field, zz, only=FEASIBILITY_METRICS)
            how = f"estimate on the picture's grid of {res} cells (ginn eval judges finer)"
        else:
            m = judge.shape(field, zz)[0]
            how = f"as ginn eval judges it ({judge.resolution} cells)"
        name = str(idx) if lat.grid is None else f"{idx // lat.grid[1]},{idx % lat.grid[1]}"
        verdict = _verdict(m, problem, judge)
        if report is not None:
            energy, c = strain_energy(report, field, zz)
            energies.append(energy)
            verdict += f"<br>compliance {c:.4g} (solved on the fine element grid)"
        text = f"<b>latent {lat.labels[idx]}</b><br>{verdict}<br><i>{how}</i>"
        faces = face_marks(problem, shape.values <= 0, ctx.grid, shape.boundary) if marked3 else None
        data = [_shape_trace(shape, ctx.grid, d, filled=report is None, marks=faces)]
        data += [_marks_trace(problem, shape, ctx.grid)] if marked else []
        frames.append(go.Frame(name=name, data=data, layout={"annotations": [note(text)]}))
        names.append(name)
        shapes.append(shape)
    if energies:
        logs = np.log10(np.concatenate([e[np.isfinite(e) & (e > 0)] for e in energies]))
        scale = (float(np.percentile(logs, 1)), float(logs.max())) if logs.size else (0.0, 1.0)
        for frame, e in zip(frames, energies):
            frame.data = (*frame.data, _energy_trace(e, problem, scale))
    for frame in frames:
        frame.traces = list(range(len(frame.data)))
    fig = go.Figure(data=[*frames[0].data, *_problem_traces(problem, res)], frames=frames if len(frames) > 1 else None)
    lo, hi = problem.domain.lo, problem.domain.hi
    layout: dict = {"title": {"text": title}, "annotations": [note(frames[0].layout.annotations[0].text)],
                    "margin": {"r": NOTE_MARGIN}, "height": 620, "legend": {"orientation": "h", "y": -0.02}}
    if d == 2:
        layout["xaxis"] = {"range": [lo[0], hi[0]], "constrain": "domain"}
        layout["yaxis"] = {"range": [lo[1], hi[1]], "scaleanchor": "x", "scaleratio": 1}
    else:
        layout["scene"] = {f"{a}axis": {"range": [lo[i], hi[i]]} for i, a in enumerate("xyz")}
        layout["scene"]["aspectmode"] = "data"
    add_sliders(layout, lat, names)
    fig.update_layout(**layout)
    trained = [s for s, t in zip(shapes, lat.trained) if t]
    extra = [_superposition(trained, ctx.grid, problem, res)] if d == 2 and len(trained) > 1 else []
    return write_page(fig, lat, names, path, title, extra)


def add_sliders(layout: dict, lat: ExplorerLatents, names: list[str]) -> None:
    """The slider(s) of ``lat`` into a figure's ``layout`` (none for a single position)."""
    if len(names) <= 1:
        return
    if lat.grid is None:
        layout["sliders"] = [_slider(lat, names, "latent ")]
    else:
        layout["sliders"] = [_slider(lat, names, "first direction ", 0), _slider(lat, names, "second direction ", 1)]


def write_page(fig, lat: ExplorerLatents, names: list[str], path: str | Path, title: str = "", extra=()) -> Path:
    """The self-contained page: ``fig`` (frames named ``names``, the sliders of ``lat``) with the
    script that follows the sliders and the ``#step=`` fragment, then the figures ``extra``."""
    script = _SCRIPT % {"grid": "true" if lat.grid is not None else "false", "names": json.dumps(names)}
    parts = [fig.to_html(include_plotlyjs=True, full_html=False, post_script=script, div_id="explorer",
                         auto_play=False)]
    parts += [f.to_html(include_plotlyjs=False, full_html=False, div_id=f"extra{i}") for i, f in enumerate(extra)]
    html = ("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>" + (title or "ginn explorer") +
            "</title></head><body>\n" + "\n".join(parts) + "\n</body></html>\n")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(html, encoding="utf-8")
    return path


#: the right margin of a page (px) and the characters per line of the text box in it (at 12 px a
#: character is about 6.5 px wide)
NOTE_MARGIN = 300
NOTE_WIDTH = 40


def wrap_note(text: str, width: int = NOTE_WIDTH) -> str:
    """``text``'s ``<br>``-separated lines broken at spaces to at most ``width`` characters (a word
    longer than that stays whole); a line in one ``<b>`` or ``<i>`` keeps it on every piece.
    Wrapping a wrapped text changes nothing."""
    out = []
    for line in text.split("<br>"):
        m = re.fullmatch(r"<([bi])>(.*)</\1>", line)
        body, tag = (m.group(2), m.group(1)) if m else (line, None)
        parts = textwrap.wrap(body, width, break_long_words=False, break_on_hyphens=False) or [""]
        out += [f"<{tag}>{p}</{tag}>" if tag else p for p in parts]
    return "<br>".join(out)


def note(text: str) -> dict:
    """A text box right of the plot (the verdict beside the picture), its lines wrapped to fit the
    margin :data:`NOTE_MARGIN`."""
    return {"text": wrap_note(text), "xref": "paper", "yref": "paper", "x": 1.02, "y": 1.0, "xanchor": "left", "yanchor": "top",
            "align": "left", "showarrow": False, "font": {"size": 12}}


def _superposition(shapes: list, grid, problem: Problem, res: int):
    import plotly.graph_objects as go

    traces = []
    for i, s in enumerate(shapes):
        x, y = _lines(_contours(s.values, grid), 2)
        traces.append(go.Scatter(x=x, y=y, mode="lines", line={"color": SHAPE_COLOR, "width": 1}, opacity=0.6,
                                 name="trained shapes", legendgroup="shapes", showlegend=i == 0, hoverinfo="skip"))
    fig = go.Figure(data=[*_problem_traces(problem, res), *traces])
    lo, hi = problem.domain.lo, problem.domain.hi
    fig.update_layout(title={"text": f"all {len(shapes)} trained shapes"}, height=520,
                      xaxis={"range": [lo[0], hi[0]], "constrain": "domain"},
                      yaxis={"range": [lo[1], hi[1]], "scaleanchor": "x", "scaleratio": 1})
    return fig
