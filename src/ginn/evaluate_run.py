"""``ginn eval``, ``ginn export`` and ``ginn plot`` on a run directory, for every task kind."""

from __future__ import annotations

import json
from pathlib import Path

import torch

from .errors import GinnError


def _write_json(path: Path, data: dict) -> None:
    path.write_text(json.dumps(data, indent=2, default=float))


def evaluate_run_dir(run_dir: Path, resolution: int | None = None, device: str | None = None) -> dict:
    """Compute the metrics of a run, write ``RUN/metrics.json`` and return them.

    The returned dict also holds ``"_text"``: a readable table for the terminal (not written).
    """
    from .train.run import load_run

    run = load_run(run_dir, device=device)
    kind = getattr(run.spec, "kind", "shape")
    if kind == "shape":
        from .evaluation import evaluate_shapes, format_table

        problem = run.task.problem
        res = evaluate_shapes(run.model, run.latents, problem, resolution)
        if problem.name == "plateau" or problem.extra.get("plateau_reference"):
            from .plateau import evaluate_plateau

            res.update(evaluate_plateau(run.model, problem))
        text = format_table(res)
        extra = {k: v for k, v in res.items() if k not in ("problem", "n_shapes", "shapes", "mean", "diversity_mean")}
        if extra:
            text += "\n" + "\n".join(f"{k}: {v}" for k, v in extra.items())
    elif kind == "mirror":
        from .mirror import evaluate_mirror

        res = {"problem": "mirror", **evaluate_mirror(run.model, run.task.params)}
        text = "\n".join(f"{k}: {v}" for k, v in res.items())
    elif kind == "gray-scott":
        from .pinn.verify import verify_run

        res = verify_run(run.model, run.latents, run.task.params, resolution=resolution or 256, out_dir=run.path)
        res = {"problem": "gray-scott", **res}
        text = json.dumps({k: v for k, v in res.items() if k != "latents"}, indent=2, default=float)
    else:  # pragma: no cover - registry rejects unknown kinds earlier
        raise GinnError(f"cannot evaluate a run of kind {kind!r}")
    _write_json(run_dir / "metrics.json", res)
    out = dict(res)
    out["_text"] = text + f"\n(written to {run_dir / 'metrics.json'})"
    return out


def print_table(results: list[dict], names: list[str]) -> None:
    from .evaluation import format_comparison_table

    shape_results = [r for r in results if "mean" in r]
    if len(shape_results) != len(results):
        raise GinnError("--table compares shape runs only")
    print(format_comparison_table(shape_results, names))


def export_run_dir(run_dir: Path, latents: list[list[float]] | None, resolution: int | None, fmt: str, out: str | None) -> list[Path]:
    """Meshes (3D) or contours (2D) for the trained latents, or for the given latent values."""
    from .export import export_shapes
    from .results import result_resolution
    from .train.run import load_run

    run = load_run(run_dir)
    if getattr(run.spec, "kind", "shape") != "shape":
        raise GinnError("export works on shape runs (mirror and gray-scott write their results at the end of training)")
    problem = run.task.problem
    Z = run.latents
    if latents:
        if Z is None:
            raise GinnError("--latent: this run trained a single shape (no latent codes)")
        k = Z.shape[1]
        if any(len(v) != k for v in latents):
            raise GinnError(f"--latent: this model takes {k} latent value(s) per shape")
        Z = torch.tensor(latents, dtype=Z.dtype, device=Z.device)
    res = resolution or result_resolution(run.config, problem.dim)
    out_dir = Path(out) if out else Path(run_dir) / "export"
    return export_shapes(run.model, Z, problem.domain, out_dir, res, mesh_format=fmt)


def plot_run_dir(run_dir: Path, resolution: int | None = None) -> list[Path]:
    """The paper-style figures of a shape run into ``RUN/figures``."""
    from .plot import plot_run
    from .train.run import load_run

    run = load_run(run_dir)
    if getattr(run.spec, "kind", "shape") != "shape":
        paths = run.task.finalize(run.model, Path(run_dir))
        return paths
    return plot_run(run.model, run.latents, run.task.problem, Path(run_dir) / "figures",
                    metrics_jsonl=Path(run_dir) / "metrics.jsonl", resolution=resolution)
