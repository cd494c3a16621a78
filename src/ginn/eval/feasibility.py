"""Which shapes are feasible: the problem's tolerances applied to the metrics of ``ginn eval``.

A shape is feasible when every constraint of :class:`~ginn.problems.problem.Tolerances` holds:

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

The same function judges the final evaluation (``ginn eval``, at the evaluation resolution) and
the check during training (:func:`check_feasibility`, on a coarse grid with only these metrics)::

    summary = check_feasibility(model, Z, problem, resolution=128)
    summary["feasible"], summary["shapes"]          # 12, 16
    print(format_feasibility(summary))
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from ..fields import Field
from ..problems.problem import Problem
from .metrics import MetricContext, diversity_mean, extract_shape, prepare_context, shape_metrics

__all__ = ["FEASIBILITY_METRICS", "BETTI_METRICS", "feasibility_metrics", "judged_volume_outside", "violations", "ratios",
           "summarize", "verdict_text", "format_feasibility", "short_summary", "check_feasibility", "FeasibilityCheck"]

#: The metrics the verdict reads.
FEASIBILITY_METRICS = ("b0_in_design_region", "connected_interfaces_share", "interface_cd1", "volume_outside",
                       "volume_outside_off_interfaces")


def judged_volume_outside(metrics: dict) -> float | None:
    """The volume outside E that the verdict bounds: ``volume_outside_off_interfaces`` where
    measured, else ``volume_outside``."""
    v = metrics.get("volume_outside_off_interfaces")
    return metrics.get("volume_outside") if v is None else v


#: The metric of each target Betti number.
BETTI_METRICS = {1: "b1_in_design_region", 2: "b2_in_design_region"}


def feasibility_metrics(problem: Problem) -> tuple[str, ...]:
    """The metrics the verdict of ``problem`` reads: :data:`FEASIBILITY_METRICS`, those of its
    topology targets and, with a symmetry, ``symmetry_error``."""
    extra = ("symmetry_error",) if problem.symmetry is not None else ()
    return FEASIBILITY_METRICS + tuple(BETTI_METRICS[k] for k in sorted(problem.topology.targets)) + extra


def _betti_names(dim: int) -> dict[int, str]:
    return {1: "holes"} if dim == 2 else {1: "tunnels", 2: "cavities"}


def _topology_off(metrics: dict, problem: Problem) -> dict[str, tuple[int | None, int]]:
    """``{name: (measured, target)}`` for each target Betti number the shape misses."""
    names = _betti_names(problem.dim)
    out = {}
    for k, target in sorted(problem.topology.targets.items()):
        got = metrics.get(BETTI_METRICS[k])
        if got is None or int(got) != target:
            out[names[k]] = (None if got is None else int(got), target)
    return out


def violations(metrics: dict, problem: Problem) -> dict[str, dict]:
    """The constraints one shape violates, ``{name: {"value": v, "bound": b}}`` (empty: feasible).

    ``metrics`` holds at least :data:`FEASIBILITY_METRICS` (``None`` where a metric does not apply).
    ``connected`` reports the number of pieces inside E as its value (bound 1) and, when the pieces
    miss interfaces, the share of interface components reached as ``interfaces``.
    """
    tol = problem.tolerances
    out: dict[str, dict] = {}
    cd1 = metrics.get("interface_cd1")
    if problem.interfaces and (cd1 is None or not math.isfinite(cd1) or cd1 > tol.interface * problem.unit_scale):
        # value None: no boundary to measure from (an empty shape)
        value = float(cd1) if cd1 is not None and math.isfinite(cd1) else None
        out["interface"] = {"value": value, "bound": tol.interface * problem.unit_scale}
    vol = judged_volume_outside(metrics)
    if vol is not None and vol > tol.volume_outside:
        out["volume_outside"] = {"value": float(vol), "bound": tol.volume_outside}
    if tol.connected:
        pieces = metrics.get("b0_in_design_region")
        share = metrics.get("connected_interfaces_share")
        if pieces != 1 or (share is not None and share < 1.0 - 1e-12):
            v = {"value": int(pieces) if pieces is not None else 0, "bound": 1}
            if share is not None:
                v["interfaces"] = float(share)
            out["connected"] = v
    off = _topology_off(metrics, problem)
    if off:
        out["topology"] = {"value": {k: v[0] for k, v in off.items()}, "bound": {k: v[1] for k, v in off.items()}}
    sym = metrics.get("symmetry_error")
    if problem.symmetry is not None and sym is not None and sym > tol.symmetry * problem.unit_scale:
        out["symmetry"] = {"value": float(sym), "bound": tol.symmetry * problem.unit_scale}
    return out


def ratios(metrics: dict, problem: Problem) -> dict[str, float]:
    """Each constraint's value over its bound for one shape (above 1: violated; ``inf`` where the
    value is undefined, e.g. the CD1 of an empty shape). ``connected``: the number of pieces inside
    E, or the inverse share of interface components its pieces reach if that is larger (1 when
    met, 0 pieces count as ``inf``). ``topology``: 1 plus the total miss of the target Betti
    numbers."""
    tol = problem.tolerances
    out: dict[str, float] = {}
    if problem.interfaces:
        cd1 = metrics.get("interface_cd1")
        ok = cd1 is not None and math.isfinite(cd1)
        out["interface"] = float(cd1) / (tol.interface * problem.unit_scale) if ok else math.inf
    vol = judged_volume_outside(metrics)
    if vol is not None:
        out["volume_outside"] = float(vol) / tol.volume_outside
    if tol.connected:
        pieces = metrics.get("b0_in_design_region")
        share = metrics.get("connected_interfaces_share")
        if not pieces:
            out["connected"] = math.inf
        else:
            missed = 1.0 / share if share is not None and share > 0 else (math.inf if share is not None else 1.0)
            out["connected"] = max(float(pieces), missed)
    if problem.topology.targets:
        off = _topology_off(metrics, problem).values()
        out["topology"] = math.inf if any(g is None for g, _ in off) else 1.0 + sum(abs(g - t) for g, t in off)
    sym = metrics.get("symmetry_error")
    if problem.symmetry is not None and sym is not None:
        out["symmetry"] = float(sym) / (tol.symmetry * problem.unit_scale)
    return out


def summarize(shapes: list[dict], problem: Problem, diversity: float | None = None) -> dict:
    """``{"feasible": k, "shapes": S, "violations": [per shape], "worst": {name: value},
    "ratios": {constraint: value / bound}, "set_violations": {...}}`` for the per-shape metric
    dicts ``shapes`` and the set's ``diversity`` (``diversity_mean``; None: not measured or
    fewer than two non-empty shapes). ``worst``: the largest CD1, the largest volume outside E
    that the verdict bounds (:func:`judged_volume_outside`) as ``volume_outside``, and the most
    pieces inside E; ``ratios``: the largest of :func:`ratios` over the shapes, ``None`` for
    ``inf``, and with ``tolerances.diversity`` its bound over the set's diversity as
    ``diversity``; ``set_violations``: ``{"diversity": {"value", "bound"}}`` when the set is less
    diverse than that (empty otherwise)."""
    per = [violations(m, problem) for m in shapes]
    worst: dict = {}
    judged = [{**m, "volume_outside": judged_volume_outside(m)} for m in shapes]
    for k in ("interface_cd1", "volume_outside", "b0_in_design_region"):
        vals = [m.get(k) for m in judged if m.get(k) is not None]
        if vals:
            worst[k] = max(float(v) for v in vals)
    top: dict[str, float] = {}
    for r in (ratios(m, problem) for m in shapes):
        for k, v in r.items():
            top[k] = max(top.get(k, 0.0), v)
    set_violations: dict[str, dict] = {}
    least = problem.tolerances.diversity
    if least is not None and len(shapes) > 1:
        bound = least * problem.unit_scale
        top["diversity"] = bound / diversity if diversity is not None and diversity > 0 else math.inf
        if diversity is None or diversity < bound:
            set_violations["diversity"] = {"value": diversity, "bound": bound}
    return {"feasible": sum(not v for v in per), "shapes": len(shapes), "violations": per, "worst": worst,
            "ratios": {k: v if math.isfinite(v) else None for k, v in top.items()},
            "set_violations": set_violations}


def _num(v: float | None) -> str:
    return "undefined (no boundary)" if v is None else f"{v:.3g}"


def verdict_text(violated: dict[str, dict]) -> str:
    """``feasible``, or each violated constraint of :func:`violations` with its value and bound."""
    if not violated:
        return "feasible"
    parts = []
    for name, d in violated.items():
        if name == "connected":
            text = f"connected: {d['value']} piece{'' if d['value'] == 1 else 's'} inside E"
            if d.get("interfaces") is not None and d["interfaces"] < 1:
                text += f", {100 * d['interfaces']:.0f} % of the interfaces reached by one piece"
            parts.append(text)
        elif name == "topology":
            singular = {"holes": "hole", "tunnels": "tunnel", "cavities": "cavity"}
            parts.append("topology: " + ", ".join(
                f"{v if v is not None else 'undefined'} {singular[k] if v == 1 else k} (want {d['bound'][k]})"
                for k, v in d["value"].items()))
        else:
            parts.append(f"{name} {_num(d['value'])} > {_num(d['bound'])}")
    return "; ".join(parts)


def format_feasibility(summary: dict) -> str:
    """One line with the count, then one line per infeasible shape naming what it violates."""
    lines = [f"feasible shapes: {summary['feasible']} of {summary['shapes']}"]
    lines += [f"  shape {i}: {verdict_text(v)}" for i, v in enumerate(summary["violations"]) if v]
    for name, d in (summary.get("set_violations") or {}).items():
        lines.append(f"  the set: {name} {_num(d['value'])} < {_num(d['bound'])}")
    return "\n".join(lines)


def short_summary(summary: dict) -> str:
    """A few words for a progress bar: ``12/16, worst interface 8.1e-03``."""
    text = f"{summary['feasible']}/{summary['shapes']}"
    worst = summary["worst"]
    if "interface_cd1" in worst:
        text += f", worst interface {worst['interface_cd1']:.1e}"
    if "volume_outside" in worst:
        text += f", outside {worst['volume_outside']:.1e}"
    return text


class FeasibilityCheck:
    """The verdicts of :func:`summarize` on a fixed grid, the metric context built once.

    Arguments:
        problem: the problem.
        resolution: grid cells along the longest axis of the domain.
        seed: of the interface samples.
    """

    def __init__(self, problem: Problem, resolution: int, seed: int = 0):
        self.problem = problem
        self.metrics = feasibility_metrics(problem)
        self.context: MetricContext = prepare_context(problem, resolution, n_design_boundary_samples=0, seed=seed)
        self.seed = seed

    def __call__(self, field: Field, Z: Tensor | None) -> dict:
        """The summary for the shapes ``{field(., z_i) <= 0}`` (``Z (S, k)`` or None)."""
        was_training = field.training if isinstance(field, torch.nn.Module) else None
        if was_training:
            field.eval()
        try:
            codes = [None] if Z is None else [Z[i] for i in range(Z.shape[0])]
            shapes, boundaries = [], []
            for z in codes:
                sh = extract_shape(field, z, self.context.grid)
                shapes.append(shape_metrics(sh, self.context, field, z, only=self.metrics))
                if self.problem.tolerances.diversity is not None and sh.boundary.n_elements > 0:
                    boundaries.append(sh.boundary)
            div = diversity_mean(boundaries, seed=self.seed) if len(boundaries) > 1 else None
        finally:
            if was_training:
                field.train()
        # as in ginn eval: undefined values (the CD1 of an empty shape) are None, JSON has no infinity
        shapes = [{k: v if not isinstance(v, float) or math.isfinite(v) else None for k, v in m.items()} for m in shapes]
        return summarize(shapes, self.problem, div)


def check_feasibility(field: Field, Z: Tensor | None, problem: Problem, resolution: int, seed: int = 0) -> dict:
    """:func:`summarize` of the shapes on a grid of ``resolution`` cells along the longest axis."""
    return FeasibilityCheck(problem, resolution, seed)(field, Z)
