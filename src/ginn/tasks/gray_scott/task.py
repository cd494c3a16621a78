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

import torch
from torch import Tensor, nn

from ...config import GrayScottParams, LossTerm, RunConfig, ShapeParams, parse_task_params
from ...extract.grid import periodic_points
from ...fields import evaluate, laplacian
from ...losses.diversity import aggregate
from ...train.task import Task
from .finite_diff import fourier_shift, grid_derivatives, spectral_laplacian
from .model import GrayScottField, build_field, fixed_latents, sample_grid
from .patterns import pattern_distance, pseudo_time_step
from .results import GrayScottResults


def parse_params(params: dict | GrayScottParams | ShapeParams | None) -> GrayScottParams:
    """Validate a gray-scott ``params`` mapping; raises :class:`ConfigError` with one line naming the bad key."""
    if isinstance(params, GrayScottParams):
        return params
    if isinstance(params, ShapeParams):  # a config without a params group: the defaults
        return GrayScottParams()
    return parse_task_params("gray-scott", params)


class GrayScottTask(Task):
    """Generative PINN for stationary Gray-Scott patterns (see the module docstring)."""

    kind = "gray-scott"

    def __init__(self, cfg: RunConfig, device: torch.device, dtype: torch.dtype):
        super().__init__(cfg, device, dtype)
        self.params = parse_params(cfg.params)
        self._target_cache: tuple[int, Tensor, Tensor, Tensor] | None = None  # step, offset, target, latents
        lat = cfg.latents
        if lat.n_shapes > 1 and lat.draw == "fixed":
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
        if lat.draw != "fixed":
            r = torch.rand(lat.n_shapes, lat.dim, generator=gen, dtype=self.dtype, device=gen.device)
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
        offset = torch.rand(2, generator=gen, dtype=self.dtype, device=gen.device).to(self.device) if p.translate else None
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

    @property
    def results(self) -> GrayScottResults:
        return GrayScottResults(self)

    def default_latents(self) -> Tensor:
        """Fixed latents in the configured range, for the figures and views of a run whose latents
        are drawn afresh every iteration (``(max(S, 2), k)``; ``(1, 0)`` without latents)."""
        lat = self.cfg.latents
        k = lat.dim if (lat.n_shapes > 1 or lat.draw != "fixed") else 0
        if k == 0:
            return torch.zeros(1, 0, dtype=self.dtype, device=self.device)
        return fixed_latents(max(lat.n_shapes, 2), k, lat.low, lat.high, self.cfg.seed).to(self.device, self.dtype)
