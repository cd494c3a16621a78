"""Run configuration: validated (pydantic) and frozen; every field is settable by ``--set a.b=v``.

A problem spec's ``defaults`` and a preset's overrides are partial dicts of :class:`RunConfig`,
merged in that order, then ``--set`` overrides; the result is validated once.
"""

from __future__ import annotations

import copy
import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from ..errors import ConfigError


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ModelConfig(_Strict):
    """The neural field."""

    kind: Literal["siren", "resmlp", "mlp", "fourier"] = "siren"
    hidden: list[int] = Field(default_factory=lambda: [64, 64, 64, 64], description="hidden widths (siren, mlp, fourier)")
    width: int = Field(512, gt=0, description="hidden width (resmlp)")
    n_blocks: int = Field(4, gt=0, description="number of hidden layers (resmlp)")
    w0_first: float = Field(1.0, gt=0, description="SIREN omega_0 of the first layer (omega_0^1)")
    w0_hidden: float = Field(1.0, gt=0, description="SIREN omega_0 of the hidden layers")
    latent_scale: float = Field(
        1.0, gt=0, description="multiply the latent codes by this before they enter the network (for a SIREN: "
        "the first layer's frequency along the latent axes is omega_0^1 * latent_scale); 1 is the paper's")
    activation: str = Field("tanh", description="activation (mlp, fourier)")
    beta: float = Field(1.0, gt=0, description="softplus sharpness (resmlp, softplus activations)")
    sigma: float = Field(1.0, gt=0, description="Fourier-feature scale (fourier)")
    n_features: int = Field(128, gt=0, description="number of Fourier features (fourier)")
    periodic: bool = Field(False, description="encode x -> (sin 2 pi x, cos 2 pi x) first")

    @field_validator("hidden")
    @classmethod
    def _positive(cls, v: list[int]) -> list[int]:
        if not v or any(w <= 0 for w in v):
            raise ValueError("hidden widths must be a non-empty list of positive integers")
        return v


class LatentConfig(_Strict):
    """The latent codes of a generative model (``n_shapes == 1``: a single shape, no latent)."""

    n_shapes: int = Field(1, ge=1)
    dim: int = Field(1, ge=1, description="latent dimension when n_shapes > 1")
    low: float = -1.0
    high: float = 1.0
    random: bool = Field(False, description="draw fresh random latents in [low, high]^dim every iteration")


class LossTerm(_Strict):
    """Weight and first iteration of one loss term (weight 0 switches it off)."""

    weight: float = Field(0.0, ge=0)
    start: int = Field(0, ge=0)

    @field_validator("weight")
    @classmethod
    def _finite(cls, v: float) -> float:
        if not math.isfinite(v):
            raise ValueError("weight must be finite")
        return v


class LossesConfig(_Strict):
    """All loss terms of a shape problem (Table 1, eikonal, obstacle, strain, connectedness, diversity)."""

    interface: LossTerm = LossTerm(weight=1.0)
    normal: LossTerm = LossTerm()
    design_region: LossTerm = LossTerm(weight=1.0)
    obstacle: LossTerm = LossTerm()
    eikonal: LossTerm = LossTerm()
    mean_curvature: LossTerm = LossTerm()
    strain: LossTerm = LossTerm()
    connectedness: LossTerm = LossTerm()
    diversity: LossTerm = LossTerm()
    containment_power: Literal[1, 2] = Field(
        2,
        description="exponent of the design-region and obstacle penalties: 2 is the paper's mean of "
        "min(0, f)^2; 1 is the mean of |min(0, f)|, an exact penalty that keeps pushing on shallow violations",
    )
    containment_slope: float = Field(
        0.0,
        ge=0,
        description="penalise f below slope * (distance into X minus E, or into an obstacle) instead of below 0; "
        "0 is the paper's loss, 1 is exact for a signed distance field of any shape inside E",
    )
    containment_margin: float = Field(
        0.0,
        ge=0,
        description="with containment_slope > 0: the floor starts this far beyond E (or inside an obstacle): "
        "f must reach slope * max(0, distance - margin); within the margin only f >= 0 is asked, which leaves "
        "a smooth field room to round the corners where an interface ends on the boundary of E",
    )


class SamplingConfig(_Strict):
    """Monte Carlo point budgets per shape and iteration."""

    n_domain: int = Field(4096, gt=0, description="uniform points in X (eikonal)")
    n_outside: int = Field(2048, ge=0, description="points in X minus E (design-region loss)")
    n_obstacle: int = Field(512, ge=0, description="points inside obstacles")
    n_interface: int = Field(512, gt=0, description="points on the interfaces")
    n_band: int = Field(0, ge=0, description="extra points in a band around the interfaces")
    band_containment: bool = Field(
        False,
        description="also apply the design-region loss to the band points that lie outside E (a denser "
        "estimate where a shape attached to an interface on dE tends to bulge out of E)",
    )
    n_boundary: int = Field(512, ge=0, description="points projected onto f = 0 (curvature, strain, diversity)")
    projection_steps: int = Field(2, ge=0, description="Newton steps of the zero-level-set projection (after a free first step)")
    strain_interface_clearance: float = Field(0.0, ge=0, description="skip boundary points this close to an interface for the strain loss")
    strain_clip: float = Field(1000.0, gt=0, description="clip per-point surface strain at this value")
    interface_corner_weight: float = Field(1.0, ge=1, description="weight of the interfaces' corner samples: polyline vertices, end points included (Plateau)")


