"""The run configuration: the groups of every layer and the task kind's ``params``, merged from
layers of partial dicts and validated once; ``--set`` parsing and retired settings."""

from __future__ import annotations

import copy
from typing import Annotated, Any, Union

import torch
import yaml
from pydantic import Discriminator, Field, Tag, ValidationError, model_validator

from ..errors import ConfigError, field_message, field_path
from .base import DTYPES, Strict
from .engine import BalancingConfig, LatentConfig, ModelConfig, OutputConfig, TrainingConfig
from .gray_scott import GrayScottParams
from .mirror import MirrorParams
from .shape import ConnectednessConfig, DiversityConfig, LossesConfig, SamplingConfig, ShapeParams, StructuralConfig, TopologyConfig

__all__ = ["TASK_PARAMS", "TASK_KINDS", "TaskParams", "RunConfig", "deep_merge", "flattened", "nested", "parse_set",
           "one_line", "RETIRED", "drop_retired", "build_config", "with_overrides", "parse_task_params", "config_to_dict"]


#: task kind -> its ``params`` group
TASK_PARAMS: dict[str, type[Strict]] = {m.model_fields["kind"].default: m for m in (ShapeParams, MirrorParams, GrayScottParams)}

#: Every task kind (``ginn.tasks.registry`` maps each to its Task class).
TASK_KINDS: tuple[str, ...] = tuple(TASK_PARAMS)


def _kind_of(v: Any) -> str:
    return v.get("kind", "shape") if isinstance(v, dict) else getattr(v, "kind", "shape")


#: The ``params`` group: one model per task kind, chosen by ``kind`` (default ``shape``).
TaskParams = Annotated[
    Union[tuple(Annotated[m, Tag(k)] for k, m in TASK_PARAMS.items())],  # type: ignore[misc]
    Discriminator(_kind_of),
]


def latent_frequency_scale(model: ModelConfig, latents: LatentConfig) -> float:
    """``model.latent_scale`` when unset: ``(r w)^(1/k - 1)``, ``r = high - low`` the side of the
    latent box, ``k`` its dimension, ``w`` the first layer's frequency (SIREN ``omega_0^1``, else 1).

    Along one latent axis of length ``r`` the first layer turns through ``r w`` radians, so the box
    holds about ``(r w)^k`` cells within which the shape varies little: scaling the codes by this
    factor keeps that count at ``r w``, the one-dimensional one, so that a step's codes and the
    held-out ones sample each cell as densely in any dimension. On the obstacle with a latent
    square (16 shapes, seed 0) the unscaled codes left 5 of 16 reported shapes and 95 of 256
    held-out codes feasible; with the rule's 0.19, all 16 and 255 of 256 (seed 1: 256 of 256;
    ``docs/results.md``, "The latent set"). One dimension: 1, the paper's.

    With ``model.latent_turns`` set, the first layer turns through that many radians along each
    latent axis instead: ``latent_turns / (r w)``.
    """
    w = model.w0_first if model.kind == "siren" else 1.0
    turns = max((latents.high - latents.low) * w, 1e-12)
    if model.latent_turns is not None:
        return float(model.latent_turns / turns)
    if latents.dim <= 1:
        return 1.0
    return float(turns ** (1.0 / latents.dim - 1.0))


class RunConfig(Strict):
    """Everything a run needs besides the problem geometry."""

    problem: str = Field("", description="built-in problem name or the spec file's path")
    preset: str | None = Field(None, description="the problem preset the run started from")
    seed: int = Field(0, ge=0, lt=2**63, description="seed of the initialisation and of every sample (0 <= seed < 2^63)")
    device: str = Field("cpu", pattern=r"^(cpu|cuda(:\d+)?)$", description="cpu, cuda or cuda:N")
    model: ModelConfig = ModelConfig()
    latents: LatentConfig = LatentConfig()
    losses: LossesConfig = LossesConfig()
    sampling: SamplingConfig = SamplingConfig()
    diversity: DiversityConfig = DiversityConfig()
    connectedness: ConnectednessConfig = ConnectednessConfig()
    topology: TopologyConfig = TopologyConfig()
    structural: StructuralConfig = StructuralConfig()
    balancing: BalancingConfig = BalancingConfig()
    training: TrainingConfig = TrainingConfig()
    params: TaskParams = Field(ShapeParams(), description="task-specific parameters; `kind` selects the group")
    output: OutputConfig = OutputConfig()

    @model_validator(mode="after")
    def _resolve_latent_scale(self):
        if self.model.latent_scale is None:
            scale = latent_frequency_scale(self.model, self.latents)
            object.__setattr__(self, "model", self.model.model_copy(update={"latent_scale": scale}))
        return self

    @property
    def kind(self) -> str:
        """The task kind (``params.kind``)."""
        return self.params.kind

    @property
    def torch_dtype(self) -> torch.dtype:
        """``training.dtype`` as a torch dtype."""
        return DTYPES[self.training.dtype]


# --- merging, overrides, validation ----------------------------------------------------------------


