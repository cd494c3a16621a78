"""Run configuration: the vocabulary every layer of ginn speaks, validated (pydantic) and frozen.

Every field is settable by ``--set a.b=v``. A problem spec's ``defaults`` and a preset's overrides
are partial dicts of :class:`RunConfig`, merged in that order, then ``--set`` overrides; the result
is validated once (:func:`build_config`). Task-specific parameters are the typed group ``params``,
one model per task kind, selected by its ``kind`` (a discriminated union): :class:`ShapeParams`,
:class:`MirrorParams`, :class:`GrayScottParams`.

This module imports only :mod:`ginn.errors`; ``docs/config.md`` is generated from the field
descriptions here (``python scripts/config_reference.py``) and a test keeps it in step.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Annotated, Any, Literal, Union

import torch
import yaml
from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, ValidationError, field_validator, model_validator

from .errors import ConfigError, field_message, field_path

#: Names of the floating-point types a run may train in (``training.dtype``).
DTYPES = {"float32": torch.float32, "float64": torch.float64}

#: Per-point surface strain is clipped at this value (training loss and metric alike).
STRAIN_CLIP = 1000.0

#: Grid cells along the longest domain axis when none is given, by purpose and dimension:
#: ``eval`` for the metrics of ``ginn eval``, ``output`` for the shapes a run writes, ``figure``
#: for a figure drawn on its own (3D renders cost time per triangle), ``check`` for the feasibility
#: checks during training.
RESOLUTION = {"eval": {2: 512, 3: 128}, "output": {2: 256, 3: 128}, "figure": {2: 256, 3: 64}, "check": {2: 128, 3: 64}}


def default_resolution(purpose: Literal["eval", "output", "figure", "check"], dim: int) -> int:
    """The grid resolution used for ``purpose`` in ``dim`` dimensions (see :data:`RESOLUTION`)."""
    return RESOLUTION[purpose][dim]


class _Strict(BaseModel):
    # every float is finite: nan and inf are refused where they are read, not found later as a divergence
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class ModelConfig(_Strict):
    """The neural field."""

    kind: Literal["siren", "wire", "resmlp", "mlp", "fourier"] = Field(
        "siren", description="siren (sine activations), wire (complex Gabor wavelet activations), resmlp (softplus "
        "residual MLP), mlp, fourier (Fourier features + MLP)")
    hidden: list[int] = Field(default_factory=lambda: [64, 64, 64, 64], description="hidden widths (siren, wire, mlp, fourier)",
                              json_schema_extra={"kinds": ("siren", "wire", "mlp", "fourier")})
    width: int = Field(512, gt=0, description="hidden width (resmlp)", json_schema_extra={"kinds": ("resmlp",)})
    n_blocks: int = Field(4, gt=0, description="number of hidden layers (resmlp)", json_schema_extra={"kinds": ("resmlp",)})
    w0_first: float = Field(1.0, gt=0, description="SIREN omega_0 of the first layer (omega_0^1)",
                            json_schema_extra={"kinds": ("siren",)})
    w0_hidden: float = Field(1.0, gt=0, description="SIREN omega_0 of the hidden layers", json_schema_extra={"kinds": ("siren",)})
    gabor_omega: float = Field(20.0, gt=0, description="WIRE: frequency omega of the Gabor activation exp(i omega u - |scale u|^2)",
                               json_schema_extra={"kinds": ("wire",)})
    gabor_scale: float = Field(10.0, gt=0, description="WIRE: inverse width of the Gabor window (scale above)",
                               json_schema_extra={"kinds": ("wire",)})
    latent_scale: float = Field(
        1.0, gt=0, description="multiply the latent codes by this before they enter the network (for a SIREN: "
        "the first layer's frequency along the latent axes is omega_0^1 * latent_scale); 1 is the paper's")
    activation: str = Field("tanh", description="activation (mlp, fourier)", json_schema_extra={"kinds": ("mlp", "fourier")})
    beta: float = Field(1.0, gt=0, description="softplus sharpness (resmlp, softplus activations)",
                        json_schema_extra={"kinds": ("resmlp", "mlp", "fourier")})
    sigma: float = Field(1.0, gt=0, description="Fourier-feature scale (fourier)", json_schema_extra={"kinds": ("fourier",)})
    n_features: int = Field(128, gt=0, description="number of Fourier features (fourier)", json_schema_extra={"kinds": ("fourier",)})
    periodic: bool = Field(False, description="encode x -> (sin 2 pi x, cos 2 pi x) first")
    frame: Literal["raw", "domain"] = Field(
        "raw", description="shape problems: raw feeds the points as they are; domain feeds (x - c) / s and returns "
        "s times the output (c the domain's centre, s half its longest side), so that a problem of any size looks "
        "the same to the network; shape specs get domain from the settings derived from their geometry")

    @field_validator("hidden")
    @classmethod
    def _positive(cls, v: list[int]) -> list[int]:
        if not v or any(w <= 0 for w in v):
            raise ValueError("hidden widths must be a non-empty list of positive integers")
        return v


class LatentConfig(_Strict):
    """The latent codes of a generative model (``n_shapes == 1``: a single shape, no latent)."""

    n_shapes: int = Field(1, ge=1, description="number of trained shapes (latent codes); 1: a single shape without latent")
    dim: int = Field(1, ge=1, description="latent dimension when n_shapes > 1")
    low: float = Field(-1.0, description="lower end of the latent interval")
    high: float = Field(1.0, description="upper end of the latent interval")
    random: bool = Field(False, description="draw fresh random latents in [low, high]^dim every iteration")


class LossTerm(_Strict):
    """Weight and first iteration of one loss term (weight 0 switches it off)."""

    weight: float = Field(0.0, ge=0, description="weight of the term (0 switches it off; a finite number)")
    start: int = Field(0, ge=0, description="first iteration at which the term is active")

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
    topology: LossTerm = LossTerm()
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
        "0 is the paper's loss, 1 is exact for a signed distance field of any shape inside E; with a slope > 0 "
        "the shapes' surface samples outside E enter the design-region term too, each at its depth",
    )


class SamplingConfig(_Strict):
    """Monte Carlo point budgets per shape and iteration."""

    n_domain: int = Field(4096, gt=0, description="uniform points in X (eikonal)")
    n_outside: int = Field(2048, ge=0, description="points in X minus E (design-region loss)")
    n_obstacle: int = Field(512, ge=0, description="points inside obstacles")
    n_interface: int = Field(512, gt=0, description="points on the interfaces")
    n_band: int = Field(0, ge=0, description="extra points in a band around the interfaces")
    n_boundary: int = Field(512, ge=0, description="points projected onto f = 0 (curvature, strain, diversity)")
    projection_steps: int = Field(2, ge=0, description="Newton steps of the zero-level-set projection (after a free first step)")
    strain_interface_clearance: float = Field(0.0, ge=0, description="skip boundary points this close to an interface for the strain loss")
    strain_clip: float = Field(STRAIN_CLIP, gt=0, description="clip per-point surface strain at this value")
    interface_corner_weight: float = Field(
        1.0, ge=1, description="weight of the interfaces' corner samples: polyline vertices, end points included (Plateau)")


class DiversityConfig(_Strict):
    """Diversity loss of Appendix E."""

    aggregation: Literal["min", "sum"] = Field(
        "min", description="min: each shape's distance to its nearest other shape (equation 11); sum: all pairs (equation 10)")
    p: float = Field(0.5, gt=0, description="exponent of the aggregation (paper: 0.5 with min)")
    eps: float = Field(0.0, ge=0, description="smooth the shape distance to sqrt(d^2 + eps^2), bounding the loss's gradient "
                       "when shapes coincide (0: the paper's distance, singular there)")


class ConnectednessConfig(_Strict):
    """Connectedness loss (Appendix C); see docs/connectedness.md."""

    method: Literal["surface-network", "persistent-homology"] = Field(
        "surface-network", description="the paper's surface-network loss, or 0-dimensional cubical persistent homology (cripser)")
    every: int = Field(10, ge=1, description="full surface-network builds at every K-th step, of the shapes due: a shape "
        "every K steps while it has something to join, up to 4 K while nothing is penalised on it (warm updates between)")
    grid: int = Field(16, ge=2, description="seed grid resolution per axis (surface network) or PH grid resolution")
    restrict_to_design_region: bool = Field(True, description="count only the part of the shape inside the design region E")
    eps: float = Field(1e-2, gt=0, description="epsilon in p_k += 1/(d + eps)")
    margin: float = Field(0.0, ge=0, description="the loss sees the shape {f <= -margin}: connections thinner than "
                          "about 2 margin count as gaps and are pushed open (0: the paper's {f <= 0})")


class TopologyConfig(_Strict):
    """The loss toward the spec's target Betti numbers (``topology:``; docs/problem-spec.md)."""

    grid: int = Field(64, ge=8, description="persistent-homology grid nodes along the longest axis of the domain; "
                      "the margin of the loss is one cell of it")
    every: int = Field(5, ge=1, description="recompute the persistence diagrams every K steps (the same cells between)")


