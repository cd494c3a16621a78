"""Periodic grid derivatives: exact on grid modes (against the analytic symbols)."""

import math

import pytest
import torch

from ginn.extract.grid import periodic_points as grid_points
from ginn.tasks.gray_scott.finite_diff import (
    fd_gradient,
    fd_gradient_symbol,
    fd_laplacian,
    fd_laplacian_symbol,
    spectral_gradient,
    spectral_laplacian,
)

N = 64
MODES = [(1, 0), (0, 3), (2, 5), (7, -4), (13, 9), (31, 1)]


def _mode(x, m0, m1, phase=0.3):
    a = 2 * math.pi * (m0 * x[..., 0] + m1 * x[..., 1]) + phase
    return torch.sin(a), torch.cos(a)


@pytest.mark.parametrize("m0,m1", MODES)
@pytest.mark.parametrize("offset", [None, (0.37, 0.81)])
def test_fd_operators_match_their_symbols(m0, m1, offset):
    off = None if offset is None else torch.tensor(offset, dtype=torch.float64)
    x = grid_points(N, off, dtype=torch.float64)
    s, c = _mode(x, m0, m1)
    g = fd_gradient(s)
    # d/dx_i sin(a) -> symbol_i * cos(a) with symbol sin(2 pi m_i h) / h
    assert torch.allclose(g[0], fd_gradient_symbol(m0, N) * c, atol=1e-10 * N, rtol=0)
    assert torch.allclose(g[1], fd_gradient_symbol(m1, N) * c, atol=1e-10 * N, rtol=0)
    lap = fd_laplacian(s)
    sym = fd_laplacian_symbol(m0, N) + fd_laplacian_symbol(m1, N)
    scale = max(1.0, abs(sym))
    assert (lap - sym * s).abs().max().item() <= 1e-10 * scale


@pytest.mark.parametrize("m0,m1", MODES)
def test_spectral_operators_are_exact_below_nyquist(m0, m1):
    x = grid_points(N, torch.tensor([0.25, 0.6], dtype=torch.float64), dtype=torch.float64)
    s, c = _mode(x, m0, m1)
    g = spectral_gradient(s)
    k0, k1 = 2 * math.pi * m0, 2 * math.pi * m1
    assert (g[0] - k0 * c).abs().max().item() <= 1e-10 * max(1.0, abs(k0))
    assert (g[1] - k1 * c).abs().max().item() <= 1e-10 * max(1.0, abs(k1))
    lap = spectral_laplacian(s)
    k2 = k0 * k0 + k1 * k1
    assert (lap + k2 * s).abs().max().item() <= 1e-10 * k2


def test_fd_symbols_are_second_order():
    # the 5-point Laplacian approximates -(2 pi m)^2 with relative error (2 pi m h)^2 / 12
    m = 3
    exact = -(2 * math.pi * m) ** 2
    rel = abs(fd_laplacian_symbol(m, N) - exact) / abs(exact)
    assert rel == pytest.approx((2 * math.pi * m / N) ** 2 / 12, rel=1e-2)


def test_batched_shapes():
    F = torch.randn(3, 2, 16, 16, dtype=torch.float64)
    assert fd_gradient(F).shape == (3, 2, 2, 16, 16)
    assert spectral_gradient(F).shape == (3, 2, 2, 16, 16)
    assert fd_laplacian(F).shape == (3, 2, 16, 16)
    # the Laplacian of anything periodic integrates to zero
    assert fd_laplacian(F).sum(dim=(-2, -1)).abs().max().item() < 1e-9
    assert spectral_laplacian(F).sum(dim=(-2, -1)).abs().max().item() < 1e-9


def test_fourier_shift_resamples_trig_fields_exactly():
    """``fourier_shift`` of samples of ``sin(2 pi (3 x + 5 y)) + cos(2 pi 7 x)`` on the grid with
    offset ``o`` equals the samples on the grid with offset ``o + delta``, to 1e-12 (float64)."""
    from ginn.tasks.gray_scott.finite_diff import fourier_shift

    def field(X):
        return torch.sin(2 * math.pi * (3 * X[..., 0] + 5 * X[..., 1])) + torch.cos(2 * math.pi * 7 * X[..., 0])

    n = 32
    o = torch.tensor([0.3, 0.7], dtype=torch.float64)
    delta = torch.tensor([0.45, -1.8], dtype=torch.float64)
    F = field(grid_points(n, o, dtype=torch.float64))
    G = fourier_shift(F[None], delta)[0]
    assert torch.allclose(G, field(grid_points(n, o + delta, dtype=torch.float64)), atol=1e-12)
    assert torch.allclose(fourier_shift(F, torch.zeros(2, dtype=torch.float64)), F, atol=1e-13)
