"""What a shape task does with a trained model: result files, ``ginn eval``, export, figures, explorer."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import torch
from torch import Tensor, nn

from ...config import default_resolution
from ...constraints import verdict_text
from ...constraints.compliance import ComplianceReport
from ...errors import ConfigError, GinnError
from ...eval.latent_space import LatentJudge, LatentSurvey, axis_paths, survey_latents
from ...eval.plateau import ReferenceVerdict, evaluate_plateau
from ...eval.results import FeasibilitySummary, ShapeEvaluation
from ...eval.shapes import evaluate_shapes
from ...extract.export import CONTOUR_FORMATS, export_shapes, latent_label, shape_boundary
from ...extract.grid import check_grid_memory, make_grid
from ...train.task import Results
from ...viz.explorer import write_explorer
from ...viz.plateau import write_plateau_results
from ...viz.plot import plot_run, save_shape_figure
from ...viz.structural import plot_strain_energy, strain_energy_meshes

if TYPE_CHECKING:
    from .task import ShapeTask

__all__ = ["ShapeResults", "PATH_CODES", "VERDICTS_FILE"]

#: What an export writes beside the shapes: each shape's code and verdict (JSON).
VERDICTS_FILE = "verdicts.json"

#: Codes per latent axis of the smoothness paths of a latent space of two or more dimensions, by
#: the problem's dimension (one dimension: the held-out codes are the path).
PATH_CODES = {2: 32, 3: 12}


def _code_label(i: int, z: Tensor | None) -> str:
    return "" if z is None else f"shape {i} (z = {', '.join(f'{float(v):.3g}' for v in z)}): "


class ShapeResults(Results):
    """The results of a :class:`~ginn.tasks.shape.ShapeTask` (its problem, latents and verdicts)."""

    kind = "shape"

    def __init__(self, task: ShapeTask):
        self.task = task

    @property
    def problem(self):
        return self.task.problem

    def _checked(self, resolution: int, bytes_per_node: int) -> int:
        """``resolution`` if it is a grid this machine can hold (a one-line ConfigError otherwise)."""
        if isinstance(resolution, bool) or not isinstance(resolution, int) or resolution < 2:
            raise ConfigError(f"resolution {resolution!r}: must be an integer >= 2")
        check_grid_memory(make_grid(self.problem.domain, resolution).n_nodes, bytes_per_node, f"resolution {resolution}")
        return resolution

    def _output_resolution(self, resolution: int | None = None) -> int:
        cfg = self.task.cfg
        return self._checked(resolution or cfg.output.resolution or default_resolution("output", self.problem.dim), 32)

    def finalize(self, model: nn.Module, run_dir: Path) -> list[Path]:
        """``shapes/`` (2D: contour polylines and drawings per shape; 3D: one STL per shape),
        ``figures/`` (shapes, superposition and interpolation in 2D, views in 3D, loss curves, the
        latent-space explorer ``explorer.html``, the strain-energy density of a structural
        problem: ``strain_energy.png``, in 3D also a coloured mesh per shape) and, for a problem with a minimal-surface reference,
        ``plateau/``."""
        run_dir = Path(run_dir)
        model.eval()
        res = self._output_resolution()
        paths = self._write_shapes(model, self.task.Z, run_dir / "shapes", res, "stl")
        paths += self.plot(model, run_dir, res)
        paths.append(self.view(model, run_dir / "figures" / "explorer.html", title=f"{self.problem.name}: {run_dir.name}"))
        if self.problem.reference == "minimal-surface":
            paths += write_plateau_results(model, self.problem, run_dir, resolution=res)
        if self.problem.physics is not None and self.problem.dim == 2:
            paths.append(plot_strain_energy(model, self.task.Z, self.problem, run_dir / "figures" / "strain_energy.png"))
        elif self.problem.physics is not None:
            paths += strain_energy_meshes(model, self.task.Z, self.problem, run_dir / "figures", res)
        return paths

    def evaluate(self, model: nn.Module, resolution: int | None = None, out_dir: Path | None = None,
                 heldout: int | None = None) -> ShapeEvaluation:
        """The Appendix B.1 metrics of every shape (:func:`ginn.eval.shapes.evaluate_shapes`) judged by
        the task's verdicts; for a generative model the verdict at ``heldout`` held-out codes of its
        latent set (None: :data:`ginn.config.HELDOUT_LATENTS`; 0: none) and the smoothness of
        z -> shape (:mod:`ginn.eval.latent_space`); the comparison with the reference surface where
        the problem has one."""
        res_ = self._checked(resolution or default_resolution("eval", self.problem.dim), 64)
        verdicts = self.task.verdicts()
        reports = [v for v in verdicts if isinstance(v, ComplianceReport)]
        for r in reports:  # every shape's fine-grid solve in one call, side by side on the threads
            r.prepare(model, self.task.Z)
        try:
            res = evaluate_shapes(model, self.task.Z, self.problem, res_, verdicts=verdicts)
        finally:
            for r in reports:
                r.release()
        if self.task.Z is not None and heldout != 0:
            survey = self.survey(model, res_, heldout)
            res.feasibility.heldout = survey.summary
            res.latent_space = survey.to_json()
        if self.problem.reference == "minimal-surface":
            # the reference verdict measured the single shape already
            ref = next((v for v in verdicts if isinstance(v, ReferenceVerdict)), None)
            full = ref.last(None) if ref is not None and self.task.Z is None else None
            res.reference.update(full if full is not None else evaluate_plateau(model, self.problem))
        return res

    def judge(self, resolution: int | None = None) -> LatentJudge:
        """The verdict of any code as ``ginn eval`` at ``resolution`` (default: the evaluation's) gives it."""
        res = self._checked(resolution or default_resolution("eval", self.problem.dim), 64)
        return LatentJudge(self.problem, res, self.task.verdicts())

    def survey(self, model: nn.Module, resolution: int, heldout: int | None = None) -> LatentSurvey:
        """The held-out codes' verdicts and the smoothness of z -> shape (:func:`ginn.eval.latent_space.survey_latents`)."""
        lat = self.task.cfg.latents
        codes = self.task.heldout("eval", heldout)
        paths = None if lat.dim == 1 else axis_paths(lat.low, lat.high, lat.dim, PATH_CODES[self.problem.dim])
        return survey_latents(model, codes, self.judge(resolution), paths)

    def export(self, model: nn.Module, latents: Tensor | list[list[float]] | None, out_dir: Path,
               resolution: int | None = None, mesh_format: str | None = None) -> list[Path]:
        """Meshes (3D, ``mesh_format`` stl (default), ply or obj) or contours (2D) for ``latents``
        ``(S, k)`` (None: the trained latents)."""
        if self.problem.dim == 2 and mesh_format is not None:
            raise GinnError(f"--format {mesh_format}: a 2D run exports contours (json, csv, npz, svg, png); "
                            "--format chooses the mesh format of a 3D run")
        Z = self.task.Z
        if latents is not None:
            if Z is None:
                raise GinnError("--latent: this run trained a single shape (no latent codes)")
            rows = latents.tolist() if isinstance(latents, Tensor) else latents
            k = Z.shape[1]
            if any(len(v) != k for v in rows):
                raise GinnError(f"--latent: this model takes {k} latent value(s) per shape")
            if not all(math.isfinite(float(x)) for v in rows for x in v):
                raise GinnError("--latent: latent values must be finite numbers")
            Z = torch.tensor(rows, dtype=Z.dtype, device=Z.device)
            if not bool(torch.isfinite(Z).all()):
                raise GinnError(f"--latent: latent values must be finite in the model's {str(Z.dtype).removeprefix('torch.')} "
                                f"(largest {torch.finfo(Z.dtype).max:.3g})")
        return self._write_shapes(model, Z, Path(out_dir), self._output_resolution(resolution), mesh_format or "stl")

    def verdicts_of(self, model: nn.Module, Z: Tensor | None) -> FeasibilitySummary:
        """Each code's verdict as ``ginn eval`` gives it (:meth:`judge`), the codes named."""
        judge = self.judge()
        return judge(model, None) if Z is None else judge.latents(model, Z)

    def _write_shapes(self, model: nn.Module, Z: Tensor | None, out_dir: Path, resolution: int, mesh_format: str) -> list[Path]:
        """Each shape of ``Z (S, k)`` (None: the single shape): a mesh in 3D; in 2D its contours, and
        a drawing over the problem titled with its verdict; ``verdicts.json``: each shape's verdict
        as ``ginn eval`` gives it (:meth:`verdicts_of`)."""
        p = self.problem
        summary, verdicts = self.verdicts_of(model, Z), self.task.verdicts()
        out_dir.mkdir(parents=True, exist_ok=True)
        record = out_dir / VERDICTS_FILE
        codes = [None] if Z is None else [Z[i] for i in range(Z.shape[0])]
        rows = [{"latent": None if z is None else [float(v) for v in z], "feasible": not bad,
                 "violations": {k: v.to_json() for k, v in bad.items()}, "text": _code_label(i, z) + verdict_text(bad, verdicts)}
                for i, (z, bad) in enumerate(zip(codes, summary.violations))]
        record.write_text(json.dumps({"resolution": self.judge().resolution, "shapes": rows}, indent=2) + "\n")
        if p.dim == 3:
            return export_shapes(model, Z, p.domain, out_dir, resolution, mesh_format=mesh_format) + [record]
        paths = export_shapes(model, Z, p.domain, out_dir, resolution, contour_formats=[f for f in CONTOUR_FORMATS if f != "png"])
        for i, (z, row) in enumerate(zip(codes, rows)):
            boundary, _, _ = shape_boundary(model, z, p.domain, resolution)
            name = "shape.png" if z is None else f"shape_{i:03d}_{latent_label(z)}.png"
            paths.append(save_shape_figure(boundary, p, out_dir / name, row["text"]))
        return paths + [record]

    def plot(self, model: nn.Module, run_dir: Path, resolution: int | None = None) -> list[Path]:
        """The paper-style figures into ``run_dir/figures`` (:func:`ginn.viz.plot.plot_run`)."""
        run_dir = Path(run_dir)
        if resolution is not None:
            self._checked(resolution, 32)
        Z, titles = self.task.Z, None
        if self.problem.dim == 3:  # each shape's views titled with its verdict (as ginn eval gives it)
            summary, verdicts = self.verdicts_of(model, Z), self.task.verdicts()
            codes = [None] if Z is None else [Z[i] for i in range(Z.shape[0])]
            titles = [_code_label(i, z) + verdict_text(v, verdicts) for i, (z, v) in enumerate(zip(codes, summary.violations))]
        return plot_run(model, Z, self.problem, run_dir / "figures", metrics_jsonl=run_dir / "metrics.jsonl",
                        resolution=resolution, view_titles=titles)

    def view(self, model: nn.Module, path: Path, steps: int = 64, title: str = "") -> Path:
        """The latent-space explorer (:func:`ginn.viz.explorer.write_explorer`)."""
        lat = self.task.cfg.latents
        return write_explorer(model, self.task.Z, self.problem, path, steps=steps, title=title, judge=self.judge(),
                              box=(lat.low, lat.high))
