"""The structural objective: the weighted compliance of the problem's load cases
(``physics:`` in the spec; ``docs/structural.md``).

Every step evaluates each shape's field at the centres of the element grid
(:func:`ginn.problems.structural.structural_grid`), turns it into element densities by a smoothed
step ``rho = sigmoid(-f / w)`` and into moduli ``E (VOID + (1 - VOID) rho^p)``
(:mod:`ginn.problems.structural`: VOID 1e-6, a weak ersatz for void), the elements outside E or in
an obstacle held void. All shapes of the step are solved in one call
(:func:`ginn.physics.compliance`), which hands autograd the adjoint gradient.

Continuation: the step width ``w`` and the penalty ``p`` start at ``START_WIDTH`` times the
design region's depth (:func:`~ginn.problems.structural.design_depth`, the radius of the largest
ball in E: half the short side of a rectangle) and at 1, and reach half the smallest element side
(a field that is a distance goes from 0.12 to 0.88 across one element) and SIMP's 3 by
``CONTINUATION`` of the run, the width geometrically and the penalty linearly; then they stay.
With the sharp step and penalty 3 from the first step only the boundary has a gradient and the
shape keeps the topology of its first steps, as a level-set method keeps its initial guess's. A
step as wide as half the depth lets every element of E feel the loads, and at ``p = 1`` the
compliance is convex in the densities, grey material carrying in proportion to its density: the
start that SIMP's uniform grey field and penalty continuation give it. ``docs/structural.md`` has
the measurements.

Under a volume bound (``tolerances.volume_fraction.max``) the compliance is that of the shape
moved onto the bound: the densities are ``sigmoid(-(f - t) / w)`` with the offset ``t <= 0`` at
which their sum in E equals the bound's share of E (obstacles included, the spec's
``vol(shape ∩ E) / vol(E)``; each element counted up to its share of E,
:func:`~ginn.problems.structural.design_shares`) less the volume term's margin
(:func:`volume_margin`, :mod:`ginn.constraints.volume`; found by bisection; 0 where the shape is
within it), and ``t`` carries its implicit gradient ``dt / df_e = r_e / sum r`` (``r = rho (1 - rho)``),
as an optimality-criteria step holds SIMP's volume. So the compliance rewards moving material, not
adding it; the volume term alone sets how much there is. Without it the compliance's pull on the
volume beat the volume term: the half MBB beam (``mbb``) ended at a volume fraction of 0.578
under a bound of 0.5.

Loss: ``sum_l w_l c_l / c_ref`` averaged over the shapes, ``c_ref`` the weighted compliance of E
all solid, so that the term has no unit and is about 2 to 5 at a volume fraction of a half. An
objective; the volume bound of the spec is its own term.

Report (:class:`ComplianceReport`, among the verdicts so that ``ginn eval`` and the checks during
training measure it, but never violated): each shape thresholded (``f <= 0`` solid, the rest the
void's modulus 1e-6) at the centres of the default element grid refined twice along each axis,
and solved there: ``compliance`` (weighted), ``compliance_cases`` (per load case) and
``max_displacement`` (the largest nodal displacement over the load cases).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from torch import Tensor

from .. import fields
from ..extract.sampling import field_dtype_device
from ..physics import ElementGrid, compliance
from ..problems.derived import smallest_feature
from ..problems.problem import Problem
from ..problems.structural import (
    PENALTY,
    VOID,
    design_depth,
    design_shares,
    in_obstacles,
    structural_grid,
    structural_solver,
    void_elements,
)
from .base import Constraint, Setting, Stage
from .batch import Batch
from .verdict import Verdict, Violation

__all__ = ["Compliance", "ComplianceReport", "count_error", "report_grid", "solid_elements", "solid_at",
           "ELEMENTS", "CONTINUATION", "START_WIDTH", "START_PENALTY", "continuation", "narrowed",
           "start_width", "covered", "volume_margin"]

#: the key of the element centres' field values in a step (:meth:`ginn.constraints.batch.Batch.field_at`)
ELEMENTS = "elements"
#: the share of the run over which the step width and the penalty reach their final values
CONTINUATION = 0.5
#: the step width at the start, in units of the design region's depth
#: (:func:`ginn.problems.structural.design_depth`)
START_WIDTH = 0.5
#: the penalty exponent at the start (compliance is convex in the densities at 1)
START_PENALTY = 1.0


def continuation(step: int, iterations: int) -> float:
    """``a`` in [0, 1]: how far the continuation is at iteration ``step`` of a run of ``iterations``
    (linear, reaching 1 at ``CONTINUATION`` of the run)."""
    n = CONTINUATION * iterations
    return min(step / n, 1.0) if n > 0 else 1.0


def narrowed(start: float, final: float, a: float) -> float:
    """The step width ``a`` of the way through the continuation: geometric from ``start`` to ``final``."""
    return start * (final / start) ** a


def start_width(problem: Problem, grid: ElementGrid) -> float:
    """The step width at the first iteration on ``grid``: ``START_WIDTH`` times the design region's
    depth, at least the final width (half the smallest element side)."""
    return max(START_WIDTH * design_depth(problem, grid), 0.5 * float(grid.h.min()))


def covered(f: Tensor, grid: ElementGrid) -> Tensor:
    """The share of each element that the shape covers, ``(S, n_elements)``, from the field values at
    the centres ``(S, n_elements)``: the field taken as linear across an element, with the gradient
    ``g`` of central differences between centres (detached), ranges over ``f +- e / 2``,
    ``e = sum_a h_a |g_a|``, and the share where it is negative is the ramp
    ``clamp(1/2 - f / e, 0, 1)`` (exact for a boundary along a grid axis; a second-order estimate
    of the volume where the centre count is first-order). Differentiable in ``f``."""
    S = f.shape[0]
    with torch.no_grad():
        grads = torch.gradient(f.detach().reshape(S, *grid.shape), spacing=[float(v) for v in grid.h],
                               dim=tuple(range(1, grid.dim + 1)))
        extent = sum(float(h) * g.abs() for h, g in zip(grid.h, grads)).reshape(S, -1).clamp_min(1e-30)
    return (0.5 - f / extent).clamp(0.0, 1.0)


def volume_margin(share: Tensor, in_design: Tensor) -> Tensor:
    """``(S,)``: how far inside its volume bound a shape is held, the standard error of the centre
    count of its volume fraction, ``sqrt(n_b / 12) / n_E`` for the ``n_b`` elements in E that its
    boundary crosses (each counted whole or not at all, off by a share uniform in +-1/2) out of
    ``n_E``. ``share`` ``(S, n_elements)``: :func:`covered` (detached); ``in_design``
    ``(n_elements,)``: E's share of each element (or whether it lies in E), ``n_E`` its sum."""
    crossed = ((share > 0) & (share < 1) & (in_design > 0)).sum(dim=1).to(share.dtype)
    return (crossed / 12.0).sqrt() / in_design.sum().clamp_min(1).to(share.dtype)


