"""Figures of a run (matplotlib, Agg canvas: no display needed, pyplot's global state untouched).

The front door of ``ginn plot``::

    paths = plot_run(field, Z, problem, out_dir, metrics_jsonl=run_dir / "metrics.jsonl")

which writes (PNG):

* ``superposition.png`` (2D): all shapes overlaid with transparency on the problem (Figure 4).
* ``shapes.png``: one panel per shape (3D: one rendered view per shape).
* ``interpolation.png``: trained shapes (colour) alternating with the shapes of the latent
  mid-points between neighbouring trained latents (grey) (Figure 6). Neighbours: consecutive
  latents after sorting by value for 1D latents, else in the given order.
* ``loss_curves.png``: the series of ``metrics.jsonl`` against the step, a panel per family
  (:mod:`ginn.viz.curves`).
* ``shape_XXX_views.png`` (3D): several views of each shape, with the design region's envelope and
  the interfaces drawn faintly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from ..config import default_resolution
from ..extract.boundary import Boundary, extract_boundary
from ..extract.export import SHAPE_COLOR, fill_polylines
from ..extract.grid import make_grid
from ..extract.sampling import sample_field
from ..fields import Field
from ..geometry.base import Box, Region
from ..problems.problem import Problem
from .curves import plot_loss_curves
from .figure import new_figure, save_figure
from .manufacturing import MARK_COLORS, draw_violations_2d, face_marks, has_marks

__all__ = [
    "new_figure",
    "save_figure",
    "save_shape_png",
    "draw_problem_2d",
    "draw_shape_2d",
    "render_mesh",
    "plot_superposition",
    "plot_shapes",
    "plot_interpolation",
    "plot_loss_curves",
    "plot_views",
    "plot_run",
    "interpolation_latents",
    "DEFAULT_VIEWS",
]

#: (elevation, azimuth) in degrees of the 3D views.
DEFAULT_VIEWS = ((25.0, 45.0), (25.0, 135.0), (25.0, -60.0), (89.0, -90.0))
GREY = "#8c8c8c"


# --- 2D -----------------------------------------------------------------------------------------------


def _polylines(shape: Boundary | Sequence[np.ndarray]) -> list[np.ndarray]:
    return shape.polylines() if isinstance(shape, Boundary) else [np.asarray(p) for p in shape]


def draw_shape_2d(ax, shape: Boundary | Sequence[np.ndarray], color=SHAPE_COLOR, alpha: float = 1.0, edge: bool = True) -> None:
    """Fill a 2D shape given by its boundary (or its polylines) on ``ax``."""
    fill_polylines(ax, _polylines(shape), color, alpha, edge)


def _region_values(region: Region, domain: Box, resolution: int):
    g = make_grid(domain, resolution)
    with torch.no_grad():
        v = region.sdf(torch.as_tensor(g.points(), dtype=torch.float64)).double().numpy().reshape(g.shape)
    return g, v


def draw_problem_2d(ax, problem: Problem, resolution: int = 256, n_interface: int = 400) -> None:
    """Draw the domain, the design region's outline, the obstacles and the interfaces."""
    lo, hi = problem.domain.lo, problem.domain.hi
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.plot([lo[0], hi[0], hi[0], lo[0], lo[0]], [lo[1], lo[1], hi[1], hi[1], lo[1]], color="#bbbbbb", lw=0.8)
    for ob in problem.obstacles:
        g, v = _region_values(ob, problem.domain, resolution)
        ax.contourf(g.axis_coords(0), g.axis_coords(1), v.T, levels=[float(v.min()) - 1.0, 0.0], colors=["#d9d9d9"])
    if problem.design_region is not None:
        g, v = _region_values(problem.design_region, problem.domain, resolution)
        ax.contour(g.axis_coords(0), g.axis_coords(1), v.T, levels=[0], colors=["#555555"], linewidths=0.7, linestyles="--")
    gen = torch.Generator().manual_seed(0)
    for itf in problem.interfaces:
        x, _ = itf.sample(n_interface, generator=gen, dtype=torch.float64)
        x = x.numpy()
        ax.scatter(x[:, 0], x[:, 1], s=1.5, color="black", zorder=5)


def save_shape_png(shape: Boundary | Sequence[np.ndarray], domain: Box, path: str | Path, color=SHAPE_COLOR) -> Path:
    """A single 2D shape, filled, in its domain."""
    ext = np.asarray(domain.hi) - np.asarray(domain.lo)
    fig = new_figure(6, 6 * ext[1] / ext[0] + 0.2)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_xlim(domain.lo[0], domain.hi[0])
    ax.set_ylim(domain.lo[1], domain.hi[1])
    ax.set_aspect("equal")
    draw_shape_2d(ax, shape, color)
    return save_figure(fig, path)


