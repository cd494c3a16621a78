"""Which shapes are feasible: the problem's verdicts applied to the metrics of ``ginn eval``.

A shape is feasible when every verdict of the problem (:func:`ginn.constraints.problem_verdicts`,
and those of a task's own constraints) holds:

* ``interface``: ``interface_cd1 <= tolerances.interface * unit_scale`` (problems with interfaces);
* ``volume_outside``: ``volume_outside_off_interfaces <= tolerances.volume_outside`` (the volume
  outside E beyond the interface tolerance of the interfaces, :mod:`ginn.eval.metrics`; metrics
  without it, e.g. of older runs, are judged by ``volume_outside``);
* ``connected`` (when required): ``b0_in_design_region == 1`` and ``connected_interfaces_share == 1``;
* ``topology`` (when the spec states targets): ``b1_in_design_region`` (holes in 2D, tunnels in
  3D) and ``b2_in_design_region`` (cavities) equal to them;
* ``symmetry`` (when the spec states a symmetry): ``symmetry_error <= tolerances.symmetry *
  unit_scale``.

A bound on the set rather than on each shape is reported apart (``set_violations``): with
``tolerances.diversity``, ``diversity_mean >= tolerances.diversity * unit_scale``.

The same verdicts judge the final evaluation (``ginn eval``, at the evaluation resolution) and
the check during training (:class:`FeasibilityCheck`, on a coarse grid with only the metrics the
verdicts read)::

    summary = check_feasibility(model, Z, problem, resolution=128)   # a FeasibilitySummary
    summary.feasible, summary.shapes                                 # 12, 16
    print(summary.text())
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from contextlib import contextmanager
from dataclasses import replace

import torch
from torch import Tensor

from ..config import CELLS_PER_LENGTH, default_resolution
from ..constraints.catalog import problem_verdicts, verdict_text
from ..constraints.containment import judged_volume_outside
from ..constraints.holes import BETTI_METRICS
from ..constraints.verdict import Verdict, Violation
from ..fields import Field
from ..problems.derived import length_scale, smallest_feature, structural_cells
from ..problems.problem import Problem
from .context import ExtractedShape
from .metrics import MetricContext, diversity_mean, extract_shape, prepare_context, shape_metrics
from .results import FeasibilitySummary, ShapeMetrics

__all__ = ["FEASIBILITY_METRICS", "BETTI_METRICS", "feasibility_metrics", "judged_volume_outside", "shape_violations",
           "violations", "ratios",
           "summarize", "verdict_text", "format_feasibility", "short_summary", "check_feasibility", "FeasibilityCheck", "evaluating",
           "measured", "check_resolution", "unresolved"]

#: The metrics every check measures (the worst values of a summary read them).
FEASIBILITY_METRICS = ("b0_in_design_region", "connected_interfaces_share", "interface_cd1", "volume_outside",
                       "volume_outside_off_interfaces")


def _verdicts(problem: Problem, verdicts: Sequence[Verdict] | None) -> list[Verdict]:
    return problem_verdicts(problem) if verdicts is None else list(verdicts)


def measured(metrics: ShapeMetrics, verdicts: Sequence[Verdict], shape: ExtractedShape, context: MetricContext,
             field: Field, z: Tensor | None) -> ShapeMetrics:
    """``metrics`` with what the verdicts measure themselves (:meth:`ginn.constraints.Verdict.measure`)
    in ``extra``, undefined values as None."""
    extra = dict(metrics.extra)
    for v in verdicts:
        extra.update(v.measure(shape, context, field, z))
    return replace(metrics, extra=extra).finite()


def feasibility_metrics(problem: Problem, verdicts: Sequence[Verdict] | None = None) -> tuple[str, ...]:
    """The metrics a check of ``problem`` measures: :data:`FEASIBILITY_METRICS` and those its
    verdicts read (the target Betti numbers, the symmetry error)."""
    out = list(FEASIBILITY_METRICS)
    for v in _verdicts(problem, verdicts):
        out += [m for m in v.metrics if m not in out and not v.on_set]
    return tuple(out)


def shape_violations(metrics: Mapping, problem: Problem, verdicts: Sequence[Verdict] | None = None) -> dict[str, Violation]:
    """The constraints one shape violates, ``{name: Violation}`` (empty: feasible)."""
    return {v.name: bad for v in _verdicts(problem, verdicts) if not v.on_set and (bad := v.violation(metrics)) is not None}


def violations(metrics: Mapping, problem: Problem, verdicts: Sequence[Verdict] | None = None) -> dict[str, dict]:
    """:func:`shape_violations` as JSON, ``{name: {"value": v, "bound": b}}``; ``connected`` also
    names the share of interface components reached (``interfaces``)."""
    return {k: v.to_json() for k, v in shape_violations(metrics, problem, verdicts).items()}


def ratios(metrics: Mapping, problem: Problem, verdicts: Sequence[Verdict] | None = None) -> dict[str, float]:
    """Each constraint's value over its bound for one shape (above 1: violated; ``inf`` where the
    value is undefined, e.g. the CD1 of an empty shape); the constraints that do not apply are
    left out."""
    out = {}
    for v in _verdicts(problem, verdicts):
        if not v.on_set and (r := v.ratio(metrics)) is not None:
            out[v.name] = r
    return out


def summarize(shapes: Sequence[Mapping], problem: Problem, diversity: float | None = None,
              verdicts: Sequence[Verdict] | None = None, latents: Tensor | None = None) -> FeasibilitySummary:
    """The verdict on the per-shape metrics ``shapes`` and the set's ``diversity``
    (``diversity_mean``; None: not measured or fewer than two non-empty shapes).

    ``worst``: the largest CD1, the largest volume outside E that the verdict bounds
    (:func:`judged_volume_outside`) as ``volume_outside``, and the most pieces inside E;
    ``ratios``: the largest of :func:`ratios` over the shapes, ``None`` for ``inf``, then the set
    verdicts' (a least diversity: its bound over the set's diversity). With ``latents (S, k)``
    the summary names each shape's code and its largest ratio (``latents``, ``shape_ratios``)."""
    vs = _verdicts(problem, verdicts)
    per = [shape_violations(m, problem, vs) for m in shapes]
    worst: dict = {}
    judged = [{"interface_cd1": m.get("interface_cd1"), "volume_outside": judged_volume_outside(m),
               "b0_in_design_region": m.get("b0_in_design_region")} for m in shapes]
    for k in ("interface_cd1", "volume_outside", "b0_in_design_region"):
        vals = [m[k] for m in judged if m[k] is not None]
        if vals:
            worst[k] = max(float(x) for x in vals)
    top: dict[str, float] = {}
    per_shape: list[float] = []
    for m in shapes:
        mine = 0.0
        for v in vs:
            if not v.on_set and (r := v.ratio(m)) is not None:
                top[v.name] = max(top.get(v.name, 0.0), r)
                mine = max(mine, r)
        per_shape.append(mine)
    whole = {"diversity_mean": diversity, "n_shapes": len(shapes)}
    set_violations = {}
    for v in vs:
        if v.on_set:
            if (r := v.ratio(whole)) is not None:
                top[v.name] = r
            if (bad := v.violation(whole)) is not None:
                set_violations[v.name] = bad
    named = latents is not None
    return FeasibilitySummary(sum(not v for v in per), len(shapes), per, worst,
                              {k: r if math.isfinite(r) else None for k, r in top.items()}, set_violations,
                              latents=latents.detach().double().cpu().tolist() if named else None,
                              shape_ratios=[r if math.isfinite(r) else None for r in per_shape] if named else None)


