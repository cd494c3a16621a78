"""High-level evaluation: the Appendix B.1 metrics of every shape of a (generative) model.

The front door of ``ginn eval``::

    result = evaluate_shapes(field, Z, problem, resolution=256)      # a ShapeEvaluation
    json.dump(result.to_json(), open(run_dir / "metrics.json", "w"), indent=2)
    print(result.text())
    print(format_comparison_table([r1.to_json(), r2.to_json()], ["run1", "run2"]))   # --table
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor

from ..config import default_resolution
from ..constraints.catalog import problem_verdicts
from ..constraints.verdict import Verdict
from ..extract.boundary import Boundary
from ..fields import Field
from ..problems.derived import length_scale
from ..problems.problem import Problem
from .feasibility import measured, summarize, unresolved
from .metrics import chamfer_matrix, diversity_from_matrix, extract_shape, prepare_context, shape_metrics
from .report import METRIC_LABELS, format_comparison_table, format_table
from .results import METRIC_NAMES, ShapeEvaluation

__all__ = ["evaluate_shapes", "format_table", "format_comparison_table", "METRIC_LABELS"]


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
    verdicts: Sequence[Verdict] | None = None,
) -> ShapeEvaluation:
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
        verdicts: what judges the shapes (None: :func:`ginn.constraints.problem_verdicts`).

    Returns:
        :class:`ginn.eval.results.ShapeEvaluation`: the metrics of every shape (``None`` where a
        metric does not apply or is undefined, e.g. the CD1 of an empty shape), their means
        (skipping ``None``), the diversity over the non-empty shapes and the verdict.
    """
    resolution = int(resolution or default_resolution("eval", problem.dim))
    judges = problem_verdicts(problem) if verdicts is None else list(verdicts)
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
            m = shape_metrics(sh, ctx, field, z, n_strain_samples=n_strain_samples, seed=seed + i, timings=tm)
            shapes.append(measured(m, judges, sh, ctx, field, z))
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
    measured_by_verdicts = sorted({k for s in shapes for k, v in s.extra.items()
                                   if isinstance(v, (int, float)) and not isinstance(v, bool)})
    mean = {k: _mean([s.get(k) for s in shapes]) for k in (*METRIC_NAMES, *measured_by_verdicts)}
    summary = summarize(shapes, problem, div, judges)
    return ShapeEvaluation(problem.name, shapes, mean, div, summary, verdicts=judges,
                           unresolved=unresolved(judges, ctx.grid.spacing, 2.0 * length_scale(problem)))


