"""Result files of a finished shape run: shapes (contours/meshes), figures, loss curves."""

from __future__ import annotations

from pathlib import Path

from torch import Tensor, nn

from .problems.problem import Problem
from .train.config import RunConfig


def result_resolution(cfg: RunConfig, dim: int) -> int:
    """Grid resolution for result files: ``output.resolution`` or 256 (2D) / 128 (3D)."""
    return int(cfg.output.get("resolution", 256 if dim == 2 else 128))


def write_shape_results(model: nn.Module, Z: Tensor | None, problem: Problem, cfg: RunConfig, run_dir: Path) -> list[Path]:
    """Write ``shapes/`` (2D: contour polylines + SVG/PNG per shape; 3D: one STL per shape) and
    ``figures/`` (shapes, superposition and interpolation in 2D, views in 3D, loss curves)."""
    from .export import export_shapes
    from .plot import plot_run

    run_dir = Path(run_dir)
    model.eval()
    res = result_resolution(cfg, problem.dim)
    paths = export_shapes(model, Z, problem.domain, run_dir / "shapes", res, mesh_format="stl")
    paths += plot_run(model, Z, problem, run_dir / "figures", metrics_jsonl=run_dir / "metrics.jsonl", resolution=res)
    if problem.name == "plateau":
        from .plateau import write_plateau_results

        paths += write_plateau_results(model, problem, run_dir, resolution=res)
    return paths
