"""A neural field that works in the domain's own frame: ``f(x, z) = s * g((x - c) / s, z)``.

``c`` is the centre of the domain and ``s`` half its longest side, so the inner network ``g`` sees
points in ``[-1, 1]`` along the longest axis and returns values in units of ``s``: a signed
distance of a problem of any size is a unit-scale function to ``g``. Initialisation, the SIREN
frequencies and Adam's step sizes then mean the same for a part of 10 mm and of 10 m.
Gradients are unchanged by the frame (``grad_x f = grad_y g`` at ``y = (x - c) / s``).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor, nn

from .base import WrappedField

__all__ = ["DomainFrame"]


class DomainFrame(WrappedField):
    """``inner`` evaluated in the frame of centre ``center (d,)`` and scale ``scale``.

    Shapes: ``x (n, d)``, ``z (n, k)`` or None -> ``(n,)`` (as ``inner``).
    """

    def __init__(self, inner: nn.Module, center: Sequence[float], scale: float):
        super().__init__(inner)
        if not scale > 0:
            raise ValueError(f"scale must be positive, got {scale}")
        self.register_buffer("center", torch.tensor([float(c) for c in center]))
        self.scale = float(scale)

    def _local(self, x: Tensor) -> Tensor:
        return (x - self.center.to(x.dtype)) / self.scale

    def forward(self, x: Tensor, z: Tensor | None = None) -> Tensor:
        return self.scale * self.inner(self._local(x), z)

    def value_and_grad(self, x: Tensor, z: Tensor | None = None) -> tuple[Tensor, Tensor] | None:
        """The inner network's fast path, if it has one, in this frame."""
        fast = getattr(self.inner, "value_and_grad", None)
        out = fast(self._local(x), z) if fast is not None else None
        if out is None:
            return None
        f, g = out
        return self.scale * f, g
