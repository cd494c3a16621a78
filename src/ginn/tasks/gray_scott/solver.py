"""An independent classical solver for the Gray-Scott system on the periodic unit square (NumPy).

Nothing here touches the networks or the training losses; the verification uses it to judge
sampled patterns.

The PDE (paper equation 2) with ``D_u``, ``D_v``, feed ``alpha`` and kill ``beta``::

    u_t = D_u lap u - u v^2 + alpha (1 - u)
    v_t = D_v lap v + u v^2 - (alpha + beta) v

**Time integrator**: Fourier pseudo-spectral in space; in time a semi-implicit exponential scheme
(ETDRK2 of Cox & Matthews 2002): the stiff linear part ``L_u = -(D_u k^2 + alpha)``,
``L_v = -(D_v k^2 + alpha + beta)`` is integrated exactly mode by mode, the nonlinear part
``N_u = -u v^2 + alpha``, ``N_v = u v^2`` explicitly with a second-order predictor-corrector.
Consequences used by the tests: the linear decay of every Fourier mode is reproduced exactly
(``exp(L dt)`` per step), and a state is a fixed point of a step exactly when it is a stationary
solution of the (spatially discretised) PDE, whatever ``dt``.
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft

from ...config import GSParams


def wavenumbers2(n: int) -> np.ndarray:
    """``|k|^2`` of the ``n x n`` periodic unit-square grid in FFT order, ``(n, n)``."""
    k = 2.0 * np.pi * np.fft.fftfreq(n, d=1.0 / n)
    return k[:, None] ** 2 + k[None, :] ** 2


def spectral_laplacian(F: np.ndarray) -> np.ndarray:
    """Spectral Laplacian of periodic samples ``(..., n, n)`` on the unit square."""
    k2 = wavenumbers2(F.shape[-1])
    return np.fft.ifft2(np.fft.fft2(F) * (-k2)).real


def residuals(u: np.ndarray, v: np.ndarray, p: GSParams) -> tuple[np.ndarray, np.ndarray]:
    """Stationary residuals ``(R_u, R_v)`` of equation 3 with the spectral Laplacian, each ``(n, n)``."""
    uvv = u * v * v
    Ru = p.D_u * spectral_laplacian(u) - uvv + p.alpha * (1.0 - u)
    Rv = p.D_v * spectral_laplacian(v) + uvv - (p.alpha + p.beta) * v
    return Ru, Rv


def relative_residual(u: np.ndarray, v: np.ndarray, p: GSParams) -> dict[str, float]:
    """Residuals relative to the reaction terms.

    ``rel_u = rms(R_u) / rms(u v^2 + alpha (1 - u) ...)``: each residual's RMS divided by the RMS of the
    reaction part of its own equation, ``-u v^2 + alpha (1 - u)`` and ``u v^2 - (alpha + beta) v``
    (for a stationary pattern the reaction balances the diffusion, so 1 means "no balance at all").

    Returns:
        ``{"residual_u", "residual_v", "reaction_u", "reaction_v", "rel_u", "rel_v", "rel"}``
        (``rel`` is the larger of the two; ``residual_*`` and ``reaction_*`` are RMS values).
    """
    Ru, Rv = residuals(u, v, p)
    uvv = u * v * v
    ru = np.sqrt(np.mean((-uvv + p.alpha * (1.0 - u)) ** 2))
    rv = np.sqrt(np.mean((uvv - (p.alpha + p.beta) * v) ** 2))
    eu, ev = float(np.sqrt(np.mean(Ru**2))), float(np.sqrt(np.mean(Rv**2)))
    rel_u, rel_v = float(eu / max(ru, 1e-300)), float(ev / max(rv, 1e-300))
    return {"residual_u": eu, "residual_v": ev, "reaction_u": float(ru), "reaction_v": float(rv),
            "rel_u": rel_u, "rel_v": rel_v, "rel": max(rel_u, rel_v)}


def _phi1(L: np.ndarray, h: float) -> np.ndarray:
    """``(exp(L h) - 1) / L`` (``h`` where ``L = 0``)."""
    out = np.full_like(L, h)
    nz = np.abs(L * h) > 1e-12
    out[nz] = np.expm1(L[nz] * h) / L[nz]
    return out


def _phi2(L: np.ndarray, h: float) -> np.ndarray:
    """``(exp(L h) - 1 - L h) / (L^2 h)`` (``h / 2`` where ``L = 0``)."""
    out = np.full_like(L, h / 2.0)
    nz = np.abs(L * h) > 1e-6
    Ln = L[nz]
    out[nz] = (np.expm1(Ln * h) - Ln * h) / (Ln * Ln * h)
    return out


class GrayScottSolver:
    """ETDRK2 pseudo-spectral integrator of the Gray-Scott PDE on an ``n x n`` periodic grid.

    Arguments:
        n: grid points per axis.
        params: coefficients.
        dt: time step (default 1.0; the reaction time scale is ``1 / (alpha + beta) ~ 12``).
    """

    def __init__(self, n: int, params: GSParams = GSParams(), dt: float = 1.0):
        self.n, self.p, self.dt = int(n), params, float(dt)
        k0 = 2.0 * np.pi * np.fft.fftfreq(self.n, d=1.0 / self.n)
        k1 = 2.0 * np.pi * np.fft.rfftfreq(self.n, d=1.0 / self.n)
        k2 = k0[:, None] ** 2 + k1[None, :] ** 2  # real-FFT layout (n, n // 2 + 1)
        self.L = np.stack([-(params.D_u * k2 + params.alpha), -(params.D_v * k2 + params.alpha + params.beta)])
        self.E = np.exp(self.L * self.dt)
        self.P1 = _phi1(self.L, self.dt)
        self.P2 = _phi2(self.L, self.dt)

    def _nonlinear_hat(self, W: np.ndarray) -> np.ndarray:
        u, v = W[0], W[1]
        uvv = u * v * v
        N = np.stack([-uvv + self.p.alpha, uvv])
        return sfft.rfft2(N)

    def _real(self, Wh: np.ndarray) -> np.ndarray:
        return sfft.irfft2(Wh, s=(self.n, self.n))

    def step_hat(self, Wh: np.ndarray) -> np.ndarray:
        """One ETDRK2 step on real-FFT coefficients ``(2, n, n // 2 + 1)``."""
        Nn = self._nonlinear_hat(self._real(Wh))
        Ah = self.E * Wh + self.P1 * Nn
        Na = self._nonlinear_hat(self._real(Ah))
        return Ah + self.P2 * (Na - Nn)

    def integrate(self, u: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Integrate from ``(u, v)`` (each ``(n, n)``) for time ``t`` (rounded to whole steps).

        Returns:
            ``(u(t), v(t))``, each ``(n, n)``.
        """
        if u.shape != (self.n, self.n) or v.shape != (self.n, self.n):
            raise ValueError(f"expected fields of shape {(self.n, self.n)}, got {u.shape} and {v.shape}")
        steps = int(round(t / self.dt))
        Wh = sfft.rfft2(np.stack([u, v]).astype(np.float64))
        for _ in range(steps):
            Wh = self.step_hat(Wh)
        W = self._real(Wh)
        return W[0], W[1]


def phase_randomised(F: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A real field with the same power spectrum (hence the same mean and variance) as ``F`` ``(n, n)``
    but uniformly random Fourier phases (a surrogate pattern that is not a solution).

    The random phases are those of the FFT of white noise (Hermitian symmetric, so the result is real).
    """
    Fh = np.fft.fft2(F)
    ph = np.fft.fft2(rng.standard_normal(F.shape))
    ph = ph / np.maximum(np.abs(ph), 1e-300)
    ph[0, 0] = 1.0
    n = F.shape[0]
    if n % 2 == 0:  # self-conjugate modes must stay real: keep their sign only
        for i in (0, n // 2):
            for j in (0, n // 2):
                ph[i, j] = 1.0
    out = np.fft.ifft2(np.abs(Fh) * ph).real
    # rescale the fluctuation so that the variance is exactly that of F (round-off aside)
    d = out - out.mean()
    s = d.std()
    return F.mean() + d * (F.std() / s if s > 0 else 0.0)