def format_feasibility(summary: FeasibilitySummary, verdicts: Sequence[Verdict] = ()) -> str:
    """One line with the count, then one line per infeasible shape naming what it violates."""
    return summary.text(verdicts)


def short_summary(summary: FeasibilitySummary) -> str:
    """A few words for a progress bar: ``12/16, worst interface 8.1e-03``."""
    return summary.short()


def check_resolution(problem: Problem, verdicts: Sequence[Verdict] | None = None) -> int:
    """The cells along the domain's longest side of the checks' grid: ``RESOLUTION['check']``, or
    ``ginn eval``'s grid (``RESOLUTION['eval']``) where a judging verdict's ``resolves`` length
    spans fewer than :data:`~ginn.config.CELLS_PER_LENGTH` cells of the former (a least thickness
    of 0.05 in a 3D domain 2 long: 1.6 cells of 64), so that the checks judge that verdict as
    ``ginn eval`` does. A ball a few cells wide is judged by the grid's luck: the bracket's shapes
    lose 1.1 to 1.4 % of their volume to the opening by a ball of 0.05 on 120 cells and 0.95 to
    1.0 % on 128.

    A problem with a ``physics`` block is judged on a grid on which an element of its structural
    grid (:func:`~ginn.problems.derived.structural_cells`) spans :data:`~ginn.config.CELLS_PER_LENGTH`
    cells, up to ``ginn eval``'s: its shapes are trusses of members an element or two thick, which
    a coarser grid cuts into pieces and whose volume it miscounts (a bell crank that ``ginn eval``
    finds in one piece within its volume bound was 7 pieces and 0.2 % over the bound on 128
    cells, one piece within the bound from 256 on), so the checks would raise and keep by what
    the shape is not."""
    d = problem.dim
    base = default_resolution("check", d)
    top = max(base, default_resolution("eval", d))
    longest = 2.0 * length_scale(problem)
    h = longest / base
    if any(v.judges and v.resolves and v.resolves < CELLS_PER_LENGTH * h for v in _verdicts(problem, verdicts)):
        return top
    if problem.physics is not None:
        element = longest / structural_cells(problem, smallest_feature(problem))
        return max(base, min(_cells_for(element, longest), top))
    return base