def report_grid(problem: Problem) -> ElementGrid:
    """The grid the report solves on: the default element grid refined twice along each axis."""
    return structural_grid(problem, 0, smallest_feature(problem)).refined(2)


def solid_elements(field, z, grid: ElementGrid, void: np.ndarray) -> np.ndarray:
    """``(n_elements,)`` bool: the elements of ``grid`` whose centre the shape of ``field`` at the
    latent ``z`` (None: a single shape) holds (``f <= 0``), less the ``void`` ones."""
    return solid_at(field, z, grid.centres) & ~void


def solid_at(field, z, points: np.ndarray) -> np.ndarray:
    """``(n,)`` bool: which of ``points`` ``(n, dim)`` the shape of ``field`` at the latent ``z``
    (None: a single shape) holds (``f <= 0``)."""
    dtype, device = field_dtype_device(field, z if isinstance(z, torch.Tensor) else None)
    x = torch.as_tensor(points, dtype=dtype, device=device)
    out = []
    with torch.no_grad():
        for s in range(0, x.shape[0], 65536):
            xc = x[s: s + 65536]
            zc = None if z is None else torch.as_tensor(z, dtype=dtype, device=device).reshape(1, -1).expand(xc.shape[0], -1)
            out.append(fields.evaluate(field, xc, zc, grad=False, create_graph=False).f.reshape(-1).cpu())
    return torch.cat(out).numpy() <= 0


