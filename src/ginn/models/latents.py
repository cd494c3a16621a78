"""Latent codes of a generative model: the reported set, the codes drawn at each step, held-out sets.

The latent set is the box ``Z = [low, high]^k``. A run *reports* ``n_shapes`` codes
(:func:`fixed_latents`: the shapes it writes and ``ginn eval`` measures) and, with
``latents.draw: lattice`` (what shape specs derive), trains on all of ``Z``: every step draws a
randomly shifted rank-1 lattice of ``C = max(n_shapes, floor)`` codes (:func:`lattice_latents`,
:func:`step_codes`; the floor is :data:`ginn.config.MIN_STEP_CODES`).

A rank-1 lattice of ``n`` points in the unit cube is ``{frac(i g / n) : i = 0..n-1}`` for an
integer generating vector ``g = (1, a, a^2, ...) mod n`` (Korobov's form); shifted by a uniform
``u`` modulo 1 it becomes a *randomly shifted lattice*:

* every point of it is uniform on the cube, so over the steps every region of ``Z`` is trained
  as often as its volume says;
* in one dimension it is the equally spaced grid of spacing ``1 / n`` shifted as a whole: each
  of the ``n`` strata of equal width holds exactly one code, and the codes keep their spacing
  (the diversity term compares shapes at the same latent distances at every step);
* the lattice spans ``Z`` widened by half a cell on every side (:func:`lattice_span`), so that
  the boundary of ``Z`` is trained from both sides like its interior: on the obstacle (4 shapes)
  the lattice over ``Z`` itself left the two end codes of ``Z`` infeasible (interface CD1 1.03
  and 1.16 times its bound) while every code between them was feasible. In one dimension the
  cell is the reported codes' spacing, and the lattice shifted by half a cell *is* the reported
  set;
* in ``k`` dimensions each coordinate is such a grid (``a`` coprime to ``n``, so every
  coordinate of the lattice is a permutation of ``0..n-1``: a Latin hypercube), and ``a`` is the
  one whose lattice has the largest smallest distance between points on the torus (searched
  once per ``(n, k)``), so that the codes spread over the box instead of lining up.

Held-out codes (:func:`heldout_latents`), judged by ``ginn eval`` and by the checks during
training: the lattice shifted by half a cell, a fixed quasi-random set (one dimension: the
centres of ``n`` equal strata).
"""

from __future__ import annotations

import math
from functools import lru_cache

import torch
from torch import Tensor

from ..config import LatentConfig

__all__ = ["fixed_latents", "random_latents", "lattice_latents", "lattice_span", "lattice_generator", "unit_lattice",
           "step_codes", "step_latents", "heldout_latents", "grid_latents", "latent_dim", "midpoints"]