def _cells_for(length: float, longest: float) -> int:
    """The cells along the longest side, a multiple of 8, at which ``length`` spans
    :data:`~ginn.config.CELLS_PER_LENGTH` cells."""
    return 8 * math.ceil(math.ceil(CELLS_PER_LENGTH * longest / length - 1e-9) / 8)


def unresolved(verdicts: Sequence[Verdict], spacing, longest: float) -> dict[str, dict]:
    """The judging verdicts whose ``resolves`` length spans fewer than two cells of a grid with
    node ``spacing (d,)``: there a ball of that diameter lies within a cell of every node, the
    opening removes nothing and the closing adds nothing whatever the shape. ``{name: {"length",
    "cells" (what it spans), "resolution" (the cells along the domain's ``longest`` side at which
    it spans CELLS_PER_LENGTH)}}``."""
    h = float(min(spacing))
    return {v.name: {"length": float(v.resolves), "cells": float(v.resolves) / h,
                     "resolution": _cells_for(float(v.resolves), longest)}
            for v in verdicts if v.judges and v.resolves and v.resolves < 2.0 * h}


class FeasibilityCheck:
    """The verdicts of :func:`summarize` on a fixed grid, the metric context built once.

    Arguments:
        problem: the problem.
        resolution: grid cells along the longest axis of the domain.
        seed: of the interface samples.
        verdicts: what to judge (None: :func:`ginn.constraints.problem_verdicts`); the reports
            among them (:attr:`~ginn.constraints.Verdict.judges` False: the compliance's solve on
            its fine grid) are not measured, ``ginn eval`` measures them.
        heldout: codes ``(H, k)`` judged beside the shapes of each call (a generative model's
            latent set beyond its reported codes: the summary's ``heldout``), or None.
    """

    def __init__(self, problem: Problem, resolution: int, seed: int = 0, verdicts: Sequence[Verdict] | None = None,
                 heldout: Tensor | None = None):
        self.problem = problem
        self.resolution = resolution
        self.verdicts = _verdicts(problem, verdicts)
        self.judging = [v for v in self.verdicts if v.judges]  # the reports are left to ginn eval
        self.metrics = feasibility_metrics(problem, self.judging)
        self.context: MetricContext = prepare_context(problem, resolution, n_design_boundary_samples=0, seed=seed)
        self.seed = seed
        self.heldout = heldout

    def shape(self, field: Field, z: Tensor | None) -> tuple[ShapeMetrics, ExtractedShape]:
        """The metrics the verdicts read of the shape ``{field(., z) <= 0}`` and the extracted shape."""
        sh = extract_shape(field, z, self.context.grid)
        m = measured(shape_metrics(sh, self.context, field, z, only=self.metrics), self.judging, sh, self.context, field, z)
        return m, sh

    def latents(self, field: Field, Z: Tensor) -> FeasibilitySummary:
        """The verdict on each code of ``Z (n, k)`` on its own (no bound on the set), naming the codes."""
        per_shape = [v for v in self.verdicts if not v.on_set]
        with evaluating(field):
            shapes = [self.shape(field, Z[i])[0] for i in range(Z.shape[0])]
        return summarize(shapes, self.problem, None, per_shape, latents=Z)

    def __call__(self, field: Field, Z: Tensor | None) -> FeasibilitySummary:
        """The summary for the shapes ``{field(., z_i) <= 0}`` (``Z (S, k)`` or None), with the
        verdict at the held-out codes when the check has them."""
        with evaluating(field):
            codes = [None] if Z is None else [Z[i] for i in range(Z.shape[0])]
            shapes, boundaries = [], []
            need_diversity = any(v.on_set for v in self.verdicts)
            for z in codes:
                m, sh = self.shape(field, z)
                shapes.append(m)
                if need_diversity and sh.boundary.n_elements > 0:
                    boundaries.append(sh.boundary)
            div = diversity_mean(boundaries, seed=self.seed) if len(boundaries) > 1 else None
        summary = summarize(shapes, self.problem, div, self.verdicts)
        if self.heldout is not None and Z is not None:
            summary.heldout = self.latents(field, self.heldout.to(device=Z.device, dtype=Z.dtype))
        return summary


@contextmanager
def evaluating(field: Field):
    """``field`` in evaluation mode for the block (a module that was training is put back)."""
    was_training = field.training if isinstance(field, torch.nn.Module) else None
    if was_training:
        field.eval()
    try:
        yield field
    finally:
        if was_training:
            field.train()


def check_feasibility(field: Field, Z: Tensor | None, problem: Problem, resolution: int, seed: int = 0,
                      verdicts: Sequence[Verdict] | None = None) -> FeasibilitySummary:
    """:func:`summarize` of the shapes on a grid of ``resolution`` cells along the longest axis."""
    return FeasibilityCheck(problem, resolution, seed, verdicts)(field, Z)
