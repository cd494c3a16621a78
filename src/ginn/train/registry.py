"""From a problem spec and a config to a Task object (the one place task kinds are looked up)."""

from __future__ import annotations

import importlib

from ..errors import SpecError
from .config import RunConfig, build_config
from .task import Task
from .trainer import DTYPES

# kind -> "module:Class" for tasks that are not shape problems
_TASKS = {
    "mirror": "ginn.mirror:MirrorTask",
    "gray-scott": "ginn.pinn.gray_scott:GrayScottTask",
}


def make_task(spec, cfg: RunConfig) -> Task:
    """Build the task of ``spec`` (a loaded problem spec) under ``cfg``."""
    dtype = DTYPES[cfg.training.dtype]
    kind = getattr(spec, "kind", "shape")
    if kind == "shape":
        from .shape_task import ShapeTask

        return ShapeTask(spec.build(), cfg, cfg.device, dtype)
    if kind not in _TASKS:
        raise SpecError(f"spec field 'kind': unknown problem kind {kind!r}")
    mod, cls = _TASKS[kind].split(":")
    return getattr(importlib.import_module(mod), cls)(cfg, cfg.device, dtype)


def resolve_config(spec, preset: str | None = None, *overrides: dict) -> RunConfig:
    """Spec defaults, then the named preset, then each override dict (CLI flags, --set)."""
    presets = getattr(spec, "presets", {}) or {}
    if preset is not None and preset not in presets:
        names = ", ".join(sorted(presets)) or "none"
        raise SpecError(f"--preset {preset!r}: problem {spec.name!r} has no such preset (available: {names})")
    layers = [dict(getattr(spec, "defaults", {}) or {}), presets.get(preset, {}) if preset else {}]
    layers.append({"preset": preset})
    return build_config(*layers, *overrides)
