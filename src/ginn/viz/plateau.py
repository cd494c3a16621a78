"""Result files of a Plateau run: the clipped GINN surface, the reference surface, and renders with
the polygon drawn on them (the paper's Figure 1)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..eval.plateau import extract_plateau_surface, gamma_of, reference_surface
from ..fields import Field

__all__ = ["render_plateau", "write_plateau_results"]


def render_plateau(V: np.ndarray, F: np.ndarray, gamma: np.ndarray, path: Path, title: str = "Plateau's problem") -> Path:
    """A 3D render (matplotlib, Agg) of a surface mesh with the polygon ``gamma`` drawn on it (Figure 1)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    G = np.asarray(gamma, dtype=np.float64)
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(111, projection="3d")
    if len(F):
        T = V[F]
        n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        light = np.array([0.4, -0.5, 0.75]) / np.linalg.norm([0.4, -0.5, 0.75])
        shade = 0.35 + 0.65 * np.abs(n @ light)
        colors = plt.cm.viridis(0.35 + 0.4 * shade)
        colors[:, :3] *= shade[:, None]
        ax.add_collection3d(Poly3DCollection(T, facecolors=colors, edgecolors="none", linewidths=0))
    loop = np.concatenate([G, G[:1]])
    ax.plot(loop[:, 0], loop[:, 1], loop[:, 2], color="tab:red", lw=2.5)
    lo, hi = G.min(0), G.max(0)
    c, r = (lo + hi) / 2, (hi - lo).max() / 2 * 1.05
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=25, azim=-60)
    ax.set_title(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write_plateau_results(field: Field, problem_or_gamma, run_dir: Path, resolution: int = 128) -> list[Path]:
    """Write ``plateau/surface.stl`` (the clipped GINN surface), ``plateau/reference.stl`` and
    ``plateau/plateau.png`` / ``plateau/reference.png`` (renders with gamma) under ``run_dir``."""
    import trimesh

    G = gamma_of(problem_or_gamma)
    out = Path(run_dir) / "plateau"
    out.mkdir(parents=True, exist_ok=True)
    V, F = extract_plateau_surface(field, G, resolution)
    ref, _ = reference_surface(G)
    paths = []
    for name, (v, f) in (("surface", (V, F)), ("reference", (ref.V, ref.F))):
        p = out / f"{name}.stl"
        trimesh.Trimesh(vertices=v, faces=f, process=False).export(p)
        paths.append(p)
    paths.append(render_plateau(V, F, G, out / "plateau.png", "GINN surface"))
    paths.append(render_plateau(ref.V, ref.F, G, out / "reference.png", "discrete minimal surface (reference)"))
    return paths
