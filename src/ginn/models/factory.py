"""Build a model from its config (the only place a model kind is looked up by name)."""

from __future__ import annotations

from torch import nn

from ..config import ModelConfig
from .base import ConcatConditioning, PeriodicEncoding
from .mlp import MLP, FourierMLP, ResMLP
from .siren import Siren
from .wire import Wire


def build_model(cfg: ModelConfig, in_dim: int, latent_dim: int = 0, out_dim: int = 1) -> nn.Module:
    """A freshly initialised neural field ``(n, in_dim), (n, latent_dim) -> (n,)`` from ``cfg``."""
    enc = PeriodicEncoding() if cfg.periodic else None
    # unset only in a ModelConfig outside a RunConfig (which resolves it from the latent box)
    cond = ConcatConditioning(1.0 if cfg.latent_scale is None else cfg.latent_scale)
    if cfg.kind == "siren":
        return Siren(in_dim, cfg.hidden, latent_dim, out_dim, cfg.w0_first, cfg.w0_hidden, encoding=enc, conditioning=cond)
    if cfg.kind == "wire":
        return Wire(in_dim, cfg.hidden, latent_dim, out_dim, cfg.gabor_omega, cfg.gabor_scale, encoding=enc, conditioning=cond)
    if cfg.kind == "resmlp":
        return ResMLP(in_dim, cfg.width, cfg.n_blocks, latent_dim, out_dim, cfg.beta, encoding=enc, conditioning=cond)
    if cfg.kind == "mlp":
        return MLP(in_dim, cfg.hidden, latent_dim, out_dim, cfg.activation, cfg.beta, encoding=enc, conditioning=cond)
    if cfg.kind == "fourier":
        return FourierMLP(in_dim, cfg.hidden, latent_dim, out_dim, cfg.sigma, cfg.n_features, cfg.activation, cfg.beta,
                          pre_encoding=enc, conditioning=cond)
    raise ValueError(f"unknown model kind {cfg.kind!r}")
