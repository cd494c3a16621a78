"""The objective of a sweep trial: a weighted sum of the metrics of ``ginn eval``.

See :mod:`ginn.sweep` for the definitions.
"""

from __future__ import annotations

import math

__all__ = ["DEFAULT_OBJECTIVE", "MISSING_PENALTY", "metric_value", "objective_value"]

DEFAULT_OBJECTIVE: dict[str, float] = {"b0_error": 1.0, "ci_missing": 1.0, "interface_cd1": 10.0, "diversity_mean": -1.0}
MISSING_PENALTY = 100.0
_LENGTH_METRICS = {"interface_cd1", "diversity_mean"}


def metric_value(result: dict, name: str, unit_scale: float = 1.0) -> float | None:
    """One named metric of a ``ginn eval`` result (see the module docstring), or None if missing."""
    mean = result.get("mean") or {}
    if name == "b0_error":
        vals = [s.get("b0") for s in result.get("shapes", [])]
        if not vals or any(v is None for v in vals):
            return None
        return float(sum(abs(float(v) - 1.0) for v in vals) / len(vals))
    if name == "ci_missing":
        v = mean.get("connected_interfaces_share")
        return None if v is None else 1.0 - float(v)
    v = mean.get(name, result.get(name))
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    v = float(v)
    return v / unit_scale if name in _LENGTH_METRICS else v


def objective_value(result: dict, weights: dict[str, float], unit_scale: float = 1.0) -> tuple[float, dict[str, float | None]]:
    """``sum_k w_k m_k`` (missing or non-finite: ``|w_k| * MISSING_PENALTY``) and the metrics used.

    ``diversity_mean`` is skipped for a single-shape result (it does not apply).
    """
    total, used = 0.0, {}
    for name, w in weights.items():
        if name == "diversity_mean" and result.get("n_shapes", 2) < 2:
            continue
        v = metric_value(result, name, unit_scale)
        used[name] = v
        total += abs(w) * MISSING_PENALTY if v is None or not math.isfinite(v) else w * v
    return total, used
