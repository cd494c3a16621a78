"""Derivatives of fields sampled on a periodic ``N x N`` grid of the unit square (torch).

Grid convention: an array ``F[..., i, j]`` holds the field at ``x = ((i + o_0) / N, (j + o_1) / N)``
(axis -2 is ``x_0``, axis -1 is ``x_1``) for an offset ``o`` in grid units; spacing ``h = 1 / N``.

Two families of operators (both periodic, both batched over any leading axes):

* **Finite differences** (the paper's choice): second-order central differences, the gradient
  ``(F[i+1] - F[i-1]) / 2h`` and the 5-point Laplacian ``(F[i+1] + F[i-1] + F[j+1] + F[j-1] - 4F) / h^2``.
  On a grid mode ``exp(2 pi i m x)`` (integer ``m``, ``|m| < N/2``) they act *exactly* as
  multiplication by their symbols ``i sin(2 pi m h) / h`` and ``-(2 - 2 cos(2 pi m h)) / h^2``
  (:func:`fd_gradient_symbol`, :func:`fd_laplacian_symbol`); "exact" in the tests means agreement
  with these symbols to round-off. They approximate the true derivatives ``2 pi i m`` and
  ``-(2 pi m)^2`` to second order in ``m h``.
* **Spectral** derivatives (FFT): exact, to round-off, for every grid mode below Nyquist
  (``|m| < N/2``; the Nyquist mode's odd derivative is set to 0).
"""

from __future__ import annotations

import math

import torch
from torch import Tensor


def fd_gradient(F: Tensor) -> Tensor:
    """Second-order central-difference gradient: ``(..., n, n) -> (..., 2, n, n)`` (periodic)."""
    n = F.shape[-1]
    g0 = (torch.roll(F, -1, dims=-2) - torch.roll(F, 1, dims=-2)) * (n / 2.0)
    g1 = (torch.roll(F, -1, dims=-1) - torch.roll(F, 1, dims=-1)) * (n / 2.0)
    return torch.stack([g0, g1], dim=-3)


def fd_laplacian(F: Tensor) -> Tensor:
    """Five-point Laplacian: ``(..., n, n) -> (..., n, n)`` (periodic)."""
    n = F.shape[-1]
    s = torch.roll(F, -1, -2) + torch.roll(F, 1, -2) + torch.roll(F, -1, -1) + torch.roll(F, 1, -1) - 4.0 * F
    return s * float(n * n)


def fd_gradient_symbol(m: float, n: int) -> float:
    """Symbol of :func:`fd_gradient` on ``exp(2 pi i m x)`` divided by ``i``: ``sin(2 pi m / n) n``."""
    return math.sin(2.0 * math.pi * m / n) * n


def fd_laplacian_symbol(m: float, n: int) -> float:
    """Symbol (one axis) of :func:`fd_laplacian` on ``exp(2 pi i m x)``: ``-(2 - 2 cos(2 pi m / n)) n^2``."""
    return -(2.0 - 2.0 * math.cos(2.0 * math.pi * m / n)) * n * n


def _wavenumbers(n: int, dtype: torch.dtype, device) -> Tensor:
    """Angular wavenumbers ``2 pi m`` of ``torch.fft.fftfreq`` order, ``(n,)``."""
    return 2.0 * math.pi * torch.fft.fftfreq(n, d=1.0 / n, dtype=dtype, device=device)


def spectral_gradient(F: Tensor) -> Tensor:
    """Spectral gradient: ``(..., n, n) -> (..., 2, n, n)``; the Nyquist mode's derivative is 0."""
    n = F.shape[-1]
    k = _wavenumbers(n, F.dtype, F.device)
    if n % 2 == 0:
        k = k.clone()
        k[n // 2] = 0.0
    Fh = torch.fft.fft2(F)
    g0 = torch.fft.ifft2(Fh * (1j * k[:, None])).real
    g1 = torch.fft.ifft2(Fh * (1j * k[None, :])).real
    return torch.stack([g0, g1], dim=-3)


def spectral_laplacian(F: Tensor) -> Tensor:
    """Spectral Laplacian: ``(..., n, n) -> (..., n, n)``."""
    n = F.shape[-1]
    k = _wavenumbers(n, F.dtype, F.device)
    k2 = k[:, None] ** 2 + k[None, :] ** 2
    return torch.fft.ifft2(torch.fft.fft2(F) * (-k2)).real


def grid_derivatives(F: Tensor, method: str) -> tuple[Tensor, Tensor]:
    """``(gradient (..., 2, n, n), Laplacian (..., n, n))`` by ``method`` ``"fd"`` or ``"spectral"``."""
    if method == "fd":
        return fd_gradient(F), fd_laplacian(F)
    if method == "spectral":
        return spectral_gradient(F), spectral_laplacian(F)
    raise ValueError(f"unknown grid derivative method {method!r} (fd, spectral)")


def fourier_shift(F: Tensor, delta: Tensor) -> Tensor:
    """Resample a periodic grid function at points translated by ``delta`` grid units.

    ``F (..., n, n)`` holds samples at ``((i, j) + o) / n``; the result holds the trigonometric
    interpolant of ``F`` at ``((i, j) + o + delta) / n`` (exact for fields without energy at the
    Nyquist mode, whose shifted samples would be complex; the real part is kept).

    Arguments:
        delta: ``(2,)`` translation in grid units.
    """
    n = F.shape[-1]
    k = _wavenumbers(n, F.dtype, F.device)
    d = delta.to(dtype=F.dtype, device=F.device)
    phase = torch.exp(1j * (k[:, None] * d[0] + k[None, :] * d[1]) / n)
    return torch.fft.ifft2(torch.fft.fft2(F) * phase).real
