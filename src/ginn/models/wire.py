"""WIRE (Saragadam et al. 2023): a neural field with complex Gabor wavelet activations.

The activation of a pre-activation ``u`` (real in the first layer, complex after it) is::

    psi(u) = exp(i omega u - |scale u|^2)

a complex sinusoid of frequency ``omega`` under a Gaussian window of width ``1 / scale``: each unit
responds only near the hyperplane where its pre-activation vanishes, so a WIRE is local where a
SIREN's sines are global. The network is

* first layer: ``h_1 = psi(W_1 [x, z] + b_1)`` with real ``W_1, b_1`` (the points and the latent
  code concatenated, as for the SIREN, :class:`~ginn.models.base.ConcatConditioning`);
* hidden layers: ``h_l = psi(W_l h_{l-1} + b_l)`` with complex ``W_l, b_l``;
* output: ``f = Re(w h_L + b)`` with complex ``w, b``.

For ``u = p + i q`` the activation is ``exp(-omega q - scale^2 (p^2 + q^2)) (cos omega p + i sin
omega p)``; its modulus is at most ``exp(omega^2 / (4 scale^2))`` (the maximum over ``q``), e^1 at
the defaults ``omega = 20``, ``scale = 10``, so no depth or weight makes an activation explode.

Complex weights are stored as two real tensors (``weight_re``, ``weight_im``): the parameters
follow the model's real dtype and device, and optimisers, checkpoints and data parallelism see
ordinary real tensors. A complex layer has twice the parameters of a real one of the same width.

Initialisation: every weight and bias (each real and imaginary part independently) is drawn from
``U(-1/sqrt(fan_in), 1/sqrt(fan_in))``, PyTorch's default for linear layers, which WIRE keeps.

Derivatives w.r.t. the points (gradients, Hessians) come from autograd through the real
arithmetic (``tests/test_models.py`` checks them against finite differences in float64).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import Tensor, nn

from .base import Conditioning, NeuralField


def gabor(p: Tensor, q: Tensor | None, omega: float, scale: float) -> tuple[Tensor, Tensor]:
    """``psi(p + i q)`` as its real and imaginary parts (``q`` None: a real pre-activation).
    Shapes: ``(n, width)`` in, two ``(n, width)`` out."""
    if q is None:
        envelope = torch.exp(-(scale * p) ** 2)
    else:
        envelope = torch.exp(-omega * q - scale * scale * (p * p + q * q))
    phase = omega * p
    return envelope * torch.cos(phase), envelope * torch.sin(phase)


class ComplexLinear(nn.Module):
    """``(h_re + i h_im) (W_re + i W_im)^T + (b_re + i b_im)``, real and imaginary parts apart.
    Shapes ``(n, fan_in)`` twice ``-> (n, fan_out)`` twice."""

    def __init__(self, fan_in: int, fan_out: int):
        super().__init__()
        bound = 1.0 / math.sqrt(fan_in)
        self.weight_re = nn.Parameter(torch.empty(fan_out, fan_in).uniform_(-bound, bound))
        self.weight_im = nn.Parameter(torch.empty(fan_out, fan_in).uniform_(-bound, bound))
        self.bias_re = nn.Parameter(torch.empty(fan_out).uniform_(-bound, bound))
        self.bias_im = nn.Parameter(torch.empty(fan_out).uniform_(-bound, bound))

    def forward(self, h_re: Tensor, h_im: Tensor) -> tuple[Tensor, Tensor]:
        re = torch.addmm(self.bias_re, h_re, self.weight_re.t()) - h_im @ self.weight_im.t()
        im = torch.addmm(self.bias_im, h_re, self.weight_im.t()) + h_im @ self.weight_re.t()
        return re, im


class _WireCore(nn.Module):
    """The layers after the conditioning: ``(n, core_in) -> (n, out_dim)``."""

    def __init__(self, fan_in: int, hidden: Sequence[int], out_dim: int, omega: float, scale: float):
        super().__init__()
        self.omega, self.scale = float(omega), float(scale)
        self.first = nn.Linear(fan_in, hidden[0])  # PyTorch's default init: U(-1/sqrt(fan_in), 1/sqrt(fan_in))
        self.hidden = nn.ModuleList(ComplexLinear(a, b) for a, b in zip(hidden[:-1], hidden[1:]))
        self.last = ComplexLinear(hidden[-1], out_dim)

    def forward(self, h: Tensor) -> Tensor:
        re, im = gabor(self.first(h), None, self.omega, self.scale)
        for layer in self.hidden:
            re, im = gabor(*layer(re, im), self.omega, self.scale)
        return self.last(re, im)[0]


class Wire(NeuralField):
    """WIRE neural field (see the module docstring).

    Arguments:
        in_dim: point dimension ``d``.
        hidden: widths of the hidden layers (complex after the first), e.g. ``[64] * 3``.
        latent_dim: latent dimension ``k`` (concatenated to the encoded points by default).
        out_dim: output channels.
        omega: the Gabor frequency of every layer.
        scale: the inverse width of the Gabor window of every layer.
        encoding, conditioning: see :class:`ginn.models.base.NeuralField`.
    """

    def __init__(
        self,
        in_dim: int,
        hidden: Sequence[int] = (64, 64, 64),
        latent_dim: int = 0,
        out_dim: int = 1,
        omega: float = 20.0,
        scale: float = 10.0,
        encoding: nn.Module | None = None,
        conditioning: Conditioning | None = None,
    ):
        super().__init__(in_dim, latent_dim, out_dim, encoding, conditioning)
        if len(hidden) < 1:
            raise ValueError("a WIRE needs at least one hidden layer")
        self.omega, self.scale = float(omega), float(scale)
        self.core = _WireCore(self.core_in_features, hidden, out_dim, omega, scale)
