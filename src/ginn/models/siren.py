"""SIREN (Sitzmann et al. 2020) with a separately configurable first-layer frequency.

Initialisation (the paper's results are sensitive to it, so it is stated exactly):

* The network is ``sin(w0_first * (W1 h + b1))`` followed by hidden layers
  ``sin(w0_hidden * (W h + b))`` and a final linear layer.
* First layer: ``W1, b1 ~ U(-1/fan_in, 1/fan_in)``; the frequency ``w0_first`` (the paper's
  omega_0^1, Table 2: 1, 2, 8, 3) scales the pre-activation, so it sets the band-width of the shape.
* Hidden and final layers: ``W, b ~ U(-c, c)`` with ``c = sqrt(6 / fan_in) / w0_hidden``. With
  ``w0_hidden = 1`` (the default; the reference implementation the authors used, Dalmia's
  ``siren-pytorch``, does the same) this is Sitzmann's scheme, under which every hidden
  pre-activation ``w0_hidden (W h + b)`` has unit variance whatever the depth (the inputs of each
  layer are arcsine-distributed with variance 1/2 and ``fan_in * Var(W) = 2``).
* Biases use the same range as the weights (as in the reference implementation); this adds
  a variance of ``2 / fan_in`` to each pre-activation, negligible at widths of 64 and above.

Sitzmann's own code uses ``w0_hidden = 30`` with weights divided by 30, which gives the same
function at initialisation; ``w0_hidden`` changes only the effective learning rate of hidden layers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import Tensor, nn

from .base import ConcatConditioning, Conditioning, IdentityEncoding, NeuralField
from .siren_grad import siren_value_and_grad


class _SinCos(torch.autograd.Function):
    """``a -> (sin a, cos a)`` whose derivatives of every order reuse the two outputs.

    Autograd's own ``sin`` recomputes ``cos a`` in its backward, ``sin a`` in the double backward
    and so on; gradients and Hessians of a SIREN (one, two and three nested backward passes) then
    spend a fifth of their time in transcendental functions. Here the backward is
    ``grad_a = grad_sin * cos - grad_cos * sin`` with the saved outputs, which are themselves
    differentiable outputs of this node, so every higher derivative is products only.
    """

    generate_vmap_rule = True

    @staticmethod
    def forward(a: Tensor) -> tuple[Tensor, Tensor]:
        return torch.sin(a), torch.cos(a)

    @staticmethod
    def setup_context(ctx, inputs, output) -> None:
        ctx.save_for_backward(*output)
        ctx.set_materialize_grads(False)

    @staticmethod
    def backward(ctx, g_sin: Tensor | None, g_cos: Tensor | None) -> Tensor | None:
        s, c = ctx.saved_tensors
        out = None if g_sin is None else g_sin * c
        if g_cos is not None:
            out = -(g_cos * s) if out is None else out - g_cos * s
        return out


def sine(a: Tensor) -> Tensor:
    """``sin a``; with autograd recording, through :class:`_SinCos` (cheaper derivatives)."""
    if torch.is_grad_enabled() and a.requires_grad:
        return _SinCos.apply(a)[0]
    return torch.sin(a)


class SineLayer(nn.Module):
    """``sin(omega * (W h + b))`` with SIREN initialisation. Shapes ``(n, fan_in) -> (n, fan_out)``."""

    def __init__(self, fan_in: int, fan_out: int, omega: float, first: bool):
        super().__init__()
        self.omega = float(omega)
        self.linear = nn.Linear(fan_in, fan_out)
        bound = 1.0 / fan_in if first else math.sqrt(6.0 / fan_in) / self.omega
        with torch.no_grad():
            self.linear.weight.uniform_(-bound, bound)
            self.linear.bias.uniform_(-bound, bound)

    def preactivation(self, h: Tensor) -> Tensor:
        # omega (W h + b) as one affine map with scaled parameters: the same function and the same
        # parameter gradients, without an elementwise product over the (n, fan_out) activations
        # (which every derivative pass would otherwise repeat)
        if self.omega == 1.0:
            return self.linear(h)
        return nn.functional.linear(h, self.omega * self.linear.weight, self.omega * self.linear.bias)

    def forward(self, h: Tensor) -> Tensor:
        return sine(self.preactivation(h))


class Siren(NeuralField):
    """SIREN neural field.

    Arguments:
        in_dim: point dimension ``d``.
        hidden: widths of the hidden layers, e.g. ``[64] * 4`` (the paper's ``4x64``).
        latent_dim: latent dimension ``k`` (concatenated to the encoded points by default).
        out_dim: output channels.
        w0_first: omega_0 of the first layer (the paper's omega_0^1).
        w0_hidden: omega_0 of the hidden layers (see the module docstring).
        encoding, conditioning: see :class:`ginn.models.base.NeuralField`.
    """

    def __init__(
        self,
        in_dim: int,
        hidden: Sequence[int] = (64, 64, 64, 64),
        latent_dim: int = 0,
        out_dim: int = 1,
        w0_first: float = 1.0,
        w0_hidden: float = 1.0,
        encoding: nn.Module | None = None,
        conditioning: Conditioning | None = None,
    ):
        super().__init__(in_dim, latent_dim, out_dim, encoding, conditioning)
        if len(hidden) < 1:
            raise ValueError("a SIREN needs at least one hidden layer")
        self.w0_first = float(w0_first)
        self.w0_hidden = float(w0_hidden)
        layers: list[nn.Module] = [SineLayer(self.core_in_features, hidden[0], w0_first, first=True)]
        for a, b in zip(hidden[:-1], hidden[1:]):
            layers.append(SineLayer(a, b, w0_hidden, first=False))
        last = nn.Linear(hidden[-1], out_dim)
        bound = math.sqrt(6.0 / hidden[-1]) / self.w0_hidden
        with torch.no_grad():
            last.weight.uniform_(-bound, bound)
            last.bias.uniform_(-bound, bound)
        layers.append(last)
        self.core = nn.Sequential(*layers)
        #: run :meth:`value_and_grad` with the ``torch.compile`` kernels (:func:`compile_derivatives`)
        self.compiled = False

    def value_and_grad(self, x: Tensor, z: Tensor | None = None) -> tuple[Tensor, Tensor] | None:
        """``f (n,)`` and ``grad_x f (n, d)`` by :func:`ginn.models.siren_grad.siren_value_and_grad`
        (a hand-written backward); ``None`` (use autograd) with an encoding, a conditioning other
        than concatenation, or several output channels."""
        if not (
            isinstance(self.encoding, IdentityEncoding)
            and type(self.conditioning) is ConcatConditioning
            and self.out_dim == 1
        ):
            return None
        self._check_inputs(x, z)
        h0 = self.conditioning(x, z if self.latent_dim > 0 else None)
        layers = list(self.core)
        weights, biases = [], []
        for layer in layers[:-1]:
            W, b = layer.linear.weight, layer.linear.bias
            if layer.omega != 1.0:
                W, b = layer.omega * W, layer.omega * b
            weights.append(W)
            biases.append(b)
        last = layers[-1]
        return siren_value_and_grad(h0, self.in_dim, weights, biases, last.weight, last.bias, self.compiled)

    def preactivations(self, x: Tensor, z: Tensor | None = None) -> list[Tensor]:
        """Pre-activations of every sine layer, each ``(n, width)`` (for checking the init)."""
        h = self.conditioning(self.encoding(x), z if self.latent_dim > 0 else None)
        out = []
        for layer in self.core:
            if isinstance(layer, SineLayer):
                p = layer.preactivation(h)
                out.append(p)
                h = torch.sin(p)
        return out


def compile_derivatives(module: nn.Module, on: bool = True) -> int:
    """Let every :class:`Siren` inside ``module`` (wrappers included) compute its value and input
    gradient with the ``torch.compile`` kernels of :mod:`ginn.models.siren_grad` (``on``) or the
    eager ones; returns how many SIRENs it set."""
    n = 0
    for m in module.modules():
        if isinstance(m, Siren):
            m.compiled = bool(on)
            n += 1
    return n
