"""High-level evaluation: the Appendix B.1 metrics of every shape of a (generative) model.

The front door of ``ginn eval``::

    result = evaluate_shapes(field, Z, problem, resolution=256)
    json.dump(result, open(run_dir / "metrics.json", "w"), indent=2)
    print(format_table(result))
    print(format_comparison_table([r1, r2], ["run1", "run2"]))   # --table
"""

from __future__ import annotations

import math
import time

import numpy as np
import torch
from torch import Tensor

from ..config import default_resolution
from ..extract.boundary import Boundary
from ..fields import Field
from ..problems.problem import Problem
from .feasibility import format_feasibility, summarize
from .metrics import (
    METRIC_NAMES,
    chamfer_matrix,
    diversity_from_matrix,
    extract_shape,
    prepare_context,
    shape_metrics,
)

__all__ = ["evaluate_shapes", "format_table", "format_comparison_table", "METRIC_LABELS"]

#: Paper-style row labels (arrow: which direction is better).
METRIC_LABELS = {
    "b0": "↓ b0(Ω)",
    "b0_in_design_region": "↓ b0(Ω ∩ E)",
    "b1_in_design_region": "b1(Ω ∩ E) (holes / tunnels)",
    "b2_in_design_region": "b2(Ω ∩ E) (cavities)",
    "genus": "genus of the mesh",
    "disconnected_volume": "↓ vol(DC(Ω)) / vol(E)",
    "disconnected_volume_in_design_region": "↓ vol(DC(Ω ∩ E)) / vol(E)",
    "connected_interfaces_share": "↑ CI(Ω, I) / n_I",
    "interface_cd1": "↓ CD1(Ω, I)",
    "boundary_overlap": "↓ vol(Ω ∩ ∂E) / vol(∂E)",
    "volume_outside": "↓ vol(Ω \\ E) / vol(X \\ E)",
    "volume_outside_off_interfaces": "↓ vol(Ω \\ (E ∪ I_h)) / vol(X \\ E)",
    "surface_strain": "↓ E_strain(Ω)",
    "symmetry_error": "↓ symmetry error",
    "diversity_mean": "↑ δ_mean(S)",
}


