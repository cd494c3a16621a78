"""How well can the gray-scott networks represent a *known* stationary pattern? (docs/gray-scott.md)

A diagnostic, not a training mode: the independent solver makes ``K`` converged labyrinths on a
64 x 64 grid (6000 time units from smooth random starts), and the two-network field of the
`gray-scott` problem (SIREN, periodic encoding, latent by concatenation) is fitted to them by plain
regression on randomly translated grids (targets moved there by an exact Fourier shift). The
relative residual of the fitted field at 256 x 256 (the check of ``ginn eval``) then says what the
representation and the optimiser can reach at best: a PINN trained on the PDE cannot do better
than a regression onto the exact answer.

    python scripts/gray_scott_fit_probe.py --patterns 1 --iterations 2000 --w0 30 --sobolev 300

``--sobolev c`` adds ``c * mean |D lap (W - T)|^2`` (the diffusion term of the residual applied to
the misfit), as ``params.step_sobolev`` does in training.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from ginn.config import GSParams
from ginn.models.base import PeriodicEncoding
from ginn.models.siren import Siren
from ginn.tasks.gray_scott import GrayScottField, fixed_latents, sample_grid
from ginn.tasks.gray_scott.finite_diff import fourier_shift, spectral_laplacian
from ginn.tasks.gray_scott.solver import GrayScottSolver, relative_residual


def fourier_resample(F: np.ndarray, n: int) -> np.ndarray:
    """Trigonometric interpolation of a periodic ``(m, m)`` array onto an ``(n, n)`` grid, ``n >= m``."""
    m = F.shape[0]
    spec = np.fft.fftshift(np.fft.fft2(F))
    out = np.zeros((n, n), complex)
    o = (n - m) // 2
    out[o:o + m, o:o + m] = spec
    return np.real(np.fft.ifft2(np.fft.ifftshift(out))) * (n / m) ** 2


def solver_patterns(k: int, n: int, p: GSParams, seed: int = 0) -> np.ndarray:
    """``k`` converged patterns ``(k, 2, n, n)`` from smooth random starts."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(k):
        u0 = 0.6 + 0.1 * fourier_resample(rng.standard_normal((16, 16)), n)
        v0 = 0.15 + 0.1 * fourier_resample(rng.standard_normal((16, 16)), n)
        out.append(np.stack(GrayScottSolver(n, p, dt=1.0).integrate(u0, v0, 6000.0)))
    return np.stack(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--patterns", type=int, default=1, help="number of patterns (latents) K")
    ap.add_argument("--iterations", type=int, default=2000)
    ap.add_argument("--hidden", default="256,128", help="hidden widths, comma separated")
    ap.add_argument("--w0", type=float, default=30.0, help="omega_0 of the first layer")
    ap.add_argument("--lr", type=float, default=1.5e-3, help="Adam learning rate, halved at each quarter")
    ap.add_argument("--sobolev", type=float, default=0.0)
    ap.add_argument("--threads", type=int, default=1)
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    n, p, dt = 64, GSParams(), torch.float32
    T = torch.tensor(solver_patterns(a.patterns, n, p), dtype=dt)
    hidden = [int(h) for h in a.hidden.split(",")]

    def net() -> Siren:
        return Siren(2, hidden, latent_dim=1, w0_first=a.w0, w0_hidden=1.0, encoding=PeriodicEncoding())

    torch.manual_seed(0)
    model = GrayScottField(net(), net(), 0.6, 0.15, 0.3).to(dt)
    Z = fixed_latents(a.patterns, 1, -1.0, 1.0, 0).to(dt) if a.patterns > 1 else torch.zeros(1, 1, dtype=dt)
    D = torch.tensor([p.D_u, p.D_v], dtype=dt)[:, None, None]
    opt = torch.optim.Adam(model.parameters(), lr=a.lr)
    gen = torch.Generator().manual_seed(1)
    quarter = max(1, a.iterations // 4)
    t0 = time.time()
    for it in range(a.iterations):
        for group in opt.param_groups:
            group["lr"] = a.lr * 0.5 ** (it // quarter)
        off = torch.rand(2, generator=gen, dtype=dt)
        d = sample_grid(model, Z, n, off) - fourier_shift(T, off)
        loss = (d * d).mean()
        if a.sobolev > 0:
            loss = loss + a.sobolev * ((D * spectral_laplacian(d)) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        if (it + 1) % max(1, a.iterations // 8) == 0 or it + 1 == a.iterations:
            with torch.no_grad():
                F = sample_grid(model, Z, 256).double().numpy()
            rel = [relative_residual(F[i, 0], F[i, 1], p)["rel"] for i in range(a.patterns)]
            print(f"iteration {it + 1}: loss {loss.item():.2e}, rel at 256^2 "
                  + " ".join(f"{r:.3f}" for r in rel) + f" ({time.time() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