class BalancingConfig(_Strict):
    """How loss terms are combined: fixed weights, or an augmented Lagrangian."""

    method: Literal["weighted", "feasibility", "adaptive", "augmented-lagrangian"] = Field(
        "weighted", description="weighted: the sum of weight * term (the paper); feasibility: the weights start the "
        "multipliers, and each feasibility check raises those of a constraint it finds violated and not on track to "
        "meet its bound by the end of the run (by the square of its worst value over bound, at most 2x); adaptive: "
        "constraint terms held at targets derived from the problem's tolerances by multipliers adapted from their "
        "running violation, the weights only starting them; "
        "augmented-lagrangian: constraints driven to zero with multipliers")
    objectives: list[str] = Field(default_factory=lambda: ["eikonal", "mean_curvature", "strain", "diversity", "connectedness"],
                                  description="weighted and augmented-lagrangian: the terms minimised as objectives, the rest are "
                                  "constraints (adaptive: the constraints are the terms the task derives targets for)")
    mu: float = Field(1.0, gt=0, description="initial penalty parameter")
    mu_growth: float = Field(1.0, ge=1.0, description="penalty growth factor per multiplier update")
    mu_max: float = Field(1e4, gt=0, description="upper bound of the penalty parameter")
    update_every: int = Field(100, ge=1, description="iterations between multiplier updates")
    lambda_lr: float = Field(1.0, gt=0, description="step size of the multiplier update")


