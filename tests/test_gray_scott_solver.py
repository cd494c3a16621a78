"""The independent spectral Gray-Scott solver: fixed points and exact linear decay."""

import math

import numpy as np
import pytest

from ginn.config import GSParams
from ginn.tasks.gray_scott.solver import GrayScottSolver, phase_randomised, relative_residual, residuals, spectral_laplacian

P = GSParams()


def test_uniform_state_is_fixed():
    n = 32
    s = GrayScottSolver(n, P, dt=1.0)
    u, v = s.integrate(np.ones((n, n)), np.zeros((n, n)), 500.0)
    assert np.abs(u - 1).max() < 1e-12
    assert np.abs(v).max() < 1e-12
    Ru, Rv = residuals(np.ones((n, n)), np.zeros((n, n)), P)
    assert np.abs(Ru).max() == 0 and np.abs(Rv).max() == 0


@pytest.mark.parametrize("m", [(1, 0), (3, 2), (6, 5)])
def test_linear_decay_of_small_perturbation(m):
    n, eps, T = 32, 1e-6, 200.0
    x = np.arange(n) / n
    X0, X1 = np.meshgrid(x, x, indexing="ij")
    mode = np.cos(2 * np.pi * (m[0] * X0 + m[1] * X1))
    k2 = (2 * np.pi) ** 2 * (m[0] ** 2 + m[1] ** 2)
    s = GrayScottSolver(n, P, dt=2.0)
    u, v = s.integrate(1 + eps * mode, eps * mode, T)
    # linearised about (1, 0): du' = (-D_u k^2 - alpha) du' - v'^2..., dv' = (-D_v k^2 - alpha - beta) v' + O(eps^2)
    amp_u = (u - 1).ravel() @ mode.ravel() / (mode.ravel() @ mode.ravel())
    amp_v = v.ravel() @ mode.ravel() / (mode.ravel() @ mode.ravel())
    exp_u = eps * math.exp(-(P.D_u * k2 + P.alpha) * T)
    exp_v = eps * math.exp(-(P.D_v * k2 + P.alpha + P.beta) * T)
    assert amp_u == pytest.approx(exp_u, rel=1e-4)
    assert amp_v == pytest.approx(exp_v, rel=1e-4)


def test_spectral_laplacian_exact():
    n = 48
    x = np.arange(n) / n
    X0, X1 = np.meshgrid(x, x, indexing="ij")
    f = np.sin(2 * np.pi * (5 * X0 - 7 * X1) + 0.2)
    lap = spectral_laplacian(f)
    assert np.abs(lap + (2 * np.pi) ** 2 * 74 * f).max() < 1e-9 * (2 * np.pi) ** 2 * 74


def test_relative_residual_of_a_non_solution():
    n = 32
    rng = np.random.default_rng(1)
    u, v = 1 + 0.1 * rng.standard_normal((n, n)), 0.2 + 0.1 * rng.standard_normal((n, n))
    r = relative_residual(u, v, P)
    Ru, Rv = residuals(u, v, P)
    assert r["residual_u"] == pytest.approx(np.sqrt(np.mean(Ru**2)))
    assert r["rel"] == max(r["rel_u"], r["rel_v"]) and r["rel"] > 0.5


def test_phase_randomised_keeps_mean_variance_and_spectrum():
    n = 64
    rng = np.random.default_rng(2)
    x = np.arange(n) / n
    X0, X1 = np.meshgrid(x, x, indexing="ij")
    F = 0.2 + 0.1 * np.sin(2 * np.pi * 7 * X0) * np.cos(2 * np.pi * 3 * X1) + 0.05 * np.cos(2 * np.pi * (2 * X0 + 5 * X1))
    G = phase_randomised(F, rng)
    assert G.mean() == pytest.approx(F.mean(), abs=1e-12)
    assert G.std() == pytest.approx(F.std(), rel=1e-12)
    assert np.allclose(np.abs(np.fft.fft2(G)), np.abs(np.fft.fft2(F)), atol=1e-9)
    assert np.abs(G - F).max() > 0.01


def _solver_pattern(n, seed, T):
    """A Turing pattern computed by the solver itself from a smooth random start (mean (0.6, 0.15))."""
    rng = np.random.default_rng(seed)
    f = np.fft.fftfreq(n, 1.0 / n)
    K = np.sqrt(f[:, None] ** 2 + f[None, :] ** 2)

    def smooth():
        F = np.fft.ifft2(np.fft.fft2(rng.standard_normal((n, n))) * np.exp(-((K / 6) ** 2))).real
        return 0.1 * F / F.std()

    s = GrayScottSolver(n, P, dt=1.0)
    return s.integrate(0.6 + smooth(), 0.15 + smooth(), T)


@pytest.mark.slow
def test_verification_passes_true_stationary_patterns():
    """The four checks pass on patterns the solver has converged to (so they can be met), and the
    phase-randomised control changes far more."""
    from ginn.tasks.gray_scott.checks import verify_fields

    n = 64
    W = np.stack([np.stack(_solver_pattern(n, seed, 6000.0)) for seed in (0, 1)])
    out = verify_fields(W, P)
    for lat in out["latents"]:
        assert lat["rel"] < 0.1 and lat["change"] < 0.1 and lat["std_v"] > 0.05
        assert lat["control_change"] > 5 * lat["change"]
    assert out["latents_passing"] == 2