def _finite_or_none(v):
    """JSON has no infinity: undefined values (e.g. the CD1 of an empty shape) become None."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _mean(values: list) -> float | None:
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    return float(np.mean(v)) if v else None


def evaluate_shapes(
    field: Field,
    Z: Tensor | None,
    problem: Problem,
    resolution: int | None = None,
    *,
    adaptive: bool = True,
    n_interface_samples: int = 4096,
    n_strain_samples: int = 2048,
    n_diversity_samples: int = 2048,
    seed: int = 0,
    timings: dict | None = None,
) -> dict:
    """Every metric of Appendix B.1 for the shapes ``{f(., z_i) <= 0}``.

    Arguments:
        field: callable ``(x, z) -> (n,)`` (a trained model, or an exact SDF via ``as_field``).
        Z: latent codes ``(S, k)``, or None for a single (unconditioned) shape.
        problem: the problem the shapes were trained for.
        resolution: grid cells along the longest domain axis (default: ``ginn.config.RESOLUTION['eval']``).
        adaptive: adaptive grid sampling (see :func:`ginn.extract.sampling.sample_field`).
        n_interface_samples, n_strain_samples, n_diversity_samples: Monte-Carlo sample counts.
        seed: seed of every sample (results are deterministic).
        timings: optional dict that receives the seconds spent per stage / metric.

    Returns:
        ``{"problem": name, "n_shapes": S, "shapes": [{metric: value}], "mean": {metric: value},
        "diversity_mean": value or None, "feasibility": :func:`ginn.eval.feasibility.summarize`}``
        (strict JSON; ``None`` where a metric does not apply or
        is undefined, e.g. the CD1 of an empty shape; means skip ``None``; the diversity is taken
        over the non-empty shapes).
    """
    resolution = int(resolution or default_resolution("eval", problem.dim))
    tm = timings if timings is not None else {}
    t0 = time.perf_counter()
    ctx = prepare_context(problem, resolution, n_interface_samples=n_interface_samples, seed=seed)
    tm["prepare"] = tm.get("prepare", 0.0) + time.perf_counter() - t0
    was_training = None
    if isinstance(field, torch.nn.Module):
        was_training = field.training
        field.eval()
    codes = [None] if Z is None else [Z[i] for i in range(Z.shape[0])]
    shapes, boundaries, samples = [], [], []
    try:
        for i, z in enumerate(codes):
            t = time.perf_counter()
            sh = extract_shape(field, z, ctx.grid, adaptive=adaptive, timings=tm)
            tm["extract"] = tm.get("extract", 0.0) + time.perf_counter() - t
            shapes.append(shape_metrics(sh, ctx, field, z, n_strain_samples=n_strain_samples, seed=seed + i, timings=tm))
            if len(codes) > 1:
                # keep a compact copy (float32 / int32, no KD-tree) for the diversity
                b = sh.boundary
                b = Boundary(b.vertices.astype(np.float32), b.elements.astype(np.int32), b.on_level_set)
                boundaries.append(b)
                samples.append(b.sample(n_diversity_samples, np.random.default_rng(seed + i)))
            del sh
    finally:
        if was_training:
            field.train()
    div = None
    keep = [i for i, b in enumerate(boundaries) if b.n_elements > 0]  # empty shapes have no boundary
    if len(keep) > 1:
        t = time.perf_counter()
        div = diversity_from_matrix(chamfer_matrix([boundaries[i] for i in keep], [samples[i] for i in keep]))
        tm["diversity_mean"] = tm.get("diversity_mean", 0.0) + time.perf_counter() - t
    shapes = [{k: _finite_or_none(v) for k, v in s.items()} for s in shapes]
    mean = {k: _mean([s[k] for s in shapes]) for k in METRIC_NAMES}
    return {
        "problem": problem.name,
        "n_shapes": len(shapes),
        "shapes": shapes,
        "mean": mean,
        "diversity_mean": div,
        "feasibility": summarize(shapes, problem, div),
    }


def _fmt(v) -> str:
    if v is None:
        return "–"
    v = float(v)
    if not math.isfinite(v):
        return str(v)
    if v == 0:
        return "0"
    if abs(v) >= 1e4 or abs(v) < 1e-3:
        return f"{v:.2e}"
    return f"{v:.4g}"


def format_table(result: dict) -> str:
    """A readable markdown table of one evaluation: mean, min and max over the shapes."""
    lines = [
        f"problem: {result.get('problem')}   shapes: {result.get('n_shapes')}",
        "",
        "| metric | mean | min | max |",
        "|---|---|---|---|",
    ]
    for k in METRIC_NAMES:
        vals = [s.get(k) for s in result.get("shapes", []) if s.get(k) is not None]
        lo = min(vals) if vals else None
        hi = max(vals) if vals else None
        lines.append(f"| {METRIC_LABELS[k]} | {_fmt(result['mean'].get(k))} | {_fmt(lo)} | {_fmt(hi)} |")
    lines.append(f"| {METRIC_LABELS['diversity_mean']} | {_fmt(result.get('diversity_mean'))} | | |")
    if result.get("feasibility") is not None:
        lines += ["", format_feasibility(result["feasibility"])]
    return "\n".join(lines)


def format_comparison_table(results: list[dict], names: list[str]) -> str:
    """Paper-style markdown table (Tables 3 and 4): one row per metric (means over shapes), one
    column per run."""
    if len(results) != len(names):
        raise ValueError("one name per result")
    lines = ["| metric | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    lines.append("| shapes | " + " | ".join(str(r.get("n_shapes")) for r in results) + " |")
    for k in METRIC_NAMES:
        lines.append(f"| {METRIC_LABELS[k]} | " + " | ".join(_fmt(r["mean"].get(k)) for r in results) + " |")
    lines.append(
        f"| {METRIC_LABELS['diversity_mean']} | " + " | ".join(_fmt(r.get("diversity_mean")) for r in results) + " |"
    )
    return "\n".join(lines)