def save_shape_figure(shape: Boundary | Sequence[np.ndarray], problem: Problem, path: str | Path, title: str = "",
                      color=SHAPE_COLOR) -> Path:
    """A single 2D shape, filled, over its problem (the domain, E's outline, the obstacles and the
    interfaces), with ``title`` (e.g. its feasibility verdict) above it."""
    ext = np.asarray(problem.domain.hi) - np.asarray(problem.domain.lo)
    fig = new_figure(6, 6 * ext[1] / ext[0] + (0.6 if title else 0.2))
    ax = fig.add_subplot(1, 1, 1)
    draw_shape_2d(ax, shape, color, alpha=0.85)
    draw_problem_2d(ax, problem)
    if title:
        ax.set_title(title, fontsize=8, wrap=True)
    return save_figure(fig, path)


# --- 3D -----------------------------------------------------------------------------------------------


def _shaded(boundary: Boundary, color, light=(0.3, -0.5, 0.8), marks: np.ndarray | None = None):
    """``(m, 3)`` the faces' RGB in ``color`` under a Lambert light; ``marks (m,)``: the faces that
    break a manufacturing tolerance, in their colours (:func:`ginn.viz.manufacturing.face_marks`)."""
    from matplotlib.colors import to_rgb

    V, F = boundary.vertices, boundary.elements
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    ll = np.asarray(light, float)
    ll /= np.linalg.norm(ll)
    shade = 0.35 + 0.65 * np.abs(n @ ll)
    base = np.broadcast_to(np.asarray(to_rgb(color)), (len(F), 3))
    if marks is not None:
        palette = np.array([to_rgb(color)] + [to_rgb(MARK_COLORS[k]) for k in sorted(MARK_COLORS)])
        base = palette[marks]
    return np.clip(base * shade[:, None], 0, 1)


