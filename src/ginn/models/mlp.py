"""Plain and residual MLP fields, and a Fourier-feature MLP.

* :class:`MLP`: ``Linear -> act -> ... -> Linear`` (tanh by default; the mirror and Plateau models).
* :class:`ResMLP`: the paper's "softplus-MLP": an input layer, residual blocks
  ``h <- h + softplus_beta(W h + b)`` and an output layer. Softplus keeps the field twice
  differentiable (normals, curvature), which ReLU would not.
* :class:`FourierMLP`: random Fourier features ``[sin(2 pi B x), cos(2 pi B x)]`` with
  ``B ~ N(0, sigma^2)`` (Tancik et al. 2020), then an MLP.

PyTorch's default ``nn.Linear`` initialisation is used for all of them.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor, nn

from .base import Conditioning, NeuralField


def make_activation(name: str, beta: float = 1.0) -> nn.Module:
    """An activation by name: ``tanh``, ``softplus`` (with ``beta``), ``sin``, ``relu``, ``gelu``, ``silu``."""
    if name == "tanh":
        return nn.Tanh()
    if name == "softplus":
        return nn.Softplus(beta=beta)
    if name == "relu":
        return nn.ReLU()
    if name == "gelu":
        return nn.GELU()
    if name == "silu":
        return nn.SiLU()
    if name == "sin":
        return _Sin()
    raise ValueError(f"unknown activation {name!r} (tanh, softplus, sin, relu, gelu, silu)")


class _Sin(nn.Module):
    def forward(self, h: Tensor) -> Tensor:
        return torch.sin(h)


class MLP(NeuralField):
    """Plain MLP field; ``hidden`` lists the hidden widths, e.g. ``[40, 40]``."""

    def __init__(
        self,
        in_dim: int,
        hidden: Sequence[int] = (40, 40),
        latent_dim: int = 0,
        out_dim: int = 1,
        activation: str = "tanh",
        beta: float = 1.0,
        encoding: nn.Module | None = None,
        conditioning: Conditioning | None = None,
    ):
        super().__init__(in_dim, latent_dim, out_dim, encoding, conditioning)
        widths = [self.core_in_features, *hidden]
        layers: list[nn.Module] = []
        for a, b in zip(widths[:-1], widths[1:]):
            layers += [nn.Linear(a, b), make_activation(activation, beta)]
        layers.append(nn.Linear(widths[-1], out_dim))
        self.core = nn.Sequential(*layers)


class _ResidualBlock(nn.Module):
    def __init__(self, width: int, beta: float):
        super().__init__()
        self.linear = nn.Linear(width, width)
        self.act = nn.Softplus(beta=beta)

    def forward(self, h: Tensor) -> Tensor:
        return h + self.act(self.linear(h))


class ResMLP(NeuralField):
    """Residual softplus MLP ("softplus-MLP" of the paper; Table 2: ``[3, 4x512, 1]``).

    Arguments:
        width: width of every hidden layer.
        n_blocks: number of hidden layers; the first maps the input to ``width`` (softplus), the
            remaining ``n_blocks - 1`` are residual blocks.
        beta: softplus sharpness, ``softplus_beta(t) = log(1 + exp(beta t)) / beta``.
    """

    def __init__(
        self,
        in_dim: int,
        width: int = 512,
        n_blocks: int = 4,
        latent_dim: int = 0,
        out_dim: int = 1,
        beta: float = 1.0,
        encoding: nn.Module | None = None,
        conditioning: Conditioning | None = None,
    ):
        super().__init__(in_dim, latent_dim, out_dim, encoding, conditioning)
        if n_blocks < 1:
            raise ValueError("ResMLP needs n_blocks >= 1")
        layers: list[nn.Module] = [nn.Linear(self.core_in_features, width), nn.Softplus(beta=beta)]
        layers += [_ResidualBlock(width, beta) for _ in range(n_blocks - 1)]
        layers.append(nn.Linear(width, out_dim))
        self.core = nn.Sequential(*layers)


class FourierFeatures(nn.Module):
    """Random Fourier features ``x -> [sin(2 pi x B^T), cos(2 pi x B^T)]``, ``B ~ N(0, sigma^2)``.

    Shapes ``(n, d) -> (n, 2 m)``; ``B`` is a fixed buffer of shape ``(m, d)``.
    """

    def __init__(self, in_dim: int, n_features: int = 128, sigma: float = 1.0, generator: torch.Generator | None = None):
        super().__init__()
        self.sigma = float(sigma)
        self.register_buffer("B", torch.randn(n_features, in_dim, generator=generator) * sigma)

    def out_features(self, in_dim: int) -> int:
        return 2 * self.B.shape[0]

    def forward(self, x: Tensor) -> Tensor:
        a = 2.0 * torch.pi * (x @ self.B.to(x.dtype).T)
        return torch.cat([torch.sin(a), torch.cos(a)], dim=-1)


class FourierMLP(MLP):
    """Fourier-feature MLP (Tancik et al. 2020). ``pre_encoding`` (e.g. periodic) is applied first."""

    def __init__(
        self,
        in_dim: int,
        hidden: Sequence[int] = (256, 256),
        latent_dim: int = 0,
        out_dim: int = 1,
        sigma: float = 1.0,
        n_features: int = 128,
        activation: str = "softplus",
        beta: float = 1.0,
        pre_encoding: nn.Module | None = None,
        conditioning: Conditioning | None = None,
    ):
        feat_in = in_dim if pre_encoding is None else pre_encoding.out_features(in_dim)
        features = FourierFeatures(feat_in, n_features, sigma)
        encoding: nn.Module = features if pre_encoding is None else _Chain(pre_encoding, features)
        super().__init__(in_dim, hidden, latent_dim, out_dim, activation, beta, encoding, conditioning)


class _Chain(nn.Module):
    def __init__(self, first: nn.Module, second: nn.Module):
        super().__init__()
        self.first, self.second = first, second

    def out_features(self, in_dim: int) -> int:
        return self.second.out_features(self.first.out_features(in_dim))

    def forward(self, x: Tensor) -> Tensor:
        return self.second(self.first(x))
