"""Compliance as a differentiable function of the element moduli.

``c_l(E) = f_l^T u_l`` with ``K(E) u_l = f_l``. Compliance is self-adjoint: its gradient needs no
second solve, ``dc_l / dE_e = -u_e^T K0 u_e`` (the element's energy at unit modulus, negated).
:func:`compliance` wraps the solve in a :class:`torch.autograd.Function`, so a network whose field
sets the moduli gets the gradient through autograd like any other term; every shape of a batch is
solved in one call.

Public names: :func:`compliance`, :class:`Solution`.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from .solve import ElasticitySolver

__all__ = ["compliance", "Solution"]


@dataclass(frozen=True)
class Solution:
    """What one solve leaves behind (float64, on the moduli's device).

    Attributes:
        displacement: ``(B, L, n_dofs)``.
        energy: ``(B, L, n_elements)`` ``u_e^T K0 u_e``: twice each element's strain energy at unit modulus.
        compliance: ``(B, L)`` ``f^T u``.
    """

    displacement: torch.Tensor
    energy: torch.Tensor
    compliance: torch.Tensor


class _Compliance(torch.autograd.Function):
    @staticmethod
    def forward(ctx, moduli: torch.Tensor, solver: ElasticitySolver, out: list) -> torch.Tensor:
        U = solver.solve(moduli)
        energy = solver.element_energy(U)
        c = (moduli.detach().to(torch.float64)[:, None, :] * energy).sum(-1)
        out.append(Solution(U, energy, c))
        ctx.save_for_backward(energy)
        ctx.dtype = moduli.dtype
        return c.to(moduli.dtype)

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        (energy,) = ctx.saved_tensors
        g = -(grad.to(torch.float64)[:, :, None] * energy).sum(1)
        return g.to(ctx.dtype), None, None


def compliance(moduli: torch.Tensor, solver: ElasticitySolver) -> tuple[torch.Tensor, Solution]:
    """The compliance ``(B, L)`` of every shape and load case for element moduli ``(B, n_elements)``
    (differentiable in the moduli), and the :class:`Solution` it came from."""
    if moduli.dim() == 1:
        moduli = moduli[None]
    out: list[Solution] = []
    c = _Compliance.apply(moduli, solver, out)
    return c, out[0]