class DiversityConfig(_Strict):
    """Diversity loss of Appendix E."""

    aggregation: Literal["min", "sum"] = "min"
    p: float = Field(0.5, gt=0, description="exponent of the aggregation (paper: 0.5 with min)")
    interface_clearance: float = Field(0.0, ge=0, description="leave boundary points this close to an interface out of "
                                       "the shape distance (every shape must share the interfaces; 0: the paper's full boundary)")
    eps: float = Field(0.0, ge=0, description="smooth the shape distance to sqrt(d^2 + eps^2), bounding the loss's gradient "
                       "when shapes coincide (0: the paper's distance, singular there)")


class ConnectednessConfig(_Strict):
    """Connectedness loss (Appendix C); see docs/connectedness.md."""

    method: Literal["surface-network", "persistent-homology"] = "surface-network"
    every: int = Field(10, ge=1, description="full surface-network rebuild at least every K steps (warm updates between)")
    grid: int = Field(16, ge=2, description="seed grid resolution per axis (surface network) or PH grid resolution")
    restrict_to_design_region: bool = True
    eps: float = Field(1e-2, gt=0, description="epsilon in p_k += 1/(d + eps)")
    margin: float = Field(0.0, ge=0, description="the loss sees the shape {f <= -margin}: connections thinner than "
                          "about 2 margin count as gaps and are pushed open (0: the paper's {f <= 0})")


class BalancingConfig(_Strict):
    """How loss terms are combined: fixed weights, or an augmented Lagrangian."""

    method: Literal["weighted", "augmented-lagrangian"] = "weighted"
    objectives: list[str] = Field(default_factory=lambda: ["eikonal", "mean_curvature", "strain", "diversity", "connectedness"],
                                  description="terms minimised as objectives; the rest are constraints (augmented Lagrangian)")
    mu: float = Field(1.0, gt=0, description="initial penalty parameter")
    mu_growth: float = Field(1.0, ge=1.0, description="penalty growth factor per multiplier update")
    mu_max: float = Field(1e4, gt=0)
    update_every: int = Field(100, ge=1, description="iterations between multiplier updates")
    lambda_lr: float = Field(1.0, gt=0, description="step size of the multiplier update")


class TrainingConfig(_Strict):
    """Optimiser, schedule and bookkeeping."""

    iterations: int = Field(3000, ge=0)
    lr: float = Field(1e-3, gt=0)
    lr_decay: float = Field(0.5, gt=0, le=1, description="learning rate is lr * lr_decay^(t / lr_decay_every)")
    lr_decay_every: int = Field(1000, gt=0)
    lr_restart_at: int = Field(
        0, ge=0, description="from this iteration on (0: never) the learning rate restarts at lr_restart and decays "
        "from there: lr_restart * lr_decay^((t - lr_restart_at) / lr_decay_every)")
    lr_restart: float = Field(1e-4, gt=0, description="learning rate at iteration lr_restart_at")
    grad_clip: float = Field(1.0, ge=0, description="clip the gradient norm (0: off)")
    log_every: int = Field(10, ge=1)
    checkpoint_every: int = Field(200, ge=1)
    max_bad_steps: int = Field(5, ge=1, description="consecutive non-finite steps before rolling back")
    rollback_lr_factor: float = Field(0.5, gt=0, lt=1)
    max_rollbacks: int = Field(3, ge=0, description="give up (error) after this many rollbacks")
    dtype: Literal["float32", "float64"] = "float32"
    threads: int = Field(0, ge=0, description="torch CPU threads (0: leave the default)")


class RunConfig(_Strict):
    """Everything a run needs besides the problem geometry."""

    problem: str = ""
    preset: str | None = None
    seed: int = 0
    device: str = "cpu"
    model: ModelConfig = ModelConfig()
    latents: LatentConfig = LatentConfig()
    losses: LossesConfig = LossesConfig()
    sampling: SamplingConfig = SamplingConfig()
    diversity: DiversityConfig = DiversityConfig()
    connectedness: ConnectednessConfig = ConnectednessConfig()
    balancing: BalancingConfig = BalancingConfig()
    training: TrainingConfig = TrainingConfig()
    params: dict[str, Any] = Field(default_factory=dict, description="task-specific parameters (mirror, gray-scott)")
    output: dict[str, Any] = Field(default_factory=dict, description="output options (resolution, ...)")


# --- merging and overrides -----------------------------------------------------------------------


def deep_merge(base: dict, over: dict) -> dict:
    """Recursive dict merge (``over`` wins); neither input is modified."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def parse_set(items: list[str]) -> dict:
    """``["a.b=1", "c=x"]`` -> nested dict with YAML-parsed values. Raises ConfigError."""
    import yaml

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


def _field_path(err: dict) -> str:
    return ".".join(str(p) for p in err.get("loc", ()))


def build_config(*layers: dict) -> RunConfig:
    """Merge partial config dicts in order and validate. Raises :class:`ConfigError` (one line)."""
    merged: dict = {}
    for layer in layers:
        if layer:
            merged = deep_merge(merged, layer)
    try:
        return RunConfig.model_validate(merged)
    except ValidationError as e:
        err = e.errors()[0]
        path = _field_path(err)
        msg = err.get("msg", "invalid value")
        if err.get("type") == "extra_forbidden":
            msg = "unknown key"
        raise ConfigError(f"config field '{path}': {msg}") from None


def config_to_dict(cfg: RunConfig) -> dict:
    return cfg.model_dump(mode="json")
