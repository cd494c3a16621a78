"""The generative PINN for stationary Gray-Scott Turing patterns (paper Section 4.3, Appendix A.6).

Model: :class:`GrayScottField`, two networks (one for ``u``, one for ``v``), each conditioned on a
latent code by concatenation, on the periodic unit square through the encoding
``x_i -> (sin 2 pi x_i, cos 2 pi x_i)``; called as ``model(x, z)`` it returns ``(n, 2)`` = ``(u, v)``.

Losses (all latents in one batched forward pass on one shared grid):

* ``residual``: ``mean(R_u^2) + mean(R_v^2)`` of the stationary equation 3, derivatives by periodic
  finite differences on an ``N x N`` grid (paper: 64) randomly translated every iteration
  (``params.derivatives``: ``fd`` (default), ``spectral`` (FFT on the same grid) or ``autograd``
  (through :func:`ginn.fields.evaluate`, an order of magnitude slower)).
* ``gradient``: the reward ``-mean_s min(cap, mean_x (|grad u|^2 + |grad v|^2))`` per latent ``s``.
  The paper prints ``-max(1, ...)``, which is constant (no gradient) below 1 and unbounded above; we
  read it as the cap ``min(1, ...)``: it pushes a pattern away from the uniform state until its mean
  squared gradient reaches ``cap`` (1) and then stops acting, so it cannot grow without bound.
* ``diversity``: ``-delta`` with the minimal aggregation of Appendix E
  (:func:`ginn.losses.diversity.aggregate_min`, exponent ``cfg.diversity.p``) of a distance between
  the sampled patterns of different latents. Patterns are fields, not shapes, so the distance is a
  field distance of ``v`` on the shared grid: ``params.diversity_distance = "rms"`` (the RMS
  difference ``sqrt(mean_x (v_i - v_j)^2)``) or ``"shift"`` (its minimum over the grid's periodic
  translations, computed by FFT cross-correlation; two translated copies of a pattern have distance 0).

Weights (paper): residual 1, gradient 1e-4, diversity 1e-7; they live in ``cfg.params.losses``
(:class:`ginn.config.GrayScottParams`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import torch
from torch import Tensor, nn

from ...config import GrayScottParams, GSParams, LossTerm, RunConfig, ShapeParams, parse_task_params
from ...errors import ConfigError
from ...eval.gray_scott import verify_run
from ...extract.grid import check_grid_memory, periodic_points
from ...fields import evaluate, laplacian
from ...losses.diversity import aggregate
from ...models import ConcatConditioning, FourierMLP, PeriodicEncoding, Siren
from ...train.task import Task
from ...viz.explorer_pinn import write_pattern_explorer
from ...viz.gray_scott import write_patterns
from .finite_diff import fourier_shift, grid_derivatives, spectral_laplacian


def parse_params(params: dict | GrayScottParams | ShapeParams | None) -> GrayScottParams:
    """Validate a gray-scott ``params`` mapping; raises :class:`ConfigError` with one line naming the bad key."""
    if isinstance(params, GrayScottParams):
        return params
    if isinstance(params, ShapeParams):  # a config without a params group: the defaults
        return GrayScottParams()
    return parse_task_params("gray-scott", params)


class GrayScottField(nn.Module):
    """``(u, v)`` of every latent: two networks ``model.u``, ``model.v``, each ``(x, z) -> (n,)``.

    ``forward(x (n, 2), z (n, k)) -> (n, 2)`` with columns ``u = u_offset + scale * model.u(x, z)``
    and ``v = v_offset + scale * model.v(x, z)`` (defaults: the raw outputs).
    """

    def __init__(self, u: nn.Module, v: nn.Module, u_offset: float = 0.0, v_offset: float = 0.0, scale: float = 1.0):
        super().__init__()
        self.u, self.v = u, v
        self.u_offset, self.v_offset, self.scale = float(u_offset), float(v_offset), float(scale)

    def field_u(self, x: Tensor, z: Tensor | None) -> Tensor:
        return self.scale * self.u(x, z) + self.u_offset

    def field_v(self, x: Tensor, z: Tensor | None) -> Tensor:
        return self.scale * self.v(x, z) + self.v_offset

    def forward(self, x: Tensor, z: Tensor | None = None) -> Tensor:
        return torch.stack([self.field_u(x, z), self.field_v(x, z)], dim=-1)


def build_field(cfg: RunConfig, params: GrayScottParams) -> GrayScottField:
    """Two identical networks per ``cfg.model`` (``siren`` or ``fourier``), periodic encoding always on."""
    k = cfg.latents.dim if cfg.latents.n_shapes > 1 or cfg.latents.random else 0
    m = cfg.model

    def one() -> nn.Module:
        if m.kind == "siren":
            return Siren(2, m.hidden, latent_dim=k, w0_first=m.w0_first, w0_hidden=m.w0_hidden,
                         encoding=PeriodicEncoding(), conditioning=ConcatConditioning(m.latent_scale))
        if m.kind == "fourier":
            return FourierMLP(2, m.hidden, latent_dim=k, sigma=m.sigma, n_features=m.n_features,
                              activation=m.activation, beta=m.beta, pre_encoding=PeriodicEncoding(),
                              conditioning=ConcatConditioning(m.latent_scale))
        raise ConfigError(f"config field 'model.kind': {m.kind!r} is not supported by gray-scott (siren, fourier)")

    return GrayScottField(one(), one(), params.u_offset, params.v_offset, params.output_scale)


def fixed_latents(n: int, dim: int, low: float, high: float, seed: int) -> Tensor:
    """The trained latent codes ``(n, dim)``: evenly spaced for ``dim == 1``, else uniform with ``seed``."""
    if dim == 1:
        return torch.linspace(low, high, n, dtype=torch.float64)[:, None]
    g = torch.Generator().manual_seed(seed + 7919)
    return low + (high - low) * torch.rand(n, dim, generator=g, dtype=torch.float64)


def sample_grid(model: GrayScottField, Z: Tensor, n: int, offset: Tensor | None = None) -> Tensor:
    """All latents on one shared grid in one forward pass: ``(S, 2, n, n)`` (channel 0 u, 1 v)."""
    S = Z.shape[0]
    X = periodic_points(n, offset, dtype=Z.dtype, device=Z.device).reshape(-1, 2)
    x = X[None].expand(S, -1, -1).reshape(-1, 2)
    z = Z[:, None, :].expand(S, n * n, Z.shape[-1]).reshape(-1, Z.shape[-1])
    out = model(x, z)
    return out.reshape(S, n, n, 2).permute(0, 3, 1, 2)


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


class GrayScottTask(Task):
    """Generative PINN for stationary Gray-Scott patterns (see the module docstring)."""

    kind = "gray-scott"

    def __init__(self, cfg: RunConfig, device: torch.device, dtype: torch.dtype):
        super().__init__(cfg, device, dtype)
        self.params = parse_params(cfg.params)
        self._target_cache: tuple[int, Tensor, Tensor, Tensor] | None = None  # step, offset, target, latents
        lat = cfg.latents
        if lat.n_shapes > 1 and not lat.random:
            self.Z = fixed_latents(lat.n_shapes, lat.dim, lat.low, lat.high, cfg.seed).to(device=self.device, dtype=dtype)
        else:
            self.Z = None

    # --- Task interface -------------------------------------------------------------------------

    def build_model(self) -> nn.Module:
        return build_field(self.cfg, self.params).to(device=self.device, dtype=self.dtype)

    def terms(self) -> dict[str, LossTerm]:
        L = self.params.losses
        return {"residual": L.residual, "gradient": L.gradient, "diversity": L.diversity}

    def latents(self) -> Tensor | None:
        return self.Z

    def _batch_latents(self, gen: torch.Generator) -> Tensor:
        lat = self.cfg.latents
        if self.Z is not None:
            return self.Z
        if lat.random:
            r = torch.rand(lat.n_shapes, lat.dim, generator=gen, dtype=self.dtype)
            return (lat.low + (lat.high - lat.low) * r).to(self.device)
        return torch.zeros(1, 0, dtype=self.dtype, device=self.device)

    def state_dict(self) -> dict:
        """The stored pseudo-time target (``residual_gradient = step``), so that a resumed run reuses
        it exactly as the uninterrupted run would."""
        c = self._target_cache
        return {} if c is None else {"target": {"step": c[0], "offset": c[1], "target": c[2], "latents": c[3]}}

    def load_state_dict(self, state: dict) -> None:
        t = state.get("target") if state else None
        if t is None:
            self._target_cache = None
            return
        dev = dict(device=self.device, dtype=self.dtype)
        self._target_cache = (int(t["step"]), t["offset"].to(**dev), t["target"].to(**dev), t["latents"].to(**dev))

    def grid_at(self, step: int) -> int:
        """Training grid points per axis at iteration ``step`` (``grid``, then ``fine_grid``)."""
        p = self.params
        return p.fine_grid if p.fine_grid > 0 and step >= p.fine_grid_from else p.grid

    def fields_and_derivatives(self, model: GrayScottField, Z: Tensor, offset: Tensor | None,
                               n: int | None = None) -> tuple[Tensor, Tensor, Tensor]:
        """``W (S, 2, n, n)``, gradients ``(S, 2, 2, n, n)`` (field, axis) and Laplacians ``(S, 2, n, n)``
        on the ``n``-point grid (default ``params.grid``)."""
        n = self.params.grid if n is None else n
        if self.params.derivatives in ("fd", "spectral"):
            W = sample_grid(model, Z, n, offset)
            G, Lap = grid_derivatives(W, self.params.derivatives)
            return W, G, Lap
        S, k = Z.shape
        X = periodic_points(n, offset, dtype=self.dtype, device=self.device).reshape(-1, 2)
        x = X[None].expand(S, -1, -1).reshape(-1, 2)
        z = Z[:, None, :].expand(S, n * n, k).reshape(-1, k)
        outs = []
        for f in (model.field_u, model.field_v):
            fv = evaluate(f, x, z, grad=False, hessian_at=True, create_graph=True)
            outs.append((fv.f, fv.hessian_grad, laplacian(fv.hessian)))
        W = torch.stack([o[0] for o in outs]).reshape(2, S, n, n).transpose(0, 1)
        G = torch.stack([o[1] for o in outs]).reshape(2, S, n, n, 2).permute(1, 0, 4, 2, 3)
        Lap = torch.stack([o[2] for o in outs]).reshape(2, S, n, n).transpose(0, 1)
        return W, G, Lap

    def loss_terms(self, model: nn.Module, step: int, active: set[str], gen: torch.Generator) -> dict[str, Tensor]:
        p, gs = self.params, self.params.gs
        Z = self._batch_latents(gen)
        offset = torch.rand(2, generator=gen, dtype=self.dtype).to(self.device) if p.translate else None
        W, G, Lap = self.fields_and_derivatives(model, Z, offset, self.grid_at(step))
        u, v = W[:, 0], W[:, 1]
        uvv = u * v * v
        Ru = gs.D_u * Lap[:, 0] - uvv + gs.alpha * (1.0 - u)
        Rv = gs.D_v * Lap[:, 1] + uvv - (gs.alpha + gs.beta) * v
        out: dict[str, Tensor] = {}
        res = (Ru * Ru).mean() + (Rv * Rv).mean()
        if "residual" in active:
            if p.residual_gradient == "full" or (p.flow_steps > 0 and step >= p.flow_steps):
                out["residual"] = res
            elif p.residual_gradient == "flow":  # value mean(R^2), gradient -2 mean(R dW/dtheta): W moves along u_t = R_u, v_t = R_v
                flow = -2.0 * ((Ru.detach() * u).mean() + (Rv.detach() * v).mean())
                out["residual"] = res.detach() + flow - flow.detach()
            else:  # value mean(R^2), gradient of mean |W - sg(step(W))|^2
                target = self._step_target(W, Z, offset, step)
                d = W - target
                fit = (d * d).mean() * 2.0
                if p.step_sobolev > 0:
                    Dd = torch.tensor([gs.D_u, gs.D_v], dtype=W.dtype, device=W.device)[:, None, None] * spectral_laplacian(d)
                    fit = fit + p.step_sobolev * (Dd * Dd).mean() * 2.0
                out["residual"] = res.detach() + fit - fit.detach()
                out["_step_misfit"] = fit.detach() / 2.0
        g2 = (G * G).sum(dim=(1, 2)).mean(dim=(-2, -1))  # (S,)
        if "gradient" in active:
            out["gradient"] = -torch.clamp(g2, max=p.gradient_cap).mean()
        if "diversity" in active and Z.shape[0] > 1:
            D = pattern_distance(v, p.diversity_distance)
            out["diversity"] = -aggregate(D, self.cfg.diversity.aggregation, self.cfg.diversity.p)
        with torch.no_grad():
            out["_residual"] = res.detach()
            out["_std_v"] = v.std(dim=(-2, -1)).mean().detach()
            out["_grad2"] = g2.mean().detach()
        return out

    def _step_target(self, W: Tensor, Z: Tensor, offset: Tensor | None, step: int) -> Tensor:
        """The regression target of ``residual_gradient = step`` for the sampled state ``W (S, 2, n, n)``:
        ``W`` advanced by ``step_count`` pseudo-time steps, recomputed every ``step_reuse`` iterations
        (and whenever the latents change); in between, the stored target is carried to this
        iteration's grid offset by :func:`fourier_shift`."""
        p = self.params
        off = offset if offset is not None else torch.zeros(2, dtype=W.dtype, device=W.device)
        c = self._target_cache
        fresh = (
            c is None or p.step_reuse == 1 or step - c[0] >= p.step_reuse or step < c[0]
            or c[2].shape != W.shape or not torch.equal(c[3], Z)
        )
        with torch.no_grad():
            if fresh:
                target = pseudo_time_step(W.detach(), p.gs, p.step_dt, p.step_count)
                self._target_cache = (step, off.clone(), target, Z.clone())
                return target
            return fourier_shift(c[2], off - c[1])

    def finalize(self, model: nn.Module, run_dir: Path) -> list[Path]:
        Z = self.Z if self.Z is not None else self.default_latents()
        paths = write_patterns(model, Z, Path(run_dir), self.params.resolution, self.params.n_interpolation)
        paths.append(write_pattern_explorer(model, Z, self.params.gs, Path(run_dir) / "figures" / "explorer.html",
                                            title=f"gray-scott: {Path(run_dir).name}"))
        return paths

    def evaluate(self, model: nn.Module, resolution: int | None = None, out_dir: Path | None = None) -> dict:
        """The four independent checks of :func:`ginn.eval.gray_scott.verify_run` on every trained latent."""
        n = resolution or 256
        Z = self.latents()
        check_grid_memory(n * n * (1 if Z is None else Z.shape[0]), 160, f"resolution {n}")
        res = verify_run(model, Z, self.params, resolution=n, out_dir=out_dir)
        return {"problem": "gray-scott", **res}

    def format_metrics(self, metrics: dict) -> str:
        return json.dumps({k: v for k, v in metrics.items() if k != "latents"}, indent=2, default=float)

    def default_latents(self) -> Tensor:
        """Fixed latents in the configured range, for the figures and views of a run whose latents
        are drawn afresh every iteration (``(max(S, 2), k)``; ``(1, 0)`` without latents)."""
        lat = self.cfg.latents
        k = lat.dim if (lat.n_shapes > 1 or lat.random) else 0
        if k == 0:
            return torch.zeros(1, 0, dtype=self.dtype, device=self.device)
        return fixed_latents(max(lat.n_shapes, 2), k, lat.low, lat.high, self.cfg.seed).to(self.device, self.dtype)
