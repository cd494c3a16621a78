"""The engine's groups: the model, the latent codes, balancing, training and what a run writes."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator

from .base import Strict

__all__ = ["ModelConfig", "LatentConfig", "BalancingConfig", "TrainingConfig", "OutputConfig"]


class ModelConfig(Strict):
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
    latent_scale: float | None = Field(
        None, gt=0, description="multiply the latent codes by this before they enter the network (for a SIREN: "
        "the first layer's frequency along the latent axes is omega_0^1 * latent_scale); unset: (r w)^(1/k - 1) for "
        "the latent box of side r = latents.high - latents.low in k = latents.dim dimensions and w = omega_0^1 "
        "(siren; 1 for the other kinds), written resolved to the run's config.yaml: 1 in one dimension (the "
        "paper's), and in k dimensions the box spans as many first-layer periods as the interval of one dimension "
        "(docs/results.md, \"The latent set\")")
    latent_turns: float | None = Field(
        None, gt=0, description="radians the first layer's frequency turns along one latent axis over the latent "
        "range, r * w * latent_scale (w = omega_0^1 for a siren, else 1); when set and latent_scale is unset, "
        "latent_scale resolves to latent_turns / (r w); unset: the rule of latent_scale")
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


class LatentConfig(Strict):
    """The latent codes of a generative model (``n_shapes == 1``: a single shape, no latent)."""

    n_shapes: int = Field(1, ge=1, description="number of trained shapes (latent codes); 1: a single shape without latent")
    dim: int = Field(1, ge=1, description="latent dimension when n_shapes > 1")
    low: float = Field(-1.0, description="lower end of the latent interval")
    high: float = Field(1.0, description="upper end of the latent interval")
    draw: Literal["fixed", "uniform", "lattice"] = Field(
        "fixed", description="the codes each iteration trains: lattice (a randomly shifted rank-1 lattice of "
        "max(n_shapes, 16 in 2D or 4 in 3D) codes in [low, high]^dim, so that training covers the whole latent set "
        "and every code of it gives a feasible shape; the n_shapes shapes' samples are spread over the codes), "
        "uniform (n_shapes fresh independent uniform draws), fixed (the n_shapes reported codes, the paper's); "
        "the reported codes are the shapes a run writes and ginn eval measures either way; shape specs "
        "get lattice from the settings derived from their geometry")


class BalancingConfig(Strict):
    """How loss terms are combined: fixed weights, or an augmented Lagrangian."""

    method: Literal["weighted", "feasibility", "adaptive", "augmented-lagrangian"] = Field(
        "weighted", description="weighted: the sum of weight * term (the paper); feasibility: the weights start the "
        "multipliers, and each feasibility check raises those of a constraint it finds violated and not on track to "
        "meet its bound by the end of the run (by the square of its worst value over bound, at most 2x); adaptive: "
        "constraint terms held at targets derived from the problem's tolerances by multipliers adapted from their "
        "running violation, the weights only starting them; "
        "augmented-lagrangian: constraints driven to zero with multipliers")
    objectives: list[str] = Field(default_factory=lambda: ["eikonal", "mean_curvature", "strain", "diversity", "connectedness",
                                                           "compliance"],
                                  description="weighted and augmented-lagrangian: the terms minimised as objectives, the rest are "
                                  "constraints (adaptive: the constraints are the terms the task derives targets for)")
    mu: float = Field(1.0, gt=0, description="initial penalty parameter")
    mu_growth: float = Field(1.0, ge=1.0, description="penalty growth factor per multiplier update")
    mu_max: float = Field(1e4, gt=0, description="upper bound of the penalty parameter")
    update_every: int = Field(100, ge=1, description="iterations between multiplier updates")
    lambda_lr: float = Field(1.0, gt=0, description="step size of the multiplier update")


class TrainingConfig(Strict):
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
        "since the previous check; the run ends with the candidate that found the most feasible shapes (then: the set's "
        "bounds met, the most feasible held-out codes; the latest of equals, the mean on a tie at one check, unless the "
        "other is feasible throughout and better by the problem's objective with no more volume or clear of the volume bound); "
        "logged as a 'restored' event when that is not the last iterate")
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




class OutputConfig(Strict):
    """What a finished run writes."""

    resolution: int | None = Field(
        None, ge=2, description="grid cells along the longest axis of the written shapes and figures "
        "(None: 256 in 2D, 128 in 3D)")
    results: bool = Field(True, description="write the shapes and figures at the end of training (--no-results: false)")
