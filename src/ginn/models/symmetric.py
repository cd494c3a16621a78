"""A field symmetric by construction: ``f(x, z) = g(phi(x), z)`` with ``phi`` the symmetry's fold."""

from __future__ import annotations

from torch import Tensor, nn

from ..geometry.symmetry import Symmetry
from .base import WrappedField

__all__ = ["SymmetricField", "FOLD_SMOOTHING"]

#: The smoothing length of the fold, in units of the domain's half longest side: a tenth of the
#: shortest wavelength a first SIREN layer of frequency 30 starts with (2 pi / 30 ~ 0.2), so the
#: fold's crease is resolved while the map stays an isometry a few percent of the domain away from
#: the mirrors and the axis.
FOLD_SMOOTHING = 0.02


class SymmetricField(WrappedField):
    """``inner`` evaluated at :meth:`Symmetry.fold` of the points: exactly invariant under every
    generator of ``symmetry`` (to rounding), smooth, and a local isometry away from the mirrors and
    the axis.

    Arguments:
        inner: a field ``(n, symmetry.fold_dim), (n, k) -> (n,)``.
        symmetry: in the coordinates the field is called with.
        eps: the smoothing length of the fold at the mirrors and the axis.

    Shapes: ``x (n, d)``, ``z (n, k)`` or None -> ``(n,)``.
    """

    def __init__(self, inner: nn.Module, symmetry: Symmetry, eps: float):
        super().__init__(inner)
        if getattr(inner, "in_dim", symmetry.fold_dim) != symmetry.fold_dim:
            raise ValueError(f"inner field takes {inner.in_dim} coordinates, the fold gives {symmetry.fold_dim}")
        if not eps > 0:
            raise ValueError(f"eps must be positive, got {eps}")
        self.symmetry = symmetry
        self.eps = float(eps)

    @property
    def in_dim(self) -> int:
        return self.symmetry.dim

    def forward(self, x: Tensor, z: Tensor | None = None) -> Tensor:
        return self.inner(self.symmetry.fold(x, self.eps), z)