class TrainingConfig(_Strict):
    """Optimiser, schedule and bookkeeping."""

    iterations: int = Field(3000, ge=0, description="optimisation steps of the run")
    lr: float = Field(1e-3, gt=0, description="Adam learning rate at iteration 0")
    lr_decay: float = Field(0.5, gt=0, le=1, description="learning rate is lr * lr_decay^(t / lr_decay_every)")
    lr_decay_every: int = Field(1000, gt=0, description="iterations over which the learning rate is multiplied by lr_decay")
    lr_restart_at: int = Field(
        0, ge=0, description="from this iteration on (0: never) the learning rate restarts at lr_restart and decays "
        "from there: lr_restart * lr_decay^((t - lr_restart_at) / lr_decay_every)")
    lr_restart: float = Field(1e-4, gt=0, description="learning rate at iteration lr_restart_at")
    lbfgs_steps: int = Field(
        0, ge=0, description="after the Adam iterations, this many L-BFGS steps on one fixed sample of points, the "
        "multipliers held; each step is up to 20 L-BFGS iterations (strong-Wolfe line search, history 20); 0: none")
    grad_clip: float = Field(1.0, ge=0, description="clip the gradient norm (0: off)")
    log_every: int = Field(10, ge=1, description="iterations between lines of metrics.jsonl")
    checkpoint_every: int = Field(200, ge=1, description="iterations between checkpoints (also written on SIGINT/SIGTERM and at the end)")
    checkpoint_seconds: float = Field(
        60.0, gt=0, description="seconds of training between checkpoints, whichever of this and checkpoint_every comes "
        "first: a crash loses at most this much work")
    max_bad_steps: int = Field(5, ge=1, description="consecutive non-finite steps before rolling back")
    rollback_lr_factor: float = Field(0.5, gt=0, lt=1, description="multiply the learning rate by this at each rollback")
    max_rollbacks: int = Field(3, ge=0, description="give up (error) after this many rollbacks")
    dtype: Literal["float32", "float64"] = Field("float32", description="floating-point type of the model and the samples")
    threads: int = Field(0, ge=0, description="torch CPU threads (0: leave the default)")
    compile: bool = Field(
        True, description="compute a SIREN's value and input gradient in the training pass with torch.compile "
        "kernels (the same numbers to rounding in fewer passes over memory; a few seconds of compiling at the "
        "start; uncompiled, with a warning, where torch cannot compile)")
    feasibility_checks: int = Field(
        10, ge=0, description="shape problems: how many times per run (evenly spaced, and at the end) the shapes are "
        "checked against the problem's tolerances on a coarse grid; logged and shown in the progress bar (0: never)")
    stop_when_feasible: bool = Field(
        False, description="end the run at a feasibility check that finds every shape feasible while the objective "
        "terms improved by less than 1 % since the previous check")
    keep_most_feasible: bool = Field(
        True, description="shape problems: each feasibility check judges the weights there and the mean of the weights "
        "since the previous check; the run ends with the candidate that found the most feasible shapes (the latest of "
        "equals, the mean on a tie at one check); logged as a 'restored' event when that is not the last iterate")
    log: list[Literal["jsonl", "tensorboard"]] = Field(
        ["jsonl"], description="where the metrics go: jsonl (metrics.jsonl, always; resume and eval read it) and "
        "optionally tensorboard (event files in RUN/tensorboard: losses, multipliers, learning rate, feasibility, "
        "the figures at the end; needs the track extra)")

    @field_validator("log")
    @classmethod
    def _jsonl_kept(cls, v: list[str]) -> list[str]:
        if "jsonl" not in v:
            raise ValueError("must include jsonl: metrics.jsonl is the run's record (resume and eval read it)")
        return list(dict.fromkeys(v))




