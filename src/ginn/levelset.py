"""Points on the zero level set of a field: Newton projection along the gradient.

One reusable routine (:func:`project_to_zero`), used by the curvature and strain losses, the
diversity loss and the metrics.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from .fields import Field, evaluate, value


@dataclass
class Projection:
    """Result of :func:`project_to_zero`.

    Attributes:
        x: projected points ``(n, d)`` (detached).
        z: their latent codes ``(n, k)`` or None.
        converged: boolean ``(n,)``: ``|f| <= tol`` and still inside the box.
        residual: ``|f|`` at the final points ``(n,)``.
    """

    x: Tensor
    z: Tensor | None
    converged: Tensor
    residual: Tensor

    @property
    def n_converged(self) -> int:
        return int(self.converged.sum())

    def select(self) -> tuple[Tensor, Tensor | None]:
        """The converged points (and their latents)."""
        m = self.converged
        return self.x[m], (None if self.z is None else self.z[m])


def project_to_zero(
    field: Field,
    x: Tensor,
    z: Tensor | None = None,
    *,
    steps: int = 8,
    tol: float = 1e-4,
    max_step: float | None = None,
    bounds: tuple[Tensor, Tensor] | None = None,
    settle: float | None = None,
) -> Projection:
    """Move points onto ``{f = 0}`` with Newton steps ``x <- x - f grad f / |grad f|^2``.

    Arguments:
        field: callable ``(x, z) -> (n,)``.
        x: start points ``(n, d)``; z: latent codes ``(n, k)`` or None.
        steps: number of Newton steps (0: only check the start points).
        tol: a point has converged when ``|f| <= tol``.
        max_step: optional cap on the length of one step (damping far from the surface).
        bounds: optional ``(lo, hi)`` box; points leaving it are marked not converged.
        settle: optional length: a point whose step was shorter than this takes no further steps
            (Newton's next step would be of the order of the square of this one), so that the
            later steps evaluate only the points still moving.

    Returns:
        :class:`Projection` (no graph is kept; re-evaluate the field at ``x`` for a loss).
    """
    x = x.detach().clone()
    moving = None  # (q,) indices of the points still moving; None: all of them
    for _ in range(steps):
        xm = x if moving is None else x[moving]
        zm = z if moving is None or z is None else z[moving]
        v = evaluate(field, xm, zm, grad=True, create_graph=False)
        g2 = (v.grad * v.grad).sum(-1).clamp_min(1e-12)
        step = (v.f / g2)[:, None] * v.grad
        if max_step is not None:
            ln = step.norm(dim=-1, keepdim=True)
            step = step * (max_step / ln.clamp_min(max_step))
        if moving is None:
            x = x - step
        else:
            x[moving] = xm - step
        if settle is not None:
            still = step.norm(dim=-1) >= settle
            moving = torch.nonzero(still).squeeze(-1) if moving is None else moving[still]
            if moving.numel() == 0:
                break
    res = value(field, x, z).abs()
    ok = torch.isfinite(res) & (res <= tol) & torch.isfinite(x).all(dim=-1)
    if bounds is not None:
        lo, hi = bounds
        ok &= ((x >= lo) & (x <= hi)).all(dim=-1)
    return Projection(x=x, z=z, converged=ok, residual=res)