def render_mesh(
    ax,
    boundary: Boundary,
    domain: Box,
    color=SHAPE_COLOR,
    view: tuple[float, float] = DEFAULT_VIEWS[0],
    envelope: Boundary | None = None,
    interface_points: np.ndarray | None = None,
    marks: np.ndarray | None = None,
) -> None:
    """Draw a 3D boundary with flat Lambert shading on a 3D axis (optionally a faint envelope,
    interface points and the faces that break a manufacturing tolerance in their colours, ``marks
    (m,)``, :func:`ginn.viz.manufacturing.face_marks`)."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    if boundary.n_elements:
        tri = boundary.vertices[boundary.elements]
        ax.add_collection3d(Poly3DCollection(tri, facecolors=_shaded(boundary, color, marks=marks), edgecolors="none",
                                             linewidths=0))
    if envelope is not None and envelope.n_elements:
        ax.add_collection3d(
            Poly3DCollection(envelope.vertices[envelope.elements], facecolors=(0.5, 0.5, 0.5, 0.04), edgecolors="none")
        )
    if interface_points is not None and len(interface_points):
        p = interface_points
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], s=0.5, color="black", alpha=0.5)
    lo, hi = np.asarray(domain.lo), np.asarray(domain.hi)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(tuple(hi - lo))
    ax.view_init(elev=view[0], azim=view[1])
    ax.set_axis_off()


def _envelope(problem: Problem, resolution: int) -> Boundary | None:
    if problem.design_region is None:
        return None
    g, v = _region_values(problem.design_region, problem.domain, resolution)
    return extract_boundary(v, g, close=True)


def _interface_points(problem: Problem, n: int = 300) -> np.ndarray:
    gen = torch.Generator().manual_seed(0)
    pts = [itf.sample(n, generator=gen, dtype=torch.float64)[0].numpy() for itf in problem.interfaces]
    return np.concatenate(pts) if pts else np.zeros((0, problem.dim))


def plot_views(
    boundary: Boundary,
    problem: Problem,
    path: str | Path,
    views: Sequence[tuple[float, float]] = DEFAULT_VIEWS,
    *,
    color=SHAPE_COLOR,
    envelope: bool = True,
    interfaces: bool = True,
    envelope_resolution: int = 32,
    title: str = "",
    marks: np.ndarray | None = None,
) -> Path:
    """Several views of one 3D shape in one PNG (the design region translucent, the interface
    samples as dots, ``marks``: see :func:`render_mesh`), titled ``title`` (e.g. its feasibility
    verdict)."""
    env = _envelope(problem, envelope_resolution) if envelope else None
    ip = _interface_points(problem) if interfaces else None
    fig = new_figure(4 * len(views), 4)
    for i, v in enumerate(views):
        ax = fig.add_subplot(1, len(views), i + 1, projection="3d")
        render_mesh(ax, boundary, problem.domain, color, v, env, ip, marks)
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, path)


# --- sets of shapes -----------------------------------------------------------------------------------


def _boundaries(
    field: Field, latents: list[Tensor | None], domain: Box, resolution: int, cache: dict | None = None
) -> list[Boundary]:
    """Extracted boundaries of the shapes of ``latents``; ``cache`` (keyed by latent values and
    resolution) lets the figures of one run share their extractions."""
    g = make_grid(domain, resolution)
    if isinstance(field, torch.nn.Module):
        field.eval()
    out = []
    for z in latents:
        key = (None if z is None else tuple(z.reshape(-1).tolist()), resolution)
        if cache is not None and key in cache:
            out.append(cache[key])
            continue
        b = extract_boundary(sample_field(field, g, z), g)
        if cache is not None:
            cache[key] = b
        out.append(b)
    return out


def _codes(Z: Tensor | None) -> list[Tensor | None]:
    return [None] if Z is None else [Z[i] for i in range(Z.shape[0])]


def _panel_grid(n: int, ncols: int | None = None) -> tuple[int, int]:
    ncols = ncols or min(n, 4 if n <= 8 else int(math.ceil(math.sqrt(n))))
    return int(math.ceil(n / ncols)), ncols


def _mesh_marks(field: Field, z: Tensor | None, problem: Problem, boundary: Boundary, resolution: int) -> np.ndarray | None:
    """The manufacturing marks of a 3D shape's faces on the picture's grid
    (:func:`ginn.viz.manufacturing.face_marks`; None where the problem states no such tolerance)."""
    if problem.dim != 3 or not has_marks(problem):
        return None
    g = make_grid(problem.domain, resolution)
    return face_marks(problem, sample_field(field, g, z) <= 0, g, boundary)


def _draw_panel(fig, rows, cols, i, boundary, problem, color, view=DEFAULT_VIEWS[0], alpha=1.0, title=None, marks=None):
    if problem.dim == 2:
        ax = fig.add_subplot(rows, cols, i + 1)
        draw_problem_2d(ax, problem)
        draw_shape_2d(ax, boundary, color, alpha)
        ax.set_xticks([])
        ax.set_yticks([])
    else:
        ax = fig.add_subplot(rows, cols, i + 1, projection="3d")
        render_mesh(ax, boundary, problem.domain, color, view, marks=marks)
    if title:
        ax.set_title(title, fontsize=8)
    return ax


def _panel_size(problem: Problem) -> tuple[float, float]:
    ext = np.asarray(problem.domain.hi) - np.asarray(problem.domain.lo)
    return (3.0, 3.0 * ext[1] / ext[0] + 0.3) if problem.dim == 2 else (3.0, 3.0)


def plot_superposition(
    field: Field, Z: Tensor | None, problem: Problem, path: str | Path, resolution: int | None = None, *, cache: dict | None = None
) -> Path:
    """Figure 4 style: every shape filled with transparency, overlaid on the problem (2D). In 3D,
    all shapes in one rendered view, each with its own colour."""
    res = resolution or default_resolution("figure", problem.dim)
    bs = _boundaries(field, _codes(Z), problem.domain, res, cache)
    w, h = _panel_size(problem)
    fig = new_figure(2 * w, 2 * h)
    if problem.dim == 2:
        ax = fig.add_subplot(1, 1, 1)
        draw_problem_2d(ax, problem)
        alpha = max(0.06, min(0.6, 1.5 / len(bs)))
        for b in bs:
            draw_shape_2d(ax, b, SHAPE_COLOR, alpha, edge=False)
        ax.set_xticks([])
        ax.set_yticks([])
    else:
        from matplotlib import colormaps

        ax = fig.add_subplot(1, 1, 1, projection="3d")
        cmap = colormaps["tab10"]
        for i, b in enumerate(bs):
            render_mesh(ax, b, problem.domain, cmap(i % 10))
    return save_figure(fig, path)


def plot_shapes(
    field: Field,
    Z: Tensor | None,
    problem: Problem,
    path: str | Path,
    resolution: int | None = None,
    ncols: int | None = None,
    *,
    cache: dict | None = None,
) -> Path:
    """One panel per shape (2D: on the problem, 3D: one rendered view), with what breaks its
    manufacturing tolerances marked on the picture's grid (:mod:`ginn.viz.manufacturing`)."""
    res = resolution or default_resolution("figure", problem.dim)
    codes = _codes(Z)
    bs = _boundaries(field, codes, problem.domain, res, cache)
    rows, cols = _panel_grid(len(bs), ncols)
    w, h = _panel_size(problem)
    fig = new_figure(w * cols, h * rows)
    marks = problem.dim == 2 and has_marks(problem)
    g = make_grid(problem.domain, res) if marks else None
    for i, b in enumerate(bs):
        title = None if codes[i] is None else "z = " + ", ".join(f"{v:.3g}" for v in codes[i].reshape(-1).tolist())
        ax = _draw_panel(fig, rows, cols, i, b, problem, SHAPE_COLOR, title=title,
                         marks=_mesh_marks(field, codes[i], problem, b, res))
        if marks:
            draw_violations_2d(ax, problem, sample_field(field, g, codes[i]) <= 0, g, b)
    return save_figure(fig, path)


