"""Geometric multigrid on an :class:`~ginn.physics.grid.ElementGrid`: the preconditioner of the
CG method of :class:`~ginn.physics.solve.ElasticitySolver`.

Levels: the element grid, then grids of ``ceil(n / 2)`` elements along each axis over the box
that these span (a coarse element covers ``2^dim`` elements of the level below; where an axis has
an odd count, its last coarse element hangs half outside), until a level has at most
:data:`COARSEST_DOFS` degrees of freedom. Between two levels the displacements are interpolated
multilinearly (``P``, one 1D matrix per axis); each coarse operator is the Galerkin product
``P^T A P`` of the operator below it, with the fixed degrees of freedom of the element grid
removed (``A_0 = D K(E) D``, ``D`` the free mask; a coarse degree of freedom that interpolates to
fixed ones only gets a zero row and stays at zero). Because an element of one level lies inside
one element of the next, the product is local: a coarse element's matrix is the sum over its
``2^dim`` children ``c`` of ``P_c^T K_c P_c``, ``P_c`` the interpolation from the coarse
element's corners to the child's. On the first coarse level this is ``sum_c E_c P_c^T K0 P_c``,
eight fixed matrices weighted by the children's moduli (a child that holds a fixed degree of
freedom adds its own masked product); above it, per-element matrices.

One V-cycle: a Chebyshev polynomial of :data:`DEGREE` in ``D^-1 A`` on the spectrum
``[mu / RATIO, mu]`` smooths before and after the coarse correction (``mu`` bounds the spectrum:
the largest over the level's elements of their own ``diag(K_e)^-1 K_e``'s), and a dense Cholesky
solve settles the coarsest level. Pre- and post-smoothing apply the same polynomial, so the cycle
is a symmetric positive definite preconditioner for CG. Where a design leaves pieces of solid
floating in the void, whose rigid motions no level represents, the cycle is balanced by those
motions (:mod:`ginn.physics.floating`). Every shape and load case of a batch runs in the same
tensor operations, on the device of the moduli.

Public names: :class:`Multigrid`, :class:`Hierarchy`, :func:`interpolation_1d`, :func:`child_interpolation`,
:data:`COARSEST_DOFS`, :data:`DEGREE`, :data:`RATIO`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from .elements import corner_offsets
from .floating import FloatingModes
from .grid import ElementGrid

__all__ = ["Multigrid", "Hierarchy", "interpolation_1d", "child_interpolation", "COARSEST_DOFS", "DEGREE", "RATIO"]

COARSEST_DOFS = 1000  # the hierarchy stops at the first level with at most this many degrees of freedom
DEGREE = 3  # terms of the Chebyshev smoother before and after each coarse correction
POWER_STEPS = 12  # power-method steps of the smoother's spectral bound
RATIO = 10.0  # the smoother's spectrum: [mu / RATIO, mu], mu the bound on that of D^-1 A


def interpolation_1d(n_fine: int) -> np.ndarray:
    """``(n_fine + 1, ceil(n_fine / 2) + 1)``: linear interpolation from the nodes of a line of
    ``ceil(n_fine / 2)`` elements to those of ``n_fine`` elements of half the length (fine node
    ``i`` sits at coarse coordinate ``i / 2``)."""
    n_coarse = -(-n_fine // 2)
    P = np.zeros((n_fine + 1, n_coarse + 1))
    i = np.arange(n_fine + 1)
    P[i[::2], i[::2] // 2] = 1.0
    odd = i[1::2]
    P[odd, odd // 2] = 0.5
    P[odd, odd // 2 + 1] = 0.5
    return P


def child_interpolation(dim: int) -> np.ndarray:
    """``(2^dim, k, k)``, ``k = dim 2^dim``: ``P_c`` maps the corner displacements of a coarse
    element to those of its child ``c`` (the child at offset bit ``a`` of ``c`` along axis ``a``),
    in the local numbering of :mod:`ginn.physics.elements`."""
    off = corner_offsets(dim)  # (n, d)
    n = off.shape[0]
    xi = 0.5 * (off[:, None, :] + off[None, :, :])  # (child, fine corner, d): position in the coarse element
    w = np.prod(np.where(off[None, None, :, :] == 1, xi[:, :, None, :], 1.0 - xi[:, :, None, :]), axis=-1)  # (c, a, b)
    return np.einsum("cab,ij->caibj", w, np.eye(dim)).reshape(n, n * dim, n * dim)


@dataclass
class _Level:
    grid: ElementGrid
    edof: torch.Tensor  # (ne, k)
    prolong: list[torch.Tensor]  # per axis, from the level above to this one: (n_a + 1, n_a' + 1); empty on the coarsest
    child_slots: torch.Tensor | None  # (ne', 2^dim): this level's element under each child slot of the next (-1: none)


class Multigrid:
    """The level hierarchy of ``grid`` with the degrees of freedom ``fixed`` held at zero.

    Arguments:
        grid: the element grid (level 0).
        K0: ``(k, k)`` the unit-modulus element matrix of ``grid``.
        fixed: ``(n_dofs,)`` bool.
        active: ``(n_elements,)`` bool, the elements whose moduli may be nonzero (default: all).
        coarsest: the hierarchy stops at the first level with at most this many degrees of freedom.
        floating: balance the V-cycle with the rigid motions of the pieces a design leaves floating
            (:mod:`ginn.physics.floating`; False: the plain V-cycle, for comparison).
    """

    def __init__(self, grid: ElementGrid, K0: np.ndarray, fixed: np.ndarray, active: np.ndarray | None = None,
                 coarsest: int = COARSEST_DOFS, floating: bool = True) -> None:
        self.grid = grid
        self.K0 = np.asarray(K0, dtype=np.float64)
        self.fixed = np.asarray(fixed, dtype=bool).reshape(-1)
        self.dim = grid.dim
        self.coarsest = int(coarsest)
        self.floating = floating
        grids = [grid]
        while grids[-1].n_dofs > coarsest and max(grids[-1].shape) > 1:
            g = grids[-1]
            shape = tuple(-(-n // 2) for n in g.shape)
            hi = tuple(lo + 2 * h * n for lo, h, n in zip(g.lo, g.h, shape))
            grids.append(ElementGrid(g.lo, hi, shape))
        self.grids = grids
        self.P = child_interpolation(self.dim)  # (c, k, k)
        self.M = np.einsum("cai,ab,cbj->cij", self.P, self.K0, self.P)  # P_c^T K0 P_c
        # where an element of the grid holds fixed degrees of freedom, its masked matrix differs
        live = np.ones(grid.n_elements, bool) if active is None else np.asarray(active, dtype=bool).reshape(-1)
        self.live = live
        touched = np.flatnonzero(self.fixed[grid.element_dofs].any(axis=1) & live)
        self._bnd = touched
        if len(grids) > 1:
            mask = (~self.fixed[grid.element_dofs[touched]]).astype(np.float64)  # (nb, k)
            child = self._child_index(grid, touched)
            Pb = self.P[child]  # (nb, k, k)
            masked = np.einsum("na,ab,nb->nab", mask, self.K0, mask)
            self._bnd_mats = np.einsum("nai,nab,nbj->nij", Pb, masked, Pb)  # (D_e P_c)^T K0 (D_e P_c)
            self._bnd_parent = self._parent_index(grid, grids[1], touched)
        self._cache: dict[str, list[_Level]] = {}

    @property
    def n_levels(self) -> int:
        return len(self.grids)

    @staticmethod
    def _child_index(g: ElementGrid, elements: np.ndarray) -> np.ndarray:
        idx = np.stack(np.unravel_index(elements, g.shape))  # (d, m)
        return ((idx & 1) << np.arange(g.dim)[:, None]).sum(0)

    @staticmethod
    def _parent_index(g: ElementGrid, coarse: ElementGrid, elements: np.ndarray) -> np.ndarray:
        idx = np.stack(np.unravel_index(elements, g.shape))
        return np.ravel_multi_index(tuple(idx >> 1), coarse.shape)

    def levels(self, device: torch.device) -> list[_Level]:
        key = str(device)
        if key not in self._cache:
            out = []
            for li, g in enumerate(self.grids):
                prolong, slots = [], None
                if li + 1 < len(self.grids):
                    prolong = [torch.as_tensor(interpolation_1d(n), device=device) for n in g.shape]
                    coarse = self.grids[li + 1]
                    slots_np = np.full((coarse.n_elements, 2**self.dim), -1, dtype=np.int64)
                    every = np.arange(g.n_elements)
                    slots_np[self._parent_index(g, coarse, every), self._child_index(g, every)] = every
                    slots = torch.as_tensor(slots_np, device=device)
                out.append(_Level(g, torch.as_tensor(g.element_dofs, device=device), prolong, slots))
            self._cache[key] = out
        return self._cache[key]

    def hierarchy(self, moduli: torch.Tensor, apply_fine) -> Hierarchy:
        """The operators of every level for element moduli ``(B, n_elements)`` (float64; those of
        elements that are not ``active`` taken as zero);
        ``apply_fine(U)`` ``(B, L, n_dofs) -> (B, L, n_dofs)`` is the element grid's operator
        (fixed rows and columns zero)."""
        dev = moduli.device
        levels = self.levels(dev)
        moduli = torch.where(torch.as_tensor(self.live, device=dev), moduli, 0.0)
        B = moduli.shape[0]
        K0 = torch.as_tensor(self.K0, device=dev)
        free = torch.as_tensor(~self.fixed, device=dev, dtype=torch.float64)
        edof0 = levels[0].edof
        diag0 = torch.zeros(B, self.grid.n_dofs, dtype=torch.float64, device=dev)
        diag0.index_add_(1, edof0.reshape(-1), (moduli[:, :, None] * torch.diagonal(K0)[None, None]).reshape(B, -1))
        inv = [_inverse(diag0 * free)]
        spread = [_spread(K0[None])]
        mats: list[torch.Tensor | None] = [None]
        if len(levels) > 1:
            # level 1: sum_c E_c P_c^T K0 P_c over the children that hold no fixed degree of freedom,
            # their own masked products over those that do (summed apart, so that a coarse degree of
            # freedom that interpolates to fixed ones only has an exactly zero row)
            slots = levels[0].child_slots  # (ne1, c)
            plain = moduli
            if self._bnd.size:
                bnd = torch.as_tensor(self._bnd, device=dev)
                plain = moduli.index_fill(1, bnd, 0.0)
            Ec = torch.where(slots >= 0, plain[:, slots.clamp_min(0)], 0.0)  # (B, ne1, c)
            K = torch.einsum("bec,cij->beij", Ec, torch.as_tensor(self.M, device=dev))
            if self._bnd.size:
                add = moduli[:, bnd][:, :, None, None] * torch.as_tensor(self._bnd_mats, device=dev)[None]
                K.index_add_(1, torch.as_tensor(self._bnd_parent, device=dev), add)
            mats.append(K)
            P = torch.as_tensor(self.P, device=dev)
            for li in range(1, len(levels) - 1):
                slots = levels[li].child_slots
                Kc = torch.where((slots >= 0)[None, :, :, None, None], K[:, slots.clamp_min(0)], 0.0)  # (B, ne', c, k, k)
                K = torch.einsum("cai,secab,cbj->seij", P, Kc, P)
                mats.append(K)
            for li in range(1, len(levels)):
                d = torch.zeros(B, levels[li].grid.n_dofs, dtype=torch.float64, device=dev)
                d.index_add_(1, levels[li].edof.reshape(-1), torch.diagonal(mats[li], dim1=-2, dim2=-1).reshape(B, -1))
                inv.append(_inverse(d))
                spread.append(_spread(mats[li]))
        # the coarsest level: dense, its zero rows set to the identity, Cholesky-factorised
        last = levels[-1]
        n = last.grid.n_dofs
        if len(levels) == 1:
            edof, Kel = last.edof, moduli[:, :, None, None] * K0[None, None]
        else:
            edof, Kel = last.edof, mats[-1]
        dense = torch.zeros(B, n * n, dtype=torch.float64, device=dev)
        flat = (edof[:, :, None] * n + edof[:, None, :]).reshape(-1)
        dense.index_add_(1, flat, Kel.reshape(B, -1))
        dense = dense.reshape(B, n, n)
        if len(levels) == 1:
            dense = dense * free[None, :, None] * free[None, None, :]
        zero = torch.diagonal(dense, dim1=-2, dim2=-1) <= 0
        dense = dense + torch.diag_embed(zero.to(torch.float64))
        chol = torch.linalg.cholesky(dense)
        modes = FloatingModes(self.grid, self.K0, self.fixed, moduli, limit=self.coarsest) if self.floating else None
        return Hierarchy(self, levels, moduli, apply_fine, mats, inv, spread, chol, (~zero).to(torch.float64), free, modes)


def _spread(mats: torch.Tensor) -> float:
    """The largest eigenvalue of ``diag(K)^-1 K`` over element matrices ``mats`` ``(..., k, k)``: it
    bounds that of ``D^-1 A`` for the matrix ``A`` they assemble (``x^T A x`` is the sum of the
    elements' ``x_e^T K_e x_e``, ``D`` the sum of their diagonals). Found by :data:`POWER_STEPS`
    steps of the power method on every element at once (an estimate from below of each element's,
    whose largest exceeds the assembled matrix's by a margin: 5.3 against 3.8 to 4.0 on the
    trilinear hexahedra of the tests), times 1.05."""
    d = torch.diagonal(mats, dim1=-2, dim2=-1)
    scale = torch.where(d > 0, d.clamp_min(torch.finfo(torch.float64).tiny).rsqrt(), 0.0)
    S = mats * scale[..., :, None] * scale[..., None, :]
    x = torch.ones(S.shape[:-1], dtype=S.dtype, device=S.device)
    x[..., ::2] = -0.5  # not orthogonal to the top eigenvector of an element in equilibrium
    lam = torch.zeros(S.shape[:-2], dtype=S.dtype, device=S.device)
    for _ in range(POWER_STEPS):
        y = torch.matmul(S, x[..., None])[..., 0]
        lam = y.norm(dim=-1) / x.norm(dim=-1).clamp_min(torch.finfo(S.dtype).tiny)
        x = y / y.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(S.dtype).tiny)
    return 1.05 * float(lam.amax())


def _inverse(diag: torch.Tensor) -> torch.Tensor:
    """``1 / diag`` where positive, zero elsewhere (fixed or inert degrees of freedom)."""
    return torch.where(diag > 0, 1.0 / diag.clamp_min(torch.finfo(torch.float64).tiny), 0.0)


@dataclass
class Hierarchy:
    """The level operators for one batch of moduli; :meth:`precondition` is one V-cycle."""

    mg: Multigrid
    levels: list[_Level]
    moduli: torch.Tensor
    apply_fine: object
    mats: list[torch.Tensor | None]
    inv: list[torch.Tensor]  # per level (B, n_dofs_l): the inverse diagonal (zero where fixed or inert)
    spread: list[float]  # per level: the bound on the spectrum of D^-1 A
    chol: torch.Tensor  # (B, n, n) the coarsest level's Cholesky factor
    live: torch.Tensor  # (B, n) the coarsest level's degrees of freedom with a nonzero row
    free: torch.Tensor  # (n_dofs,) the element grid's free mask
    modes: FloatingModes | None  # the rigid motions of the floating pieces (None: the plain cycle)

    def apply(self, li: int, U: torch.Tensor) -> torch.Tensor:
        """Level ``li``'s operator on ``U`` ``(B, L, n_dofs_l)``."""
        if li == 0:
            return self.apply_fine(U)
        edof = self.levels[li].edof
        Ue = U[:, :, edof]  # (B, L, ne, k)
        Fe = torch.einsum("seij,slej->slei", self.mats[li], Ue)
        out = torch.zeros_like(U)
        out.index_add_(2, edof.reshape(-1), Fe.reshape(*Fe.shape[:2], -1))
        return out

    def _prolong(self, li: int, U: torch.Tensor) -> torch.Tensor:
        """Level ``li + 1``'s ``(B, L, n_dofs)`` to level ``li``'s."""
        g = self.levels[li + 1].grid
        X = U.reshape(*U.shape[:2], *g.node_shape, g.dim)
        for a, Pa in enumerate(self.levels[li].prolong):
            X = torch.movedim(torch.matmul(Pa, torch.movedim(X, 2 + a, -2)), -2, 2 + a)
        X = X.reshape(*U.shape[:2], -1)
        return X * self.free if li == 0 else X

    def _restrict(self, li: int, R: torch.Tensor) -> torch.Tensor:
        """Level ``li``'s residual ``(B, L, n_dofs)`` to level ``li + 1`` (``P^T``)."""
        g = self.levels[li].grid
        if li == 0:
            R = R * self.free
        X = R.reshape(*R.shape[:2], *g.node_shape, g.dim)
        for a, Pa in enumerate(self.levels[li].prolong):
            X = torch.movedim(torch.matmul(Pa.T, torch.movedim(X, 2 + a, -2)), -2, 2 + a)
        return X.reshape(*R.shape[:2], -1)

    def _smooth(self, li: int, R: torch.Tensor, X: torch.Tensor | None) -> torch.Tensor:
        """Chebyshev smoothing of ``A X = R`` from ``X`` (``None``: zero), :data:`DEGREE` terms, on the
        spectrum ``[mu / RATIO, mu]`` of ``D^-1 A`` (``mu`` the element bound of the level)."""
        inv = self.inv[li][:, None]
        mu = self.spread[li]
        theta, delta = 0.5 * mu * (1 + 1 / RATIO), 0.5 * mu * (1 - 1 / RATIO)
        sigma = theta / delta
        rho = 1.0 / sigma
        r = R if X is None else R - self.apply(li, X)
        d = inv * r / theta
        X = d if X is None else X + d
        for _ in range(DEGREE - 1):
            r = r - self.apply(li, d)
            rho_new = 1.0 / (2.0 * sigma - rho)
            d = rho_new * rho * d + (2.0 * rho_new / delta) * inv * r
            rho = rho_new
            X = X + d
        return X

    def _cycle(self, li: int, R: torch.Tensor) -> torch.Tensor:
        if li == len(self.levels) - 1:
            x = torch.cholesky_solve((R * self.live[:, None]).transpose(1, 2), self.chol).transpose(1, 2)
            return x * self.live[:, None]
        X = self._smooth(li, R, None)
        X = X + self._prolong(li, self._cycle(li + 1, self._restrict(li, R - self.apply(li, X))))
        return self._smooth(li, R, X)

    def precondition(self, R: torch.Tensor) -> torch.Tensor:
        """One V-cycle on the element grid's residuals ``(B, L, n_dofs)`` (zero at fixed degrees of
        freedom), balanced by the floating pieces' rigid motions (:mod:`ginn.physics.floating`):
        ``Q R + (I - Q A) V (I - A Q) R``, ``Q = Z A_c^-1 Z^T`` and ``V`` the cycle."""
        if self.modes is None or self.modes.G == 0:
            return self._cycle(0, R)
        q = self.modes.correct(R)
        v = self._cycle(0, R - self.apply(0, q))
        return q + v - self.modes.correct(self.apply(0, v))
