"""Independent verification of trained Gray-Scott patterns (none of it uses the training loss).

For every trained latent, ``u`` and ``v`` are sampled on a ``resolution x resolution`` periodic grid
(float64 NumPy from here on) and four checks are made:

1. **stationary residual**: equation 3 with a *spectral* Laplacian
   (:func:`ginn.tasks.gray_scott.solver.relative_residual`): ``rel`` = RMS residual / RMS reaction term of the
   same equation (the larger of the u and v equations); passes when ``rel <= residual_max``.
2. **stationarity under time integration**: the PDE is integrated from the sampled state for
   ``t_final`` (1000) time units with the ETDRK2 spectral solver
   (:class:`ginn.tasks.gray_scott.solver.GrayScottSolver`); ``change = ||v(T) - v(0)|| / ||v(0)||`` must be
   ``<= change_max`` (0.10). A control with the same mean and variance (same power spectrum) but
   random Fourier phases (:func:`ginn.tasks.gray_scott.solver.phase_randomised`) is integrated the same way and
   its ``control_change`` reported.
3. **non-trivial**: ``std(v) >= std_min`` (0.05); the uniform state ``u = 1, v = 0`` solves the PDE.
4. **diverse**: the translation-invariant distance
   ``d_ij = min_s sqrt(mean_x (v_i(x) - v_j(x + s))^2)`` (minimum over all periodic grid shifts, by FFT
   cross-correlation) to the nearest other latent must be ``>= distance_min``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from ...config import GrayScottParams, GSParams, parse_task_params
from ...extract.grid import periodic_points
from .solver import GrayScottSolver, phase_randomised, relative_residual


@dataclass(frozen=True)
class Thresholds:
    """Pass thresholds of the four checks."""

    residual_max: float = 0.1
    change_max: float = 0.10
    std_min: float = 0.05
    distance_min: float = 0.02
    t_final: float = 1000.0
    dt: float = 1.0


def sample_fields(model: nn.Module, Z: Tensor, resolution: int, chunk: int = 65536) -> np.ndarray:
    """``(S, 2, n, n)`` float64 array of ``(u, v)`` for the latents ``Z (S, k)`` on the grid ``i / n``."""
    p = next(model.parameters())
    X = periodic_points(resolution, dtype=p.dtype, device=p.device).reshape(-1, 2)
    out = []
    with torch.no_grad():
        for z in Z.to(device=p.device, dtype=p.dtype):
            vals = [model(X[s:s + chunk], z[None].expand(min(chunk, X.shape[0] - s), -1)) for s in range(0, X.shape[0], chunk)]
            out.append(torch.cat(vals).reshape(resolution, resolution, 2).permute(2, 0, 1))
    return torch.stack(out).double().cpu().numpy()


def translation_invariant_distance(V: np.ndarray) -> np.ndarray:
    """``(S, S)`` matrix of ``min_s sqrt(mean (v_i - v_j(. + s))^2)`` for patterns ``V (S, n, n)``."""
    Vh = np.fft.fft2(V)
    n2 = V.shape[-1] * V.shape[-2]
    corr = np.fft.ifft2(Vh[:, None].conj() * Vh[None, :]).real / n2
    best = corr.reshape(V.shape[0], V.shape[0], -1).max(-1)
    sq = (V * V).mean(axis=(-2, -1))
    d2 = sq[:, None] + sq[None, :] - 2.0 * best
    return np.sqrt(np.clip(d2, 0.0, None))


def verify_fields(W: np.ndarray, params: GSParams, th: Thresholds = Thresholds(), seed: int = 0) -> dict:
    """The four checks on sampled fields ``W (S, 2, n, n)``; see the module docstring.

    Returns:
        ``{"latents": [per-latent dict], "latents_passing": int, "n_latents": int,
        "distance_matrix": list, "thresholds": dict}``.
    """
    S, _, n, _ = W.shape
    solver = GrayScottSolver(n, params, th.dt)
    rng = np.random.default_rng(seed)
    D = translation_invariant_distance(W[:, 1])
    per = []
    for s in range(S):
        u, v = W[s, 0], W[s, 1]
        rr = relative_residual(u, v, params)
        _, vT = solver.integrate(u, v, th.t_final)
        change = float(np.linalg.norm(vT - v) / max(np.linalg.norm(v), 1e-300))
        uc, vc = phase_randomised(u, rng), phase_randomised(v, rng)
        _, vcT = solver.integrate(uc, vc, th.t_final)
        control = float(np.linalg.norm(vcT - vc) / max(np.linalg.norm(vc), 1e-300))
        std_v = float(v.std())
        nearest = float(np.min(np.where(np.arange(S) == s, np.inf, D[s]))) if S > 1 else float("nan")
        checks = {
            "residual": bool(rr["rel"] <= th.residual_max),
            "stationary": bool(np.isfinite(change) and change <= th.change_max),
            "nontrivial": bool(std_v >= th.std_min),
            "diverse": bool(S > 1 and nearest >= th.distance_min),
        }
        per.append({"index": s, **rr, "change": change, "control_change": control, "std_v": std_v,
                    "mean_v": float(v.mean()), "nearest_distance": nearest, "checks": checks,
                    "passed": all(checks.values())})
    return {"n_latents": S, "latents_passing": int(sum(p["passed"] for p in per)), "latents": per,
            "distance_matrix": D.tolist(), "thresholds": th.__dict__.copy()}


def verify_run(model: nn.Module, latents: Tensor, params: GrayScottParams | GSParams | dict, resolution: int = 256,
               out_dir: Path | None = None, thresholds: Thresholds = Thresholds()) -> dict:
    """Verify a trained gray-scott model.

    Arguments:
        model: the trained :class:`ginn.tasks.gray_scott.GrayScottField` (``(x, z) -> (n, 2)``).
        latents: trained latent codes ``(S, k)``.
        params: :class:`ginn.config.GSParams`, :class:`ginn.config.GrayScottParams`, or a
            gray-scott ``params`` mapping.
        resolution: grid points per axis (256).
        out_dir: if given (the run directory), ``u`` and ``v`` of every latent are saved there as
            ``verify_u_{s:02d}.npy`` / ``verify_v_{s:02d}.npy`` (``(resolution, resolution)`` float64,
            ``[i, j]`` at ``x = (i, j) / resolution``).

    Returns:
        the dict of :func:`verify_fields` (``latents_passing`` at the top level), plus ``resolution``
        and ``files``.
    """
    if isinstance(params, dict):
        params = parse_task_params("gray-scott", params)
    gs = params.gs if isinstance(params, GrayScottParams) else params
    W = sample_fields(model, latents, resolution)
    out = verify_fields(W, gs, thresholds)
    out["resolution"] = resolution
    files = []
    if out_dir is not None:
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        for s in range(W.shape[0]):
            for c, name in enumerate("uv"):
                f = out_dir / f"verify_{name}_{s:02d}.npy"
                np.save(f, W[s, c])
                files.append(str(f))
    out["files"] = files
    return out