def interpolation_latents(Z: Tensor) -> tuple[Tensor, list[bool]]:
    """Trained latents interleaved with the mid-points of neighbouring ones.

    Arguments:
        Z: trained latents ``(S, k)``; 1D latents are sorted by value first.

    Returns:
        ``(latents (2S - 1, k), is_trained)``.
    """
    if Z.dim() == 1:
        Z = Z[:, None]
    if Z.shape[1] == 1:
        Z = Z[torch.argsort(Z[:, 0])]
    out, trained = [], []
    for i in range(Z.shape[0]):
        if i:
            out.append((Z[i - 1] + Z[i]) / 2)
            trained.append(False)
        out.append(Z[i])
        trained.append(True)
    return torch.stack(out), trained


def plot_interpolation(
    field: Field,
    Z: Tensor,
    problem: Problem,
    path: str | Path,
    resolution: int | None = None,
    ncols: int | None = None,
    *,
    cache: dict | None = None,
) -> Path:
    """Figure 6 style: trained shapes in colour, the shapes at the latent mid-points of neighbouring
    trained latents in grey, in sequence (trained, mid-point, trained, ...)."""
    from matplotlib import colormaps

    res = resolution or default_resolution("figure", problem.dim)
    lat, trained = interpolation_latents(Z)
    bs = _boundaries(field, _codes(lat), problem.domain, res, cache)
    n = len(bs)
    cols = ncols or min(n, 5 if problem.dim == 2 else 5)
    rows = int(math.ceil(n / cols))
    w, h = _panel_size(problem)
    fig = new_figure(w * cols, h * rows)
    cmap = colormaps["viridis"]
    S = max(1, sum(trained) - 1)
    k = 0
    for i, (b, t) in enumerate(zip(bs, trained)):
        color = cmap(0.9 * k / S) if t else GREY
        label = ("z = " if t else "mid z = ") + ", ".join(f"{v:.3g}" for v in lat[i].reshape(-1).tolist())
        _draw_panel(fig, rows, cols, i, b, problem, color, title=label)
        k += int(t)
    return save_figure(fig, path)


def plot_run(
    field: Field,
    Z: Tensor | None,
    problem: Problem,
    out_dir: str | Path,
    *,
    metrics_jsonl: str | Path | None = None,
    resolution: int | None = None,
    views: Sequence[tuple[float, float]] = DEFAULT_VIEWS,
    max_view_shapes: int = 16,
    max_render_resolution: int = 64,
    view_titles: Sequence[str] | None = None,
) -> list[Path]:
    """All figures of a run into ``out_dir`` (see the module docstring); returns the paths.

    Every shape is extracted once (shared by the figures). In 3D the meshes drawn by matplotlib are
    extracted at ``min(resolution, max_render_resolution)`` (rendering cost grows with triangles).
    """
    out_dir = Path(out_dir)
    res = resolution or default_resolution("figure", problem.dim)
    if problem.dim == 3:
        res = min(res, max_render_resolution)
    cache: dict = {}
    paths = []
    if problem.dim == 2:
        paths.append(plot_superposition(field, Z, problem, out_dir / "superposition.png", res, cache=cache))
    paths.append(plot_shapes(field, Z, problem, out_dir / "shapes.png", res, cache=cache))
    if Z is not None and Z.shape[0] > 1:
        paths.append(plot_interpolation(field, Z, problem, out_dir / "interpolation.png", res, cache=cache))
    if metrics_jsonl is not None and Path(metrics_jsonl).exists():
        paths.append(plot_loss_curves(metrics_jsonl, out_dir / "loss_curves.png"))
    if problem.dim == 3:
        codes = _codes(Z)[:max_view_shapes]
        for i, b in enumerate(_boundaries(field, codes, problem.domain, res, cache)):
            title = view_titles[i] if view_titles is not None and i < len(view_titles) else ""
            paths.append(plot_views(b, problem, out_dir / f"shape_{i:03d}_views.png", views, title=title,
                                    marks=_mesh_marks(field, codes[i], problem, b, res)))
    return paths