def deep_merge(base: dict, over: dict) -> dict:
    """Recursive dict merge (``over`` wins); neither input is modified."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def flattened(tree: dict, prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}`` (the inverse of :func:`nested`)."""
    out: dict[str, Any] = {}
    for k, v in tree.items():
        if isinstance(v, dict):
            out.update(flattened(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def nested(flat: dict[str, Any]) -> dict:
    """``{"a.b": 1}`` -> ``{"a": {"b": 1}}``."""
    out: dict = {}
    for key, val in flat.items():
        node = out
        parts = key.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = val
    return out


def parse_set(items: list[str]) -> dict:
    """``["a.b=1", "c=x"]`` -> nested dict with YAML-parsed values. Raises ConfigError."""
    out: dict = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--set {item!r}: expected key=value")
        key, raw = item.split("=", 1)
        key = key.strip()
        if not key or any(not p for p in key.split(".")):
            raise ConfigError(f"--set {item!r}: empty key")
        try:
            val = yaml.safe_load(raw) if raw.strip() else ""
        except yaml.YAMLError:
            val = raw
        node = out
        parts = key.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
            if not isinstance(node, dict):
                raise ConfigError(f"--set {item!r}: {p} is set twice")
        node[parts[-1]] = val
    return out


def one_line(e: ValidationError, data: Any, prefix: str = "") -> str:
    """``config field '<path>': <what is wrong>`` for the first error of ``e`` (``prefix`` is put in
    front of the path, e.g. ``params.`` when a task group is validated on its own)."""
    err = e.errors()[0]
    path = field_path(err.get("loc", ()), data, tags=TASK_KINDS)
    path = prefix + path if path != "<root>" else (prefix.rstrip(".") or path)
    return f"config field '{path}': {field_message(err)}"


#: Settings that were removed, with the value that made them do nothing and what replaces them.
#: A config naming one at that value loads (run directories written by earlier versions keep resuming); any
#: other value is refused with the reason (the measurements: docs/obstacle.md, docs/bracket.md).
RETIRED: dict[str, tuple[Any, str]] = {
    "losses.containment_margin": (
        0.0, "the containment floor starts at the boundary of E (losses.containment_slope); a margin of 0.05 "
        "detached 9 of 16 obstacle shapes"),
    "sampling.band_containment": (
        False, "the design-region term uses the uniform samples of X \\ E (sampling.n_outside); adding the band "
        "points did not lower the volume outside E on the bracket"),
    "diversity.interface_clearance": (
        0.0, "the diversity measures the whole boundary (the paper's); leaving the interfaces out worsened CD1 "
        "and detached 4 of 16 obstacle shapes"),
}


#: Settings that were replaced by another, with the function from the old value to the new settings.
#: Run directories written before keep resuming as they trained.
RENAMED: dict[str, Any] = {
    "latents.random": lambda v: {"latents.draw": "uniform" if v else "fixed"},
}


def drop_retired(layer: dict) -> dict:
    """``layer`` without the :data:`RETIRED` settings it names at their inert value, and with the
    :data:`RENAMED` ones in their new form.

    Raises:
        ConfigError: a retired setting with any other value (one line: its replacement).
    """
    flat = flattened(layer)
    hit = [k for k in flat if k in RETIRED]
    renamed = [k for k in flat if k in RENAMED]
    if not hit and not renamed:
        return layer
    for key in renamed:
        old = flat.pop(key)
        if not isinstance(old, bool):
            raise ConfigError(f"config field '{key}': must be true or false")
        for new, value in RENAMED[key](old).items():
            if new in flat and flat[new] != value:
                raise ConfigError(f"config field '{key}' is the old name of '{new}': give only '{new}'")
            flat[new] = value
    for key in hit:
        inert, why = RETIRED[key]
        if flat[key] != inert:
            raise ConfigError(f"config field '{key}' was retired: {why}")
        del flat[key]
    return nested(flat)


def build_config(*layers: dict) -> RunConfig:
    """Merge partial config dicts in order and validate. Raises :class:`ConfigError` (one line)."""
    merged: dict = {}
    for layer in layers:
        if layer:
            merged = deep_merge(merged, drop_retired(layer))
    try:
        return RunConfig.model_validate(merged)
    except ValidationError as e:
        raise ConfigError(one_line(e, merged)) from None


def with_overrides(cfg: RunConfig, *layers: dict) -> RunConfig:
    """``cfg`` with further partial dicts merged on top (validated again)."""
    return build_config(config_to_dict(cfg), *layers)


def parse_task_params(kind: str, params: dict | None) -> ShapeParams | MirrorParams | GrayScottParams:
    """Validate ``params`` (without its ``kind``) as the parameter group of ``kind``.

    Raises:
        ConfigError: one line, ``config field 'params.<key>': <what is wrong>``.
    """
    data = {**(params or {}), "kind": kind}
    model = TASK_PARAMS.get(kind)
    if model is None:
        raise ConfigError(f"config field 'params.kind': unknown task kind {kind!r} (one of {', '.join(TASK_KINDS)})")
    try:
        return model.model_validate(data)
    except ValidationError as e:
        raise ConfigError(one_line(e, data, prefix="params.")) from None


def config_to_dict(cfg: RunConfig, relevant_only: bool = False) -> dict:
    """The config as plain data. With ``relevant_only`` (what ``config.yaml`` holds) the ``model``
    fields that the chosen ``model.kind`` does not use are left out."""
    out = cfg.model_dump(mode="json")
    if relevant_only:
        kind = cfg.model.kind
        for name, f in ModelConfig.model_fields.items():
            kinds = (f.json_schema_extra or {}).get("kinds")
            if kinds is not None and kind not in kinds:
                out["model"].pop(name, None)
    return out
