"""The neural-field interface every model implements.

A neural field maps points ``x`` of shape ``(n, d)`` and latent codes ``z`` of shape ``(n, k)``
(``k = 0`` allowed, or ``z=None``) to values of shape ``(n,)`` (``out_dim == 1``) or ``(n, c)``.

Conditioning is a separate object (:class:`Conditioning`) so that a modulation-based scheme can be
added later without touching callers: callers only ever call ``model(x, z)``.
"""

from __future__ import annotations

import abc

import torch
from torch import Tensor, nn


class Conditioning(nn.Module, abc.ABC):
    """Combines (encoded) points with latent codes into the network's first-layer input.

    Subclasses define ``out_features(point_features, latent_dim)`` and ``forward(h, z)``.
    """

    @abc.abstractmethod
    def out_features(self, point_features: int, latent_dim: int) -> int: ...

    @abc.abstractmethod
    def forward(self, h: Tensor, z: Tensor | None) -> Tensor: ...


class ConcatConditioning(Conditioning):
    """The paper's choice: concatenate ``z`` to the point features, ``[h, scale * z]``.

    For a SIREN this amounts to a latent-dependent bias of the first layer. ``scale`` (default 1,
    the paper's) multiplies the codes before they enter: for a SIREN it is the first layer's
    frequency along the latent axes relative to the spatial ones (``omega_0^1 * scale``), so a
    larger scale lets the initial field vary faster from one code to the next without sharpening
    it in space. It is the same as spreading the codes over an interval ``scale`` times as wide,
    but keeps the codes the user names.
    """

    def __init__(self, scale: float = 1.0):
        super().__init__()
        if not scale > 0:
            raise ValueError(f"latent scale must be positive, got {scale}")
        self.scale = float(scale)

    def out_features(self, point_features: int, latent_dim: int) -> int:
        return point_features + latent_dim

    def forward(self, h: Tensor, z: Tensor | None) -> Tensor:
        if z is None or z.shape[-1] == 0:
            return h
        z = z.to(h.dtype)
        return torch.cat([h, z if self.scale == 1.0 else self.scale * z], dim=-1)


class PeriodicEncoding(nn.Module):
    """``x_i -> (sin 2 pi x_i, cos 2 pi x_i)``: a field of the encoded points is 1-periodic.

    Shapes: ``(n, d) -> (n, 2 d)`` (all sines first, then all cosines).
    """

    def __init__(self, period: float = 1.0):
        super().__init__()
        self.period = float(period)

    def out_features(self, in_dim: int) -> int:
        return 2 * in_dim

    def forward(self, x: Tensor) -> Tensor:
        a = (2.0 * torch.pi / self.period) * x
        return torch.cat([torch.sin(a), torch.cos(a)], dim=-1)


class IdentityEncoding(nn.Module):
    """No encoding: ``(n, d) -> (n, d)``."""

    def out_features(self, in_dim: int) -> int:
        return in_dim

    def forward(self, x: Tensor) -> Tensor:
        return x


class NeuralField(nn.Module):
    """Base class: encoding of ``x`` -> conditioning with ``z`` -> a core network.

    Arguments:
        in_dim: spatial dimension ``d`` of the points.
        latent_dim: dimension ``k`` of the latent codes (0 for a single shape).
        out_dim: number of output channels ``c`` (1 gives outputs of shape ``(n,)``).
        encoding: optional module applied to ``x`` alone (for example :class:`PeriodicEncoding`);
            it must provide ``out_features(in_dim)``.
        conditioning: how ``z`` enters (default :class:`ConcatConditioning`).

    Subclasses build ``self.core`` from ``self.core_in_features`` and implement nothing else.
    """

    def __init__(
        self,
        in_dim: int,
        latent_dim: int = 0,
        out_dim: int = 1,
        encoding: nn.Module | None = None,
        conditioning: Conditioning | None = None,
    ):
        super().__init__()
        if in_dim < 1:
            raise ValueError(f"in_dim must be >= 1, got {in_dim}")
        if latent_dim < 0:
            raise ValueError(f"latent_dim must be >= 0, got {latent_dim}")
        self.in_dim = int(in_dim)
        self.latent_dim = int(latent_dim)
        self.out_dim = int(out_dim)
        self.encoding = encoding if encoding is not None else IdentityEncoding()
        self.conditioning = conditioning if conditioning is not None else ConcatConditioning()
        point_features = self.encoding.out_features(self.in_dim)
        self.core_in_features = self.conditioning.out_features(point_features, self.latent_dim)
        self.core: nn.Module

    def forward(self, x: Tensor, z: Tensor | None = None) -> Tensor:
        """Evaluate the field.

        Arguments:
            x: points, shape ``(n, d)``.
            z: latent codes, shape ``(n, k)``, or ``None`` when ``k == 0``.

        Returns:
            ``(n,)`` when ``out_dim == 1``, else ``(n, out_dim)``.
        """
        self._check_inputs(x, z)
        h = self.conditioning(self.encoding(x), z if self.latent_dim > 0 else None)
        out = self.core(h)
        return out.squeeze(-1) if self.out_dim == 1 else out

    def value_and_grad(self, x: Tensor, z: Tensor | None = None) -> tuple[Tensor, Tensor] | None:
        """Optional fast path of :func:`ginn.fields.evaluate`: ``f (n,)`` and ``grad_x f (n, d)``
        at once, differentiable (once) w.r.t. the parameters, or ``None`` where this model has
        none (the engine then uses autograd). Subclasses may override; results must equal the
        autograd ones."""
        return None

    def _check_inputs(self, x: Tensor, z: Tensor | None) -> None:
        if x.shape[-1] != self.in_dim:
            raise ValueError(f"expected points with {self.in_dim} coordinates, got shape {tuple(x.shape)}")
        if self.latent_dim > 0:
            if z is None or z.shape[-1] != self.latent_dim:
                raise ValueError(
                    f"model expects latent codes of dimension {self.latent_dim}, got "
                    f"{None if z is None else tuple(z.shape)}"
                )
            if z.shape[0] != x.shape[0]:
                raise ValueError(f"x and z must have the same number of rows, got {x.shape[0]} and {z.shape[0]}")


class WrappedField(nn.Module):
    """A field that calls an ``inner`` field on transformed points (a frame, a symmetry fold): it
    reports the inner field's latent and output sizes, and its point dimension unless it changes
    it."""

    def __init__(self, inner: nn.Module):
        super().__init__()
        self.inner = inner

    @property
    def in_dim(self) -> int:
        return self.inner.in_dim

    @property
    def latent_dim(self) -> int:
        return self.inner.latent_dim

    @property
    def out_dim(self) -> int:
        return self.inner.out_dim
