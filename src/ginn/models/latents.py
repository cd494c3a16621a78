"""Latent codes of a generative model: fixed equally spaced sets, or random draws."""

from __future__ import annotations

import torch
from torch import Tensor

from ..config import LatentConfig


def fixed_latents(cfg: LatentConfig, device=None, dtype=torch.float32) -> Tensor | None:
    """The trained latent set ``(S, k)``, or None for a single shape (``n_shapes == 1``).

    One dimension: ``S`` equally spaced codes in ``[low, high]`` (obstacle: 16 in [-1, 1]).
    Several dimensions: ``S`` codes drawn once from a seeded uniform distribution on
    ``[low, high]^k`` (seed 0, independent of the run seed, so the set is part of the config).
    """
    if cfg.n_shapes == 1:
        return None
    if cfg.dim == 1:
        return torch.linspace(cfg.low, cfg.high, cfg.n_shapes, device=device, dtype=dtype)[:, None]
    g = torch.Generator().manual_seed(0)
    u = torch.rand(cfg.n_shapes, cfg.dim, generator=g, dtype=torch.float64)
    return (cfg.low + (cfg.high - cfg.low) * u).to(device=device, dtype=dtype)


def random_latents(cfg: LatentConfig, gen: torch.Generator, device=None, dtype=torch.float32) -> Tensor:
    """``n_shapes`` fresh uniform draws on ``[low, high]^dim``, ``(S, k)``."""
    u = torch.rand(cfg.n_shapes, cfg.dim, generator=gen, device=device, dtype=dtype)
    return cfg.low + (cfg.high - cfg.low) * u


def latent_dim(cfg: LatentConfig) -> int:
    return 0 if cfg.n_shapes == 1 else cfg.dim


def midpoints(Z: Tensor) -> Tensor:
    """Mid-points between neighbouring codes ``(S, k) -> (S - 1, k)`` (interpolation figures)."""
    return 0.5 * (Z[1:] + Z[:-1])