def count_error(solids: np.ndarray, grid: ElementGrid, shares: np.ndarray) -> np.ndarray:
    """``(S,)``: the standard error of the volume fraction that the element counts ``solids``
    ``(S, n_elements)`` (bool) give, ``sqrt(n_b / 12) / n_E`` as :func:`volume_margin`'s, the
    ``n_b`` boundary elements being the solid ones with a face neighbour that is not; ``shares``
    ``(n_elements,)``: E's share of each element, ``n_E`` their sum."""
    S = solids.shape[0]
    cube = solids.reshape(S, *grid.shape)
    edge = np.zeros_like(cube)
    for axis in range(1, grid.dim + 1):
        a = np.swapaxes(cube, 1, axis)
        e = np.swapaxes(edge, 1, axis)
        e[:, 1:] |= a[:, 1:] & ~a[:, :-1]
        e[:, :-1] |= a[:, :-1] & ~a[:, 1:]
    return np.sqrt(edge.reshape(S, -1).sum(axis=1) / 12.0) / max(float(shares.sum()), 1.0)


class ComplianceReport(Verdict):
    """The compliance of the thresholded shape on the fine grid (module docstring); never violated."""

    name = "compliance"
    judges = False  # a solve on the fine grid per shape: ginn eval's, not the checks' during training
    objective = True

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("compliance",)
        self._fine: tuple | None = None
        self._solved: dict[bytes, tuple[torch.Tensor, torch.Tensor]] = {}  # :meth:`prepare`'s solutions
        self._shares: np.ndarray | None = None  # E's share of each fine element, for :meth:`objective_of`

    def fine(self) -> tuple:
        """``(grid, solver, weights, void)`` of the report's grid, built at the first use."""
        if self._fine is None:
            p = self.problem
            grid = report_grid(p)
            solver, w = structural_solver(p, grid)
            self._fine = (grid, solver, w, void_elements(p, grid))
        return self._fine

    def solid(self, field, z) -> np.ndarray:
        """``(n_elements,)`` bool: the fine grid's elements whose centre the shape holds (``f <= 0``) in E."""
        grid, _, _, void = self.fine()
        return solid_elements(field, z, grid, void)

    def analyse(self, field, z) -> tuple[np.ndarray, torch.Tensor, torch.Tensor]:
        """The thresholded shape solved on the fine grid: its solid elements ``(n_elements,)``, the
        displacements ``(L, n_dofs)`` and the strain-energy density of each element ``(L, n_elements)``
        (``E_e u_e^T K0 u_e / (2 V_e)``); a shape :meth:`prepare` solved is not solved again."""
        solid = self.solid(field, z)
        done = self._solved.get(solid.tobytes())
        if done is not None:
            return solid, done[0], done[1]
        U, density = self._solve(solid[None])
        return solid, U[0], density[0]

    def analyse_all(self, field, Z: torch.Tensor | None) -> list[tuple[np.ndarray, torch.Tensor, torch.Tensor]]:
        """:meth:`analyse` of each shape of ``Z`` ``(S, k)`` (None: the single shape), all solved in
        one call: the shapes side by side on the solver's threads, each solution the same bit for bit
        as :meth:`analyse` gives it alone."""
        codes = [None] if Z is None else [Z[i] for i in range(Z.shape[0])]
        solids = np.stack([self.solid(field, z) for z in codes])
        U, density = self._solve(solids)
        return [(solids[i], U[i], density[i]) for i in range(len(codes))]

    def prepare(self, field, Z: torch.Tensor | None) -> None:
        """Solve the shapes of ``Z`` in one call (:meth:`analyse_all`) and keep their solutions for
        :meth:`analyse` and :meth:`measure` until :meth:`release`: ``ginn eval`` measures the shapes
        one at a time, and a 3D fine grid's factorisation takes seconds per shape."""
        for solid, U, density in self.analyse_all(field, Z):
            self._solved[solid.tobytes()] = (U, density)

    def release(self) -> None:
        """Forget :meth:`prepare`'s solutions."""
        self._solved.clear()

    def _solve(self, solids: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        """Displacements ``(B, L, n_dofs)`` and strain-energy densities ``(B, L, n_elements)`` of the
        thresholded shapes ``solids`` ``(B, n_elements)`` on the fine grid."""
        grid, solver, _, _ = self.fine()
        E = float(self.problem.physics.youngs_modulus)
        moduli = torch.as_tensor(E * np.where(solids, 1.0, VOID))
        U = solver.solve(moduli)
        return U, moduli[:, None] * solver.element_energy(U) / (2.0 * grid.element_volume)

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        grid, solver, w, _ = self.fine()
        _, U, _ = self.analyse(field, z)
        cases = solver.work(U[None])[0].numpy()
        disp = U.reshape(U.shape[0], -1, grid.dim).norm(dim=-1).max()
        return {"compliance": float(w @ cases), "compliance_cases": [float(c) for c in cases],
                "max_displacement": float(disp)}

    def objective_of(self, field, Z: torch.Tensor | None) -> tuple[float, float, bool]:
        """``(compliance, volume, inside)``: the means over the shapes of ``Z`` ``(S, k)`` (None: the
        single shape) of the weighted compliance of each thresholded shape on the fine grid
        (``measure``'s ``compliance``, the shapes solved in one call, CG from a cold start whatever
        was solved before) and of the volume fraction that solve held (its solid elements' shares of
        E), and whether every shape's volume lies inside the bound by twice the standard error of
        that count (:func:`count_error`; true without a bound)."""
        grid, solver, w, _ = self.fine()
        solver.load_warm_state({}, torch.device("cpu"))
        solved = self.analyse_all(field, Z)
        U = torch.stack([U for _, U, _ in solved])  # (S, L, n_dofs)
        if self._shares is None:
            self._shares = design_shares(self.problem, grid)
        solids = np.stack([solid for solid, _, _ in solved])  # (S, n_elements)
        volumes = solids @ self._shares / self._shares.sum()
        bound = self.problem.tolerances.volume_fraction
        inside = bound is None or bound.max is None or bool(
            np.all(volumes + 2 * count_error(solids, grid, self._shares) <= bound.max))
        return float((solver.work(U).numpy() @ w).mean()), float(volumes.mean()), inside

    def violation(self, metrics: Mapping) -> Violation | None:
        return None

    def ratio(self, metrics: Mapping) -> float | None:
        return None


class Compliance(Constraint):
    """The weighted compliance of every shape of the step (see the module docstring)."""

    name = "compliance"
    stage = Stage.FIELD

    def __init__(self, setting: Setting):
        super().__init__(setting)
        p, cfg = setting.problem, setting.cfg.structural
        self.grid = structural_grid(p, cfg.cells, smallest_feature(p))
        self.solver, w = structural_solver(p, self.grid, cfg.method)
        dev = setting.device
        self.weights = torch.as_tensor(w, dtype=torch.float64, device=dev)
        self.void = torch.as_tensor(void_elements(p, self.grid), device=dev)
        shares = design_shares(p, self.grid)  # E's share of each element, obstacles included
        self.design = torch.as_tensor(shares, dtype=setting.dtype, device=dev)
        self.design_volume = float(shares.sum())  # vol(E) in elements
        blocked = in_obstacles(p, self.grid.centres)
        self.counted = torch.as_tensor((shares > 0) & ~blocked, device=dev)  # where the shape's volume in E can be
        self.centres = torch.as_tensor(self.grid.centres, dtype=setting.dtype, device=dev)
        self.final_width = 0.5 * float(self.grid.h.min())
        self.start_width = start_width(p, self.grid)
        self.width, self.penalty = self.final_width, PENALTY
        self.modulus = float(p.physics.youngs_modulus)
        solid = torch.where(self.void, 0.0, 1.0).to(torch.float64)[None]
        c, _ = compliance(self.moduli(solid), self.solver)
        self.reference = float((c * self.weights).sum())

    def schedule(self, step: int) -> tuple[float, float]:
        """``(width, penalty)`` at iteration ``step`` (the continuation of the module docstring)."""
        a = continuation(step, self.setting.cfg.training.iterations)
        return narrowed(self.start_width, self.final_width, a), START_PENALTY + (PENALTY - START_PENALTY) * a

    def density(self, f: Tensor) -> Tensor:
        """Element densities ``(S, n_elements)`` of field values at the centres ``(S, n_elements)``
        (at the current step width :attr:`width`)."""
        rho = torch.sigmoid(-f / self.width)
        return torch.where(self.void, torch.zeros_like(rho), rho)

    def offset(self, f: Tensor) -> Tensor:
        """``t`` ``(S, 1)``: the offset that moves each shape onto the volume bound (module docstring),
        with its implicit gradient; zeros without a bound."""
        b = self.setting.problem.tolerances.volume_fraction
        S = f.shape[0]
        if b is None or b.max is None:
            return torch.zeros(S, 1, dtype=f.dtype, device=f.device)
        inE, share = self.counted, self.design
        with torch.no_grad():
            fd = f.detach()
            # the bound is a share of E, obstacles included; each element holds at most its share of E
            target = (float(b.max) - volume_margin(covered(fd, self.grid), share))[:, None] * self.design_volume

            def mass(t: Tensor) -> Tensor:
                rho = torch.minimum(torch.sigmoid(-(fd - t) / self.width), share)
                return torch.where(inE, rho, 0.0).sum(dim=1, keepdim=True)

            lo = fd.min(dim=1, keepdim=True).values - 40 * self.width
            hi = torch.zeros(S, 1, dtype=f.dtype, device=f.device)
            over = mass(hi) > target  # only shapes over the bound move
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                big = mass(mid) > target
                hi = torch.where(big, mid, hi)
                lo = torch.where(big, lo, mid)
            t0 = torch.where(over, 0.5 * (lo + hi), torch.zeros_like(hi))
            rho = torch.where(inE, torch.sigmoid(-(fd - t0) / self.width), 0.0)
            r = torch.where(rho < share, rho * (1 - rho), 0.0)  # an element filled to its share of E adds no mass
            a = torch.where(over, r / r.sum(dim=1, keepdim=True).clamp_min(1e-30), torch.zeros_like(r))
        return t0 + (a * (f - fd)).sum(dim=1, keepdim=True)

    def moduli(self, rho: Tensor) -> Tensor:
        """Element moduli (float64) of densities ``rho`` (at the current penalty :attr:`penalty`)."""
        rho = rho.to(torch.float64)
        return self.modulus * (VOID + (1.0 - VOID) * rho**self.penalty)

    def state_dict(self) -> dict:
        """The CG solver's warm starts (empty for the direct solver)."""
        return {"warm": self.solver.warm_state()}

    def load_state_dict(self, state: dict) -> None:
        self.solver.load_warm_state(state.get("warm", {}), self.setting.device)

    def loss(self, batch: Batch) -> Tensor:
        self.width, self.penalty = self.schedule(batch.step)
        f = batch.field_at(ELEMENTS, self.centres)
        c, _ = compliance(self.moduli(self.density(f - self.offset(f))), self.solver)  # (S, L)
        weighted = (c * self.weights).sum(-1)
        batch.diagnostics["_compliance"] = weighted.detach().mean()
        return (weighted / self.reference).mean().to(f.dtype)
