"""What the Gray-Scott losses compare: distances between patterns (plain and up to a periodic
translation) and the PDE's own pseudo-time step."""

from __future__ import annotations

import math

import torch
from torch import Tensor

from ...config import GSParams

__all__ = ["shift_invariant_sq_distance", "pattern_distance", "pseudo_time_step"]


def shift_invariant_sq_distance(A: Tensor, B: Tensor) -> Tensor:
    """``min over periodic grid shifts s of mean_x (A(x) - B(x + s))^2``, batched.

    Arguments:
        A: ``(S, n, n)``; B: ``(T, n, n)``.

    Returns:
        ``(S, T)``: ``mean A^2 + mean B^2 - 2 max_s corr(A, B)(s)`` (FFT cross-correlation).
    """
    n2 = A.shape[-1] * A.shape[-2]
    Ah, Bh = torch.fft.fft2(A), torch.fft.fft2(B)
    corr = torch.fft.ifft2(Ah[:, None].conj() * Bh[None, :]).real / n2  # (S, T, n, n)
    best = corr.flatten(-2).max(dim=-1).values
    a2 = (A * A).mean(dim=(-2, -1))
    b2 = (B * B).mean(dim=(-2, -1))
    return (a2[:, None] + b2[None, :] - 2.0 * best).clamp_min(0.0)


def pattern_distance(V: Tensor, kind: str) -> Tensor:
    """Distance matrix ``(S, S)`` between patterns ``V (S, n, n)`` (``rms`` or ``shift``)."""
    if kind == "rms":
        diff = V[:, None] - V[None, :]
        return (diff * diff).mean(dim=(-2, -1)).clamp_min(1e-12).sqrt()
    if kind == "shift":
        return shift_invariant_sq_distance(V, V).clamp_min(1e-12).sqrt()
    raise ValueError(f"unknown pattern distance {kind!r} (rms, shift)")


def pseudo_time_step(W: Tensor, gs: GSParams, dt: float, count: int) -> Tensor:
    """``count`` semi-implicit (IMEX Euler) steps of the Gray-Scott PDE on the training grid.

    Diffusion and the linear decay (``-alpha u``, ``-(alpha + beta) v``) implicit per Fourier mode,
    the rest (``-u v^2 + alpha``, ``+u v^2``) explicit; spectral Laplacian on the (translated) grid.
    A state is a fixed point exactly when it solves the stationary equation 3 on the grid.

    Arguments:
        W: ``(S, 2, n, n)`` sampled ``(u, v)``.

    Returns:
        the advanced state, ``(S, 2, n, n)``.
    """
    n = W.shape[-1]
    k = 2.0 * math.pi * torch.fft.fftfreq(n, d=1.0 / n, dtype=W.dtype, device=W.device)
    k2 = k[:, None] ** 2 + k[None, :] ** 2
    den = torch.stack([1.0 + dt * (gs.D_u * k2 + gs.alpha), 1.0 + dt * (gs.D_v * k2 + gs.alpha + gs.beta)])
    for _ in range(count):
        u, v = W[:, 0], W[:, 1]
        uvv = u * v * v
        N = torch.stack([W[:, 0] + dt * (gs.alpha - uvv), W[:, 1] + dt * uvv], dim=1)
        W = torch.fft.ifft2(torch.fft.fft2(N) / den).real
    return W
