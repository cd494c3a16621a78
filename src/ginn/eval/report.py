"""Readable tables of ``ginn eval``: one evaluation's metrics (mean, min, max over the shapes) and
paper-style comparisons of runs (Tables 3 and 4)."""

from __future__ import annotations

import math

__all__ = ["METRIC_LABELS", "format_table", "format_comparison_table"]

#: Paper-style row labels (arrow: which direction is better), the per-shape metrics in the order of
#: :data:`ginn.eval.results.METRIC_NAMES`, then the set's diversity.
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
    "interface_cd1_worst": "CD1 of the worst-met interface",
    "boundary_overlap": "↓ vol(Ω ∩ ∂E) / vol(∂E)",
    "volume_outside": "↓ vol(Ω \\ E) / vol(X \\ E)",
    "volume_outside_off_interfaces": "↓ vol(Ω \\ (E ∪ I_h)) / vol(X \\ E)",
    "volume_fraction": "vol(Ω ∩ E) / vol(E)",
    "surface_strain": "↓ E_strain(Ω)",
    "symmetry_error": "↓ symmetry error",
    "boundary_area": "area (2D: length) of ∂Ω",
    "thickness_removed": "↓ vol(Ω minus its opening by the min-thickness ball) / vol(Ω)",
    "gap_filled": "↓ vol(closing of Ω by the min-gap ball minus Ω) / vol(Ω)",
    "overhang_share": "↓ overhanging share of the down-facing boundary",
    "sharp_share": "↓ share of the boundary sharper than the fillet radius",
    "curvature_max": "largest principal curvature |κ|",
    "face_deviation": "↓ faces: largest angle (distance) / allowed",
    "compliance": "↓ compliance (weighted over the load cases)",
    "max_displacement": "largest displacement",
    "cd2_to_reference": "↓ CD2 to the reference surface",
    "area_relative_error": "area / reference area - 1",
    "diversity_mean": "↑ δ_mean(S)",
}

_ROWS = tuple(k for k in METRIC_LABELS if k != "diversity_mean")
#: rows shown only where a run measures them (the verdicts of some tolerances measure them)
_OPTIONAL = ("boundary_area", "thickness_removed", "gap_filled", "overhang_share", "sharp_share", "curvature_max", "face_deviation",
             "compliance", "max_displacement", "cd2_to_reference", "area_relative_error")


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


def format_table(result: dict, feasibility: str | None = None) -> str:
    """A readable markdown table of one evaluation (the JSON of ``metrics.json``): mean, min and
    max over the shapes, then ``feasibility`` (the verdict's lines)."""
    lines = [
        f"problem: {result.get('problem')}   shapes: {result.get('n_shapes')}",
        "",
        "| metric | mean | min | max |",
        "|---|---|---|---|",
    ]
    for k in _ROWS:
        vals = [s.get(k) for s in result.get("shapes", []) if s.get(k) is not None]
        if k in _OPTIONAL and not vals:
            continue
        lo = min(vals) if vals else None
        hi = max(vals) if vals else None
        lines.append(f"| {METRIC_LABELS[k]} | {_fmt(result['mean'].get(k))} | {_fmt(lo)} | {_fmt(hi)} |")
    lines.append(f"| {METRIC_LABELS['diversity_mean']} | {_fmt(result.get('diversity_mean'))} | | |")
    if feasibility:
        lines += ["", feasibility]
    return "\n".join(lines)


def format_comparison_table(results: list[dict], names: list[str]) -> str:
    """Paper-style markdown table (Tables 3 and 4): one row per metric (means over shapes), one
    column per run."""
    if len(results) != len(names):
        raise ValueError("one name per result")
    lines = ["| metric | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    lines.append("| shapes | " + " | ".join(str(r.get("n_shapes")) for r in results) + " |")
    for k in _ROWS:
        if k in _OPTIONAL and all(r["mean"].get(k) is None for r in results):
            continue
        lines.append(f"| {METRIC_LABELS[k]} | " + " | ".join(_fmt(r["mean"].get(k)) for r in results) + " |")
    lines.append(
        f"| {METRIC_LABELS['diversity_mean']} | " + " | ".join(_fmt(r.get("diversity_mean")) for r in results) + " |"
    )
    return "\n".join(lines)