def fixed_latents(cfg: LatentConfig, device=None, dtype=torch.float32) -> Tensor | None:
    """The reported latent set ``(S, k)``, or None for a single shape (``n_shapes == 1``).

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
    """``n_shapes`` fresh independent uniform draws on ``[low, high]^dim``, ``(S, k)``."""
    u = torch.rand(cfg.n_shapes, cfg.dim, generator=gen, device=device, dtype=dtype)
    return cfg.low + (cfg.high - cfg.low) * u


def _torus_min_distance(n: int, g: list[int]) -> float:
    """The smallest distance between two points of the lattice ``frac(i g / n)`` on the unit torus."""
    i = torch.arange(1, n, dtype=torch.float64)[:, None]  # the differences i - j cover 1..n-1
    frac = torch.remainder(i * torch.tensor(g, dtype=torch.float64) / n, 1.0)
    wrapped = torch.minimum(frac, 1.0 - frac)
    return float(wrapped.pow(2).sum(1).sqrt().min())


@lru_cache(maxsize=64)
def lattice_generator(n: int, k: int) -> tuple[int, ...]:
    """The generating vector ``(1, a, a^2, ...) mod n`` of a rank-1 lattice of ``n`` points in
    ``k`` dimensions: among the ``a`` coprime to ``n`` (each coordinate a permutation), the one
    with the largest smallest distance on the torus, the smallest such ``a`` on ties."""
    if k == 1 or n <= 2:
        return (1,) * k
    best, best_d = None, -1.0
    for a in range(1, n):
        if math.gcd(a, n) != 1:
            continue
        g = [pow(a, j, n) for j in range(k)]
        if len(set(g)) < k and n > k:  # repeated coordinates: the points lie on a diagonal
            continue
        d = _torus_min_distance(n, g)
        if d > best_d + 1e-12:
            best, best_d = g, d
    return tuple(best if best is not None else [pow(1, j, n) for j in range(k)])


def unit_lattice(n: int, k: int, shift: Tensor) -> Tensor:
    """The rank-1 lattice of ``n`` points in ``[0, 1)^k`` shifted by ``shift (k,)`` modulo 1, ``(n, k)``
    (float64)."""
    g = torch.tensor(lattice_generator(n, k), dtype=torch.float64)
    i = torch.arange(n, dtype=torch.float64)[:, None]
    return torch.remainder(i * g / n + shift.to(torch.float64), 1.0)


def lattice_latents(cfg: LatentConfig, gen: torch.Generator, device=None, dtype=torch.float32,
                    n: int | None = None) -> Tensor:
    """A randomly shifted rank-1 lattice of ``n`` codes (default ``n_shapes``) in ``Z``, ``(n, k)``,
    the shift drawn from ``gen`` (module docstring)."""
    n = cfg.n_shapes if n is None else n
    shift = torch.rand(cfg.dim, generator=gen, dtype=torch.float64, device=gen.device).cpu()
    u = unit_lattice(n, cfg.dim, shift)
    lo, hi = lattice_span(cfg, n)
    return (lo + (hi - lo) * u).to(device=device, dtype=dtype)


def lattice_span(cfg: LatentConfig, n: int | None = None) -> tuple[float, float]:
    """The interval each coordinate of the drawn lattice spans: ``[low, high]`` widened by half a
    cell ``w = (high - low) / (2 (n - 1))`` on each side (module docstring)."""
    n = cfg.n_shapes if n is None else n
    w = 0.5 * (cfg.high - cfg.low) / max(1, n - 1)
    return cfg.low - w, cfg.high + w


def step_codes(cfg: LatentConfig, floor: int = 1) -> int:
    """How many codes one training step trains: ``max(n_shapes, floor)`` for a lattice draw,
    ``n_shapes`` otherwise (1 for a single shape)."""
    if cfg.n_shapes == 1:
        return 1
    return max(cfg.n_shapes, floor) if cfg.draw == "lattice" else cfg.n_shapes


def step_latents(cfg: LatentConfig, gen: torch.Generator, reported: Tensor | None, device=None,
                 dtype=torch.float32, n: int | None = None) -> Tensor | None:
    """The codes one training step trains (``latents.draw``): the reported set (``fixed``), fresh
    uniform draws (``uniform``) or a randomly shifted lattice of ``n`` codes (``lattice``; default
    ``n_shapes``, see :func:`step_codes`); None for a single shape."""
    if cfg.n_shapes == 1:
        return None
    if cfg.draw == "uniform":
        return random_latents(cfg, gen, device, dtype)
    if cfg.draw == "lattice":
        return lattice_latents(cfg, gen, device, dtype, n=n)
    return reported


def heldout_latents(cfg: LatentConfig, n: int, device=None, dtype=torch.float32) -> Tensor:
    """``n`` fixed codes spread over ``Z`` that a run is judged on beside its reported ones, ``(n, k)``:
    the lattice shifted by half a cell in each coordinate (one dimension: the centres of ``n``
    equal strata of ``[low, high]``, none of them a reported code of an odd spacing)."""
    u = unit_lattice(n, cfg.dim, torch.full((cfg.dim,), 0.5 / n, dtype=torch.float64))
    return (cfg.low + (cfg.high - cfg.low) * u).to(device=device, dtype=dtype)


def grid_latents(cfg: LatentConfig, n: int, device=None, dtype=torch.float32) -> Tensor:
    """The ``n^2`` codes of an ``n x n`` grid over the first two latent axes (the others at the
    centre of ``Z``), row-major, ``(n * n, k)``."""
    t = torch.linspace(cfg.low, cfg.high, n, dtype=torch.float64)
    Z = torch.full((n * n, cfg.dim), 0.5 * (cfg.low + cfg.high), dtype=torch.float64)
    a, b = torch.meshgrid(t, t, indexing="ij")
    Z[:, 0], Z[:, 1] = a.reshape(-1), b.reshape(-1)
    return Z.to(device=device, dtype=dtype)


def latent_dim(cfg: LatentConfig) -> int:
    return 0 if cfg.n_shapes == 1 else cfg.dim


def midpoints(Z: Tensor) -> Tensor:
    """Mid-points between neighbouring codes ``(S, k) -> (S - 1, k)`` (interpolation figures)."""
    return 0.5 * (Z[1:] + Z[:-1])
