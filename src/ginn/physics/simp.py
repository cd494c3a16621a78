"""The reference optimiser: SIMP with optimality-criteria updates (Sigmund 2001; Andreassen et al.
2011, "Efficient topology optimization in MATLAB using 88 lines of code").

Element densities ``x`` in ``[0, 1]``; the physical densities are ``x`` filtered (``density``
filter) or ``x`` itself (``sensitivity`` filter); the modulus of an element is
``E_min + xphys^p (1 - E_min)`` (``E`` relative to the solid's); the objective is the weighted sum of
the load cases' compliances; the volume of the physical densities is held at
``volume_fraction`` of the design elements by bisection on the optimality-criteria multiplier; the
move limit is 0.2 and the run stops when no density moves by more than ``tol`` (0.01), as in the
88-line code. Elements can be held solid or void (``passive``).

Public names: :func:`simp`, :class:`SimpResult`, :class:`DensityFilter`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import torch

from .solve import ElasticitySolver

__all__ = ["simp", "SimpResult", "DensityFilter"]


class DensityFilter:
    """The linear cone filter of radius ``radius`` element sizes: ``H_ij = max(0, r - |c_i - c_j|)``
    over element centres (distances in element sizes), rows normalised by ``Hs_i = sum_j H_ij``."""

    def __init__(self, shape: tuple[int, ...], radius: float) -> None:
        if radius <= 0:
            raise ValueError("DensityFilter: the radius must be positive")
        reach = int(np.ceil(radius)) - 1
        idx = np.indices(shape).reshape(len(shape), -1).T  # (ne, d)
        rows, cols, vals = [], [], []
        offsets = np.indices((2 * reach + 1,) * len(shape)).reshape(len(shape), -1).T - reach
        for off in offsets:  # a loop over the (2 reach + 1)^d stencil offsets, vectorised over elements
            w = radius - float(np.sqrt((off**2).sum()))
            if w <= 0:
                continue
            nb = idx + off
            ok = np.all((nb >= 0) & (nb < np.asarray(shape)), axis=1)
            rows.append(np.flatnonzero(ok))
            cols.append(np.ravel_multi_index(tuple(nb[ok].T), shape))
            vals.append(np.full(int(ok.sum()), w))
        n = int(np.prod(shape))
        self.H = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
        self.Hs = np.asarray(self.H.sum(axis=1)).reshape(-1)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The filtered field ``H x / Hs``."""
        return (self.H @ x) / self.Hs

    def adjoint(self, g: np.ndarray) -> np.ndarray:
        """The gradient with respect to ``x`` of a function whose gradient in ``H x / Hs`` is ``g``."""
        return self.H.T @ (g / self.Hs)


@dataclass
class SimpResult:
    """A SIMP run.

    Attributes:
        density: ``(n_elements,)`` the physical densities of the last design.
        compliance: the weighted compliance of that design (with its grey elements).
        compliances: ``(L,)`` per load case.
        volume_fraction: mean physical density over the design elements.
        iterations: optimisation steps taken.
        history: the weighted compliance at each step.
    """

    density: np.ndarray
    compliance: float
    compliances: np.ndarray
    volume_fraction: float
    iterations: int
    history: list[float] = field(default_factory=list)


def simp(solver: ElasticitySolver, volume_fraction: float, *, penalty: float = 3.0, filter_radius: float = 1.5,
         filter: str = "density", weights: np.ndarray | None = None, passive_solid: np.ndarray | None = None,
         passive_void: np.ndarray | None = None, e_min: float = 1e-9, move: float = 0.2, tol: float = 0.01,
         max_iter: int = 500) -> SimpResult:
    """Minimise the weighted compliance on ``solver``'s grid under a volume bound.

    Arguments:
        solver: the elasticity problem (grid, supports, load cases).
        volume_fraction: the bound on the mean physical density of the design elements (those not passive).
        penalty: the SIMP exponent ``p``.
        filter_radius: the cone filter's radius in element sizes (the 88-line code's ``rmin``).
        filter: ``density`` (the 88-line code's ``ft = 2``) or ``sensitivity`` (``ft = 1``).
        weights: ``(L,)`` load-case weights (default all 1).
        passive_solid, passive_void: ``(n_elements,)`` bool, elements held at density 1 or 0.
        e_min: the void's modulus relative to the solid's.
        move, tol, max_iter: the move limit, the stopping change and the step cap.
    """
    if filter not in ("density", "sensitivity"):
        raise ValueError("simp: filter must be 'density' or 'sensitivity'")
    g = solver.grid
    ne = g.n_elements
    w = np.ones(solver.n_loads) if weights is None else np.asarray(weights, dtype=np.float64)
    solid = np.zeros(ne, bool) if passive_solid is None else np.asarray(passive_solid, bool)
    void = np.zeros(ne, bool) if passive_void is None else np.asarray(passive_void, bool)
    design = ~(solid | void)
    target = volume_fraction * design.sum() + solid.sum()
    filt = DensityFilter(g.shape, filter_radius)

    def physical(x: np.ndarray) -> np.ndarray:
        xp = filt(x) if filter == "density" else x.copy()
        xp[solid] = 1.0
        xp[void] = 0.0
        return xp

    x = np.where(solid, 1.0, np.where(void, 0.0, volume_fraction))
    xphys = physical(x)
    history: list[float] = []
    it = 0
    while True:
        it += 1
        E = e_min + xphys**penalty * (1.0 - e_min)
        U = solver.solve(torch.from_numpy(E))
        energy = solver.element_energy(U)[0].numpy()  # (L, ne)
        cl = (E[None] * energy).sum(-1)
        c = float(w @ cl)
        history.append(c)
        dc = -penalty * (1.0 - e_min) * xphys ** (penalty - 1) * (w @ energy)
        dv = np.ones(ne)
        if filter == "sensitivity":
            dc = (filt.H @ (x * dc)) / filt.Hs / np.maximum(1e-3, x)
        else:
            dc = filt.adjoint(dc)
            dv = filt.adjoint(dv)
        dc[~design] = 0.0
        scale = np.sqrt(np.maximum(-dc, 0.0) / dv)
        lo, hi = 0.0, 1e9
        while (hi - lo) / (hi + lo) > 1e-3:
            mid = 0.5 * (lo + hi)
            xnew = np.clip(x * scale / np.sqrt(mid), np.maximum(0.0, x - move), np.minimum(1.0, x + move))
            xnew[solid] = 1.0
            xnew[void] = 0.0
            xphys_new = physical(xnew)
            if xphys_new.sum() > target:
                lo = mid
            else:
                hi = mid
        change = float(np.abs(xnew - x).max())
        x, xphys = xnew, xphys_new
        if change <= tol or it >= max_iter:
            break
    E = e_min + xphys**penalty * (1.0 - e_min)
    U = solver.solve(torch.from_numpy(E))
    cl = solver.work(U)[0].numpy()
    return SimpResult(xphys, float(w @ cl), cl, float(xphys[design].mean()), it, history)
