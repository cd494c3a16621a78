"""The search space of a sweep: a YAML file mapping dotted config keys to distributions.

See :mod:`ginn.sweep` for the file format.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import build_config, nested
from ..errors import ConfigError
from ..yamlfile import load_yaml
from .objective import DEFAULT_OBJECTIVE

__all__ = ["SearchSpace", "parse_space", "load_space", "check_space_keys", "suggest"]

_OPTIONS = {"objective", "direction", "sampler", "pruner", "report_every", "intermediate", "eval_resolution", "seed", "params"}
_DIST_KEYS = {"float": {"type", "low", "high", "log", "step"}, "int": {"type", "low", "high", "log", "step"},
              "categorical": {"type", "choices"}}


@dataclass(frozen=True)
class SearchSpace:
    """A parsed search space file.

    Attributes:
        params: dotted config key -> distribution dict (``type`` float/int/categorical, ...).
        objective: metric name -> weight (minimised sum).
        direction, sampler, pruner: Optuna settings.
        report_every: iterations between intermediate values (None: iterations / 10).
        intermediate: unweighted loss terms summed as the intermediate value (None: the
            constraint terms interface, design_region, obstacle that the task has).
        eval_resolution: evaluation grid resolution (None: ``ginn eval``'s default).
        seed: sampler seed or None.
    """

    params: dict[str, dict]
    objective: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_OBJECTIVE))
    direction: str = "minimize"
    sampler: str = "tpe"
    pruner: str = "median"
    report_every: int | None = None
    intermediate: tuple[str, ...] | None = None
    eval_resolution: int | None = None
    seed: int | None = None


def _check_dist(key: str, d: Any) -> dict:
    where = f"search space {key!r}"
    if not isinstance(d, dict) or "type" not in d:
        raise ConfigError(f"{where}: expected a mapping with 'type' (float, int or categorical)")
    kind = d["type"]
    if kind not in _DIST_KEYS:
        raise ConfigError(f"{where}: unknown type {kind!r} (float, int, categorical)")
    extra = set(d) - _DIST_KEYS[kind]
    if extra:
        raise ConfigError(f"{where}: unknown field {sorted(extra)[0]!r} for type {kind}")
    if kind == "categorical":
        ch = d.get("choices")
        if not isinstance(ch, list) or not ch:
            raise ConfigError(f"{where}: 'choices' must be a non-empty list")
        return {"type": kind, "choices": ch}
    if "low" not in d or "high" not in d:
        raise ConfigError(f"{where}: {kind} needs 'low' and 'high'")
    num = int if kind == "int" else float
    try:
        low, high = num(d["low"]), num(d["high"])
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: 'low' and 'high' must be numbers") from None
    if kind == "int" and (low != d["low"] or high != d["high"]):
        raise ConfigError(f"{where}: int bounds must be integers")
    if not (math.isfinite(low) and math.isfinite(high)) or low > high:
        raise ConfigError(f"{where}: need finite low <= high (got {d['low']}, {d['high']})")
    log = d.get("log", False)
    if not isinstance(log, bool):
        raise ConfigError(f"{where}: 'log' must be true or false")
    if log and low <= 0:
        raise ConfigError(f"{where}: log scale needs low > 0")
    out = {"type": kind, "low": low, "high": high, "log": log}
    if "step" in d:
        if log:
            raise ConfigError(f"{where}: 'step' and 'log' cannot be combined")
        try:
            step = num(d["step"])
        except (TypeError, ValueError):
            raise ConfigError(f"{where}: 'step' must be a number") from None
        if step <= 0:
            raise ConfigError(f"{where}: 'step' must be > 0")
        out["step"] = step
    return out


def parse_space(data: Any, source: str = "search space") -> SearchSpace:
    """Validate a search space mapping (see the module docstring). Raises :class:`ConfigError`."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping of config keys to distributions")
    raw = dict(data.get("params") or {})
    if not isinstance(raw, dict):
        raise ConfigError(f"{source}: 'params' must be a mapping")
    raw.update({k: v for k, v in data.items() if k not in _OPTIONS})
    params = {str(k): _check_dist(str(k), v) for k, v in raw.items()}
    if not params:
        raise ConfigError(f"{source}: no parameters to search")
    kw: dict[str, Any] = {}
    if "objective" in data:
        obj = data["objective"]
        if not isinstance(obj, dict) or not obj:
            raise ConfigError(f"{source}: 'objective' must map metric names to weights")
        try:
            kw["objective"] = {str(k): float(v) for k, v in obj.items()}
        except (TypeError, ValueError):
            raise ConfigError(f"{source}: objective weights must be numbers") from None
    for name, choices in (("direction", ("minimize", "maximize")), ("sampler", ("tpe", "random")), ("pruner", ("median", "none"))):
        if name in data:
            if data[name] not in choices:
                raise ConfigError(f"{source}: {name} must be one of {', '.join(choices)} (got {data[name]!r})")
            kw[name] = data[name]
    for name in ("report_every", "eval_resolution", "seed"):
        if name in data:
            v = data[name]
            if not isinstance(v, int) or isinstance(v, bool) or (v < 1 and name != "seed"):
                raise ConfigError(f"{source}: {name} must be a positive integer")
            kw[name] = v
    if "intermediate" in data:
        v = data["intermediate"]
        v = [v] if isinstance(v, str) else v
        if not isinstance(v, list) or not v or not all(isinstance(x, str) for x in v):
            raise ConfigError(f"{source}: 'intermediate' must be a loss term name or a list of them")
        kw["intermediate"] = tuple(v)
    return SearchSpace(params=params, **kw)


def load_space(path: str | Path) -> SearchSpace:
    """Read and validate a search space YAML file. Raises :class:`ConfigError` (one line)."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"--space {p}: no such file")
    try:
        data = load_yaml(p.read_text(), f"--space {p}")
    except ConfigError as e:
        raise ConfigError(f"--space {p}: not valid YAML ({str(e).removeprefix(f'--space {p}: ')})") from None
    return parse_space(data, f"--space {p}")


def check_space_keys(space: SearchSpace, base: dict) -> None:
    """Every parameter must be a valid config key at its bounds/choices (one-line ConfigError)."""
    for key, d in space.params.items():
        values = d["choices"] if d["type"] == "categorical" else [d["low"], d["high"]]
        for v in values:
            try:
                build_config(base, nested({key: v}))
            except ConfigError as e:
                raise ConfigError(f"search space {key!r} = {v!r}: {e}") from None


def suggest(trial, space: SearchSpace) -> dict[str, Any]:
    """Sample every parameter of ``space`` for an Optuna ``trial``: dotted key -> value."""
    out: dict[str, Any] = {}
    for key, d in space.params.items():
        if d["type"] == "categorical":
            out[key] = trial.suggest_categorical(key, d["choices"])
        elif d["type"] == "int":
            out[key] = trial.suggest_int(key, d["low"], d["high"], step=d.get("step", 1), log=d["log"])
        else:
            out[key] = trial.suggest_float(key, d["low"], d["high"], step=d.get("step"), log=d["log"])
    return out
