"""The Gray-Scott model: two networks (``u`` and ``v``) over the periodic unit square, each
conditioned on a latent code by concatenation, and the fields of every latent on one shared grid."""

from __future__ import annotations

import torch
from torch import Tensor, nn

from ...config import GrayScottParams, RunConfig
from ...errors import ConfigError
from ...extract.grid import periodic_points
from ...models import ConcatConditioning, FourierMLP, PeriodicEncoding, Siren

__all__ = ["GrayScottField", "build_field", "fixed_latents", "sample_grid"]


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
    k = cfg.latents.dim if cfg.latents.n_shapes > 1 or cfg.latents.draw != "fixed" else 0
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