# --- task parameters: one typed group per task kind ------------------------------------------------


class ShapeParams(_Strict):
    """``params`` of a shape problem: none beyond the groups above."""

    kind: Literal["shape"] = Field("shape", description="the task kind this group belongs to")


class MirrorParams(_Strict):
    """``params`` of the parabolic mirror (``kind: mirror``)."""

    kind: Literal["mirror"] = Field("mirror", description="the task kind this group belongs to")
    focus: float = Field(1.0, gt=0, description="height F of the focus (0, F); the exact mirror is x^2 / (4 F)")
    x_min: float = Field(-1.0, description="left end of the aperture")
    x_max: float = Field(1.0, description="right end of the aperture")
    n_samples: int = Field(256, gt=0, description="ray positions per iteration")
    sampling: Literal["uniform", "stratified"] = Field(
        "stratified", description="uniform: i.i.d. uniform ray positions; stratified: one uniform point per equal cell")
    reflection_weight: float = Field(1.0, ge=0, description="weight of the optics loss (the interface weight is losses.interface)")
    reflection_start: int = Field(0, ge=0, description="first iteration of the optics loss")
    n_eval: int = Field(2001, ge=2, description="grid points for the error against the exact parabola")
    n_rays_plot: int = Field(15, ge=1, description="rays drawn in the figure")

    @model_validator(mode="after")
    def _aperture(self) -> MirrorParams:
        if not self.x_min < self.x_max:
            raise ValueError("x_min must be smaller than x_max")
        return self


@dataclass(frozen=True)
class GSParams:
    """Coefficients of the Gray-Scott equation (defaults: the paper's Appendix A.6)."""

    D_v: float = 1.2e-5
    D_u: float = 2.4e-5
    alpha: float = 0.028
    beta: float = 0.057


class GrayScottLosses(_Strict):
    """Weights and start iterations of the three Gray-Scott loss terms."""

    residual: LossTerm = LossTerm(weight=1.0)
    gradient: LossTerm = LossTerm(weight=1e-4)
    diversity: LossTerm = LossTerm(weight=1e-7)


