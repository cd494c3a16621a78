"""Exporting shapes: watertight meshes (3D) and contour polylines / drawings (2D).

The front door of ``ginn export``::

    paths = export_shapes(field, latents, problem.domain, out_dir, resolution=256, mesh_format="stl")

``latents`` may be any latent values (trained or not): a ``(S, k)`` tensor, or None for a shape
without a latent code.

File formats:

* 3D: ``.stl`` / ``.ply`` / ``.obj`` through trimesh (closed at the domain faces, watertight).
* 2D: ``.json`` (``{"domain": {"lo", "hi"}, "contours": [[[x, y], ...], ...]}``), ``.csv`` (rows
  ``contour, x, y``), ``.npz`` (arrays ``contour_0``, ``contour_1``, ...), ``.svg`` (filled
  shape, y axis up in the picture) and ``.png`` (matplotlib, Agg). Closed contours repeat their
  first vertex at the end; outer contours run counter-clockwise, holes clockwise.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from ..fields import Field
from ..geometry.base import Box
from .boundary import Boundary, extract_boundary
from .grid import Grid, make_grid
from .sampling import sample_field

__all__ = [
    "MESH_FORMATS",
    "CONTOUR_FORMATS",
    "shape_boundary",
    "export_mesh",
    "watertight_mesh",
    "export_contours",
    "export_shape",
    "export_shapes",
    "latent_label",
    "fill_polylines",
]

MESH_FORMATS = ("stl", "ply", "obj")
CONTOUR_FORMATS = ("json", "csv", "npz", "svg", "png")
SHAPE_COLOR = "#1f77b4"


def shape_boundary(field: Field, z: Tensor | None, domain: Box, resolution: int, *,
                   adaptive: bool = True) -> tuple[Boundary, np.ndarray, Grid]:
    """Extract the closed boundary of ``{f(., z) <= 0}`` in ``domain``.

    Returns:
        ``(boundary, values (grid.shape), grid)``.
    """
    grid = make_grid(domain, resolution)
    values = sample_field(field, grid, z, adaptive=adaptive)
    return extract_boundary(values, grid, close=True), values, grid


def export_mesh(boundary: Boundary, path: str | Path, file_format: str | None = None) -> Path:
    """Write a 3D boundary as a mesh (format from ``file_format`` or the suffix: stl, ply, obj;
    ``.<format>`` is appended when ``path`` does not already end with it)."""
    path = Path(path)
    fmt = (file_format or path.suffix.lstrip(".")).lower()
    if fmt not in MESH_FORMATS:
        raise ValueError(f"unknown mesh format {fmt!r} (one of {', '.join(MESH_FORMATS)})")
    if boundary.dim != 3:
        raise ValueError("meshes are exported for 3D shapes; use export_contours in 2D")
    if path.suffix.lower() != "." + fmt:
        path = path.with_name(path.name + "." + fmt)
    path.parent.mkdir(parents=True, exist_ok=True)
    watertight_mesh(boundary).export(path, file_type=fmt)
    return path


def watertight_mesh(boundary: Boundary):
    """The ``trimesh.Trimesh`` that :func:`export_mesh` writes for a closed 3D boundary."""
    import trimesh

    mesh = trimesh.Trimesh(boundary.vertices, boundary.elements, process=False)
    # marching cubes emits zero-area triangles where the surface passes through grid nodes; they
    # leave edges shared by 4 or 6 faces, so drop them to keep the exported mesh watertight
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def _svg(polylines: list[np.ndarray], domain: Box, width_px: float = 800.0) -> str:
    lo, hi = np.asarray(domain.lo, float), np.asarray(domain.hi, float)
    s = width_px / (hi[0] - lo[0])
    W, H = width_px, (hi[1] - lo[1]) * s
    parts = []
    for p in polylines:
        X = (p[:, 0] - lo[0]) * s
        Y = (hi[1] - p[:, 1]) * s
        d = "M " + " L ".join(f"{a:.3f} {b:.3f}" for a, b in zip(X, Y))
        if len(p) > 2 and np.allclose(p[0], p[-1]):
            d += " Z"
        parts.append(d)
    path = " ".join(parts)
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{W:.0f}" height="{H:.0f}" viewBox="0 0 {W:.3f} {H:.3f}">\n'
        f'  <rect x="0" y="0" width="{W:.3f}" height="{H:.3f}" fill="white" stroke="#999" stroke-width="1"/>\n'
        f'  <path d="{path}" fill="#1f77b4" fill-rule="evenodd" stroke="black" stroke-width="1"/>\n'
        "</svg>\n"
    )


def fill_polylines(ax, polylines: Sequence[np.ndarray], color: str = SHAPE_COLOR, alpha: float = 1.0, edge: bool = True) -> None:
    """Fill the shape bounded by closed ``polylines`` ``[(k_i, 2)]`` on a matplotlib axis (even-odd:
    holes stay empty)."""
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MplPath

    lines = [np.asarray(p) for p in polylines if len(p) > 2]
    if not lines:
        return
    verts = np.concatenate(lines)
    codes = np.concatenate(
        [np.r_[MplPath.MOVETO, np.full(len(p) - 2, MplPath.LINETO), MplPath.CLOSEPOLY] for p in lines]
    ).astype(np.uint8)
    ax.add_patch(PathPatch(MplPath(verts, codes), facecolor=color, alpha=alpha, edgecolor=color if edge else "none", lw=0.6))


def _png(polylines: list[np.ndarray], domain: Box, path: Path) -> None:
    """A single 2D shape, filled, in its domain (matplotlib on an Agg canvas)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    ext = np.asarray(domain.hi) - np.asarray(domain.lo)
    fig = Figure(figsize=(6, 6 * ext[1] / ext[0] + 0.2), dpi=120)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_xlim(domain.lo[0], domain.hi[0])
    ax.set_ylim(domain.lo[1], domain.hi[1])
    ax.set_aspect("equal")
    fill_polylines(ax, polylines)
    fig.savefig(path, bbox_inches="tight")


def export_contours(boundary: Boundary, stem: str | Path, domain: Box, formats: Sequence[str] = CONTOUR_FORMATS) -> list[Path]:
    """Write a 2D boundary's polylines to ``stem.<format>`` for each format (json csv npz svg png).

    Returns:
        The written paths.
    """
    if boundary.dim != 2:
        raise ValueError("contours are exported for 2D shapes; use export_mesh in 3D")
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    lines = boundary.polylines()
    out = []
    for fmt in formats:
        fmt = fmt.lower()
        p = stem.with_name(stem.name + "." + fmt)
        if fmt == "json":
            p.write_text(
                json.dumps({"domain": {"lo": list(domain.lo), "hi": list(domain.hi)}, "contours": [c.tolist() for c in lines]})
            )
        elif fmt == "csv":
            with p.open("w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(["contour", "x", "y"])
                for i, c in enumerate(lines):
                    for x, y in c:
                        w.writerow([i, repr(float(x)), repr(float(y))])
        elif fmt == "npz":
            np.savez(p, **{f"contour_{i}": c for i, c in enumerate(lines)})
        elif fmt == "svg":
            p.write_text(_svg(lines, domain))
        elif fmt == "png":
            _png(lines, domain, p)
        else:
            raise ValueError(f"unknown contour format {fmt!r} (one of {', '.join(CONTOUR_FORMATS)})")
        out.append(p)
    return out


def latent_label(z: Tensor | None) -> str:
    """A file-name friendly label of a latent value (``z0.125`` or ``z0.1_-0.3``; ``shape`` for None)."""
    if z is None:
        return "shape"
    vals = z.reshape(-1).tolist()
    return "z" + "_".join(f"{v:.4g}" for v in vals)


def export_shape(
    field: Field,
    z: Tensor | None,
    domain: Box,
    stem: str | Path,
    resolution: int = 256,
    *,
    mesh_format: str = "stl",
    contour_formats: Sequence[str] = CONTOUR_FORMATS,
    adaptive: bool = True,
) -> list[Path]:
    """Extract one shape and write it (a mesh in 3D, contours and drawings in 2D) to ``stem.*``."""
    b, _, _ = shape_boundary(field, z, domain, resolution, adaptive=adaptive)
    if domain.dim == 3:
        return [export_mesh(b, Path(stem), mesh_format)]
    return export_contours(b, stem, domain, contour_formats)


def export_shapes(
    field: Field,
    latents: Tensor | None,
    domain: Box,
    out_dir: str | Path,
    resolution: int = 256,
    *,
    mesh_format: str = "stl",
    contour_formats: Sequence[str] = CONTOUR_FORMATS,
    prefix: str = "shape",
    adaptive: bool = True,
) -> list[Path]:
    """Export the shapes of every latent value in ``latents`` (``(S, k)`` or None) into ``out_dir``.

    Files are named ``{prefix}_{i:03d}_{latent_label}.{ext}`` (``{prefix}.{ext}`` without latents).

    Returns:
        All written paths.
    """
    out_dir = Path(out_dir)
    if isinstance(field, torch.nn.Module):
        field.eval()
    if latents is None:
        return export_shape(field, None, domain, out_dir / prefix, resolution, mesh_format=mesh_format,
                            contour_formats=contour_formats, adaptive=adaptive)
    if latents.dim() == 1:
        latents = latents[:, None]
    paths: list[Path] = []
    for i in range(latents.shape[0]):
        z = latents[i]
        stem = out_dir / f"{prefix}_{i:03d}_{latent_label(z)}"
        paths += export_shape(field, z, domain, stem, resolution, mesh_format=mesh_format,
                              contour_formats=contour_formats, adaptive=adaptive)
    return paths