class GrayScottParams(_Strict):
    """``params`` of the Gray-Scott generative PINN (``kind: gray-scott``); see docs/gray-scott.md."""

    kind: Literal["gray-scott"] = Field("gray-scott", description="the task kind this group belongs to")
    D_v: float = Field(1.2e-5, gt=0, description="diffusion coefficient of v")
    D_u: float | None = Field(None, gt=0, description="diffusion coefficient of u (None: 2 D_v)")
    alpha: float = Field(0.028, gt=0, description="feed rate")
    beta: float = Field(0.057, gt=0, description="kill rate")
    grid: int = Field(64, ge=8, description="training grid points per axis")
    fine_grid: int = Field(
        0, ge=0, description="from iteration fine_grid_from on, train on this grid instead of `grid` (0: never); a "
        "finer grid holds the pattern's harmonics above the coarse grid's Nyquist frequency")
    fine_grid_from: int = Field(0, ge=0, description="first iteration on `fine_grid`")
    translate: bool = Field(True, description="translate the training grid randomly every iteration")
    derivatives: Literal["fd", "spectral", "autograd"] = Field(
        "fd", description="periodic finite differences, FFT on the same grid, or autograd through ginn.fields")
    gradient_cap: float = Field(1.0, gt=0, description="the gradient reward saturates at this mean |grad|^2")
    diversity_distance: Literal["rms", "shift"] = Field(
        "rms", description="rms: RMS difference of v; shift: its minimum over the grid's periodic translations")
    residual_gradient: Literal["full", "flow", "step"] = Field(
        "full", description="full: gradient of mean(R^2) (the paper); flow: descend along the PDE's own time derivative R; "
        "step: regress on the sampled state advanced by a semi-implicit pseudo-time step")
    flow_steps: int = Field(0, ge=0, description="with residual_gradient=flow/step: switch to full after this many iterations (0: never)")
    step_dt: float = Field(1.0, gt=0, description="pseudo-time sub-step of residual_gradient=step")
    step_count: int = Field(10, ge=1, description="sub-steps per target of residual_gradient=step (target time step_dt * step_count)")
    step_sobolev: float = Field(
        0.0, ge=0, description="residual_gradient=step: add this weight times mean |D lap (W - target)|^2 (D = D_u, D_v) "
        "to the regression, so that the network's error is also weighted where diffusion amplifies it into the residual")
    step_reuse: int = Field(
        1, ge=1, description="residual_gradient=step: iterations that regress on one target (computed every step_reuse "
        "iterations and moved to each iteration's translated grid by an exact Fourier shift)")
    u_offset: float = Field(0.0, description="u = u_offset + network output (0: the paper's raw output)")
    v_offset: float = Field(0.0, description="v = v_offset + network output")
    output_scale: float = Field(1.0, gt=0, description="u = u_offset + output_scale * network output (same for v)")
    losses: GrayScottLosses = GrayScottLosses()
    resolution: int = Field(256, ge=8, description="resolution of the written fields and pictures")
    n_interpolation: int = Field(8, ge=2, description="patterns in the latent interpolation strip")

    @property
    def gs(self) -> GSParams:
        """The equation's coefficients (``D_u`` defaults to ``2 D_v``)."""
        return GSParams(D_v=self.D_v, D_u=self.D_u if self.D_u is not None else 2.0 * self.D_v,
                        alpha=self.alpha, beta=self.beta)


#: task kind -> its ``params`` group
TASK_PARAMS: dict[str, type[_Strict]] = {m.model_fields["kind"].default: m for m in (ShapeParams, MirrorParams, GrayScottParams)}

#: Every task kind (``ginn.tasks.registry`` maps each to its Task class).
TASK_KINDS: tuple[str, ...] = tuple(TASK_PARAMS)


def _kind_of(v: Any) -> str:
    return v.get("kind", "shape") if isinstance(v, dict) else getattr(v, "kind", "shape")


#: The ``params`` group: one model per task kind, chosen by ``kind`` (default ``shape``).
TaskParams = Annotated[
    Union[tuple(Annotated[m, Tag(k)] for k, m in TASK_PARAMS.items())],  # type: ignore[misc]
    Discriminator(_kind_of),
]


class OutputConfig(_Strict):
    """What a finished run writes."""

    resolution: int | None = Field(
        None, ge=2, description="grid cells along the longest axis of the written shapes and figures "
        "(None: 256 in 2D, 128 in 3D)")
    results: bool = Field(True, description="write the shapes and figures at the end of training (--no-results: false)")


class RunConfig(_Strict):
    """Everything a run needs besides the problem geometry."""

    problem: str = Field("", description="built-in problem name or the spec file's path")
    preset: str | None = Field(None, description="the problem preset the run started from")
    seed: int = Field(0, description="seed of the initialisation and of every sample")
    device: str = Field("cpu", description="cpu or cuda[:N]")
    model: ModelConfig = ModelConfig()
    latents: LatentConfig = LatentConfig()
    losses: LossesConfig = LossesConfig()
    sampling: SamplingConfig = SamplingConfig()
    diversity: DiversityConfig = DiversityConfig()
    connectedness: ConnectednessConfig = ConnectednessConfig()
    topology: TopologyConfig = TopologyConfig()
    balancing: BalancingConfig = BalancingConfig()
    training: TrainingConfig = TrainingConfig()
    params: TaskParams = Field(ShapeParams(), description="task-specific parameters; `kind` selects the group")
    output: OutputConfig = OutputConfig()

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


def drop_retired(layer: dict) -> dict:
    """``layer`` without the :data:`RETIRED` settings it names at their inert value.

    Raises:
        ConfigError: a retired setting with any other value (one line: its replacement).
    """
    flat = flattened(layer)
    hit = [k for k in flat if k in RETIRED]
    if not hit:
        return layer
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
