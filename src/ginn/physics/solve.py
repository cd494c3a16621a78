"""Linear elasticity on an :class:`~ginn.physics.grid.ElementGrid`: the stiffness of every shape of a
batch from its element moduli, solved for every load case.

``K(E) = sum_e E_e K0_e`` with ``K0`` the unit-modulus element matrix
(:func:`~ginn.physics.elements.element_stiffness`), the same for every element of the grid. The
fixed degrees of freedom are removed (zero displacement there); a load case is a vector of nodal
forces. A node may also be held along a direction of its own (``normals``: a frictionless pin in a
round hole holds each node of the rim along the rim's normal, so the part turns about the pin): its
degrees of freedom are taken in a frame of its own (:class:`_Frames`), whose first axes span the
held directions, and the elements around it get the rotated matrix ``T_e^T K0 T_e``; the solve
runs in those frames and returns Cartesian displacements. Every method solves over the *active*
elements only (``active``: those of the design region, where a grid over a box has elements that
stay void; default all): the others are left out (modulus zero) and the degrees of freedom of
nodes with no active element are held at zero. Two methods solve ``K u = f``:

* ``direct``: the assembled matrix of the solved degrees of freedom (one scatter of the element
  matrices into a precomputed pattern), factorised once per shape and solved for every load case,
  then one step of iterative refinement. In 2D it is a band: the nodes numbered with the grid's
  shortest axis fastest, the matrix has half-bandwidth at most ``2 n_short + 5`` and LAPACK's band
  Cholesky (``dpbtrf``/``dpbtrs``, called without the interpreter lock: :mod:`ginn.physics.band`)
  factorises it; in 3D, where a band would be a plane of nodes
  wide, MKL's PARDISO (:mod:`ginn.physics.pardiso`, nested dissection and supernodes) factorises
  the sparse matrix where it is installed, SciPy's SuperLU (minimum-degree ordering of
  ``A^T + A``) otherwise. The shapes of a batch run side by side on as many threads as torch uses
  (the factorisations release the GIL), each on one BLAS thread, so that each shape's solve is the
  same on any count;
* ``cg``: matrix-free conjugate gradients in torch preconditioned by one V-cycle of geometric
  multigrid (:mod:`ginn.physics.multigrid`), balanced by the rigid motions of the pieces a design
  leaves floating (:mod:`ginn.physics.floating`), every shape and load case of the batch in one set of
  tensor operations on the moduli's device, warm-started from the previous solve of a batch of the
  same size; ``cg-diagonal``: the same preconditioned by the diagonal (the comparison of
  ``benchmarks/structural.py solver``).

``auto`` picks ``direct`` on the CPU for 2D grids, and for 3D grids with several load cases where
PARDISO is installed (one factorisation serves every load case, where CG solves each); ``cg``
otherwise and on accelerators (``docs/structural.md``, "The solver", has the measurements).

Public names: :class:`ElasticitySolver`, :data:`METHODS`.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import torch
from threadpoolctl import ThreadpoolController

from . import band
from .elements import element_stiffness
from .grid import ElementGrid
from .multigrid import Multigrid
from .pardiso import PardisoCholesky
from .pardiso import available as pardiso_available

__all__ = ["ElasticitySolver", "METHODS"]

METHODS = ("auto", "direct", "cg", "cg-diagonal")

_BLAS = ThreadpoolController()  # each shape's factorisation runs on one BLAS thread (``ElasticitySolver.solve``)


@dataclass(frozen=True)
class _DeviceData:
    """The solver's arrays on one device (:meth:`ElasticitySolver._torch_data`)."""

    K0: torch.Tensor  # (k, k) the unit-modulus element matrix
    edof: torch.Tensor  # (n_elements, k) every element's degrees of freedom
    free: torch.Tensor  # (n_dofs,) 1.0 where not fixed
    forces: torch.Tensor  # (L, n_dofs)
    local_forces: torch.Tensor  # (L, n_dofs) the forces in the nodes' frames (:class:`_Frames`)
    active: torch.Tensor  # (n_active,) the active elements' indices
    active_mask: torch.Tensor  # (n_elements,) bool, True at the active elements
    solved: torch.Tensor  # (n_dofs,) 1.0 where the CG methods solve (not held), in the nodes' frames
    active_edof: torch.Tensor  # (n_active, k) the active elements' degrees of freedom
    clamped: torch.Tensor  # (n_dofs,) 1.0 where the multigrid preconditioner solves (every framed node held)
    framed: torch.Tensor  # (n_dofs,) 1.0 at the framed nodes' solved degrees of freedom


class _Frames:
    """The nodes held along directions of their own and the frames their degrees of freedom are
    taken in.

    A node with a nonzero row of ``normals`` ``(n_nodes, d)`` is held along it and along its fixed
    axes: its frame ``Q`` ``(d, d)`` (orthonormal columns; Cartesian displacement ``Q u_local``)
    has first the ``r`` axes that span those directions (held: ``r = 1`` for a normal alone, more
    where a fixed axis adds another), then the ones it may move along. The nodes without a normal
    keep the Cartesian frame and their fixed axes.

    Attributes:
        nodes: ``(m,)`` the framed nodes.
        Q: ``(m, d, d)`` their frames.
        fixed: ``(n_dofs,)`` bool, the held degrees of freedom in the nodes' frames.
        elements: ``(n_e,)`` the elements with a framed corner.
        K0: ``(n_e, k, k)`` their unit-modulus matrices in the corners' frames, ``T_e^T K0 T_e``.
    """

    def __init__(self, grid: ElementGrid, K0: np.ndarray, fixed: np.ndarray, normals: np.ndarray | None) -> None:
        d = grid.dim
        self.fixed = fixed.copy()
        n = np.zeros((grid.n_nodes, d)) if normals is None else np.asarray(normals, dtype=np.float64).reshape(grid.n_nodes, d)
        length = np.linalg.norm(n, axis=1)
        self.nodes = np.flatnonzero(length > 0)
        m = self.nodes.size
        self.Q = np.zeros((m, d, d))
        self.elements = np.zeros(0, dtype=np.int64)
        self.K0 = np.zeros((0,) + K0.shape)
        self._on_device: dict = {}  # (device, dtype) -> (Q, nodes) as tensors there
        if m == 0:
            return
        held = np.zeros((m, d, d + 1))  # per node: its fixed axes' unit vectors and its normal, as columns
        axes = fixed.reshape(grid.n_nodes, d)[self.nodes]  # (m, d)
        held[:, :, :d] = np.eye(d)[None] * axes[:, None, :]
        held[:, :, d] = n[self.nodes] / length[self.nodes, None]
        U, S, _ = np.linalg.svd(held)  # U's first rank columns span the held directions
        rank = (S > 1e-9 * S[:, :1]).sum(axis=1)
        self.Q = U
        local = np.arange(d)[None, :] < rank[:, None]  # (m, d)
        self.fixed.reshape(grid.n_nodes, d)[self.nodes] = local
        framed = np.zeros(grid.n_nodes, bool)
        framed[self.nodes] = True
        corners = grid.element_nodes  # (n_elements, 2^d)
        self.elements = np.flatnonzero(framed[corners].any(axis=1))
        slot = np.full(grid.n_nodes, -1)
        slot[self.nodes] = np.arange(m)
        T = np.zeros((self.elements.size,) + K0.shape)  # blockdiag of the corners' frames
        eye = np.eye(d)
        for c in range(corners.shape[1]):
            j = slot[corners[self.elements, c]]
            T[:, c * d:(c + 1) * d, c * d:(c + 1) * d] = np.where((j >= 0)[:, None, None], self.Q[j.clip(0)], eye)
        self.K0 = np.einsum("eai,ab,ebj->eij", T, K0, T)

    def to_cartesian(self, U: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
        """``(..., n_dofs)`` displacements from the nodes' frames to Cartesian (a copy)."""
        return self._turn(U, transpose=False)

    def to_local(self, U: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
        """``(..., n_dofs)`` vectors from Cartesian to the nodes' frames (a copy)."""
        return self._turn(U, transpose=True)

    def _turn(self, U, transpose: bool):
        is_torch = isinstance(U, torch.Tensor)
        out = U.clone() if is_torch else np.array(U, copy=True)
        if self.nodes.size == 0:
            return out
        d = self.Q.shape[1]
        if is_torch:
            key = (str(U.device), U.dtype)
            if key not in self._on_device:
                self._on_device[key] = (torch.as_tensor(self.Q, device=U.device, dtype=U.dtype),
                                        torch.as_tensor(self.nodes, device=U.device))
            Q, nodes = self._on_device[key]
            V = out.reshape(*out.shape[:-1], -1, d)
            V[..., nodes, :] = torch.einsum("mji,...mj->...mi" if transpose else "mij,...mj->...mi", Q, V[..., nodes, :])
            return out
        V = out.reshape(*out.shape[:-1], -1, d)
        V[..., self.nodes, :] = np.einsum("mji,...mj->...mi" if transpose else "mij,...mj->...mi", self.Q, V[..., self.nodes, :])
        return out


class ElasticitySolver:
    """Solves linear elasticity on ``grid`` for a batch of element-modulus fields.

    Arguments:
        grid: the element grid.
        nu: Poisson's ratio (plane stress in 2D).
        fixed: ``(n_dofs,)`` bool, the degrees of freedom held at zero.
        forces: ``(L, n_dofs)`` nodal forces of the ``L`` load cases.
        method: one of :data:`METHODS`.
        rtol: relative residual at which CG stops.
        max_iter: CG's iteration cap (a solve that reaches it raises).
        active: ``(n_elements,)`` bool, the elements that may carry load (default: all). Every
            method leaves the others out (modulus zero instead of the weak ersatz) and holds the
            degrees of freedom of nodes with no active element at zero, so that a grid over a box
            solves only the design region's share of it.
        normals: ``(n_nodes, dim)``: a node with a nonzero row is also held along that direction
            (its displacement has no component along it) and moves freely across it (default:
            none).
    """

    def __init__(self, grid: ElementGrid, nu: float, fixed: np.ndarray, forces: np.ndarray, *,
                 method: str = "auto", rtol: float = 1e-10, max_iter: int = 20_000,
                 active: np.ndarray | None = None, normals: np.ndarray | None = None) -> None:
        if method not in METHODS:
            raise ValueError(f"ElasticitySolver: method must be one of {METHODS}, not {method!r}")
        fixed = np.asarray(fixed, dtype=bool).reshape(-1)
        forces = np.atleast_2d(np.asarray(forces, dtype=np.float64))
        if fixed.shape != (grid.n_dofs,) or forces.shape[1] != grid.n_dofs:
            raise ValueError("ElasticitySolver: fixed needs (n_dofs,) and forces (L, n_dofs) entries")
        self.grid = grid
        self.nu = float(nu)
        self.method = method
        self.rtol = float(rtol)
        self.max_iter = int(max_iter)
        self.iterations = 0  # CG's iterations in the last solve
        self.K0 = element_stiffness(grid.h, nu)  # (k, k)
        self.fixed = fixed  # Cartesian: the fixed axes
        self.active = np.ones(grid.n_elements, bool) if active is None else np.asarray(active, dtype=bool).reshape(-1)
        if self.active.shape != (grid.n_elements,):
            raise ValueError("ElasticitySolver: active needs (n_elements,) entries")
        if normals is not None and np.asarray(normals).shape != (grid.n_nodes, grid.dim):
            raise ValueError("ElasticitySolver: normals needs (n_nodes, dim) entries")
        self.frames = _Frames(grid, self.K0, fixed, normals)
        touched = np.zeros(grid.n_dofs, bool)
        touched[grid.element_dofs[self.active].reshape(-1)] = True
        if np.any(forces[:, ~touched & ~fixed] != 0):
            raise ValueError("ElasticitySolver: a load on a node with no active element")
        # the zero degrees of freedom, in the nodes' frames: held, or on no active element
        self.held = self.frames.fixed | ~touched
        self.free = np.flatnonzero(~self.held)  # the direct method's unknowns
        self.forces = forces
        self.local_forces = self.frames.to_local(forces)  # (L, n_dofs) in the nodes' frames
        self._pattern: tuple | None = None
        self._warm: dict = {}
        self._torch_cache: dict = {}
        self._band: tuple | None = None
        self._upper_pattern: tuple | None = None
        self._factorisers: dict[int, PardisoCholesky] = {}  # the 3D direct method's, per worker thread
        self._mg: Multigrid | None = None

    @property
    def n_loads(self) -> int:
        return self.forces.shape[0]

    def resolved_method(self, device: torch.device) -> str:
        if self.method != "auto":
            return self.method
        if device.type != "cpu":
            return "cg"
        if self.grid.dim == 2 or (self.n_loads > 1 and pardiso_available()):
            return "direct"
        return "cg"

    # --- assembly -------------------------------------------------------------------------------

    def _sparsity(self) -> tuple:
        """The CSR pattern of the free-dof matrix and, per kept (active element, a, b) entry, its
        slot (the elements left out add no entries: no fill the factorisation would carry)."""
        if self._pattern is None:
            g = self.grid
            k = self.K0.shape[0]
            index = np.full(g.n_dofs, -1, dtype=np.int64)
            index[self.free] = np.arange(self.free.size)
            edof = index[g.element_dofs[self.active]]  # (n_active, k)
            rows = np.repeat(edof, k, axis=1).reshape(-1)
            cols = np.tile(edof, (1, k)).reshape(-1)
            keep = (rows >= 0) & (cols >= 0)
            nf = self.free.size
            key = rows[keep] * nf + cols[keep]
            uniq, slot = np.unique(key, return_inverse=True)
            indptr = np.searchsorted(uniq // nf, np.arange(nf + 1))
            self._pattern = (keep, slot, uniq % nf, indptr, uniq.size)
        return self._pattern

    def stiffness(self, moduli: np.ndarray) -> sp.csr_matrix:
        """The free-dof stiffness matrix of one shape with element moduli ``moduli`` ``(n_elements,)``."""
        keep, slot, indices, indptr, nnz = self._sparsity()
        moduli = np.asarray(moduli, dtype=np.float64)
        if not self.active.all():
            moduli = moduli[self.active]
        vals = moduli[:, None] * self.K0.reshape(1, -1)  # (n_active, k k)
        if self.frames.elements.size:
            pos, turned = self._turned_active()
            vals[pos] = moduli[pos, None] * turned.reshape(pos.size, -1)
        vals = vals.reshape(-1)[keep]
        data = np.bincount(slot, weights=vals, minlength=nnz)
        n = self.free.size
        return sp.csr_matrix((data, indices, indptr), shape=(n, n))

    def _turned_active(self) -> tuple[np.ndarray, np.ndarray]:
        """The active elements with a framed corner: their positions among the active elements
        ``(n,)`` and their matrices in the corners' frames ``(n, k, k)``."""
        act = self.active[self.frames.elements]
        pos = np.searchsorted(np.flatnonzero(self.active), self.frames.elements[act])
        return pos, self.frames.K0[act]

    # --- solving --------------------------------------------------------------------------------

    def solve(self, moduli: torch.Tensor) -> torch.Tensor:
        """Displacements ``(B, L, n_dofs)`` (float64, on the moduli's device) for element moduli
        ``(B, n_elements)`` (or ``(n_elements,)``: ``B = 1``)."""
        E = torch.as_tensor(moduli).detach()
        if E.dim() == 1:
            E = E[None]
        if E.shape[1] != self.grid.n_elements:
            raise ValueError(f"ElasticitySolver.solve: {E.shape[1]} moduli for {self.grid.n_elements} elements")
        if not bool(torch.all(E > 0)):
            raise ValueError("ElasticitySolver.solve: every element modulus must be positive (give void a weak ersatz modulus)")
        method = self.resolved_method(E.device)
        if method in ("cg", "cg-diagonal"):
            return self._solve_cg(E.to(torch.float64), multigrid=method == "cg")
        En = E.to(torch.float64).cpu().numpy()
        U = np.zeros((En.shape[0], self.n_loads, self.grid.n_dofs))
        F = np.ascontiguousarray(self.local_forces[:, self.free].T)  # (nf, L)
        solve_one = self._band_solver(F) if self.grid.dim == 2 else self._sparse_solver(F)

        def run(worker: int, shapes: np.ndarray) -> None:
            for b in shapes:
                U[b][:, self.free] = solve_one(En[b], worker).T

        # the shapes side by side on torch's threads (the factorisations release the GIL), each on
        # one BLAS thread, so that a shape's solve is the same on any thread count
        chunks = np.array_split(np.arange(En.shape[0]), min(En.shape[0], torch.get_num_threads()))
        with _BLAS.limit(limits=1, user_api="blas"):
            if len(chunks) > 1:
                with ThreadPoolExecutor(len(chunks)) as pool:
                    list(pool.map(run, range(len(chunks)), chunks))
            else:
                run(0, chunks[0])
        if self.frames.nodes.size:
            U = self.frames.to_cartesian(U)
        return torch.from_numpy(U).to(E.device)

    def _upper(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The upper triangle of :meth:`stiffness`'s pattern: ``(entries, indices, indptr)``, its
        entries' positions in the full pattern's data and its own CSR arrays."""
        if self._upper_pattern is None:
            _, _, indices, indptr, _ = self._sparsity()
            rows = np.repeat(np.arange(indptr.size - 1), np.diff(indptr))
            entries = np.flatnonzero(indices >= rows)  # row by row, columns sorted: a CSR order
            counts = np.bincount(rows[entries], minlength=indptr.size - 1)
            self._upper_pattern = (entries, indices[entries], np.concatenate([[0], np.cumsum(counts)]))
        return self._upper_pattern

    def _sparse_solver(self, F: np.ndarray):
        """``(moduli (n_elements,), worker) -> u (nf, L)``, the free-dof loads ``F`` ``(nf, L)``:
        PARDISO's Cholesky where it is installed (one factoriser per worker thread, kept for the
        solver's life; then one step of iterative refinement), SuperLU otherwise."""
        if not pardiso_available():
            def solve_superlu(moduli: np.ndarray, worker: int) -> np.ndarray:
                return spla.splu(self.stiffness(moduli).tocsc(), permc_spec="MMD_AT_PLUS_A").solve(F)

            return solve_superlu
        entries, indices, indptr = self._upper()

        def solve_pardiso(moduli: np.ndarray, worker: int) -> np.ndarray:
            K = self.stiffness(moduli)
            chol = self._factorisers.get(worker)
            if chol is None:
                chol = self._factorisers[worker] = PardisoCholesky(indices, indptr)
            chol.factor(K.data[entries])
            x = chol.solve(F)
            x += chol.solve(F - K @ x)
            return x

        return solve_pardiso

    def band_layout(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """The 2D direct method's band: ``(order, slots, upper, w)``.

        ``order`` ``(nf,)``: position ``i`` of the band holds the free degree of freedom
        ``order[i]`` (an index into :attr:`free`), the nodes taken with the grid's axes from the
        longest (slowest) to the shortest (fastest), so that two degrees of freedom of one element
        are at most one row of nodes along the shortest axis apart. ``upper`` ``(n_upper,)``: the
        entries of the CSR pattern of :meth:`stiffness` whose row comes at or before their column
        in that order; ``slots`` ``(n_upper,)``: their flat indices into LAPACK's upper band storage
        (``ab[w + i - j, j]``, ``(w + 1, nf)`` in Fortran order). ``w``: the half-bandwidth."""
        if self._band is None:
            g = self.grid
            axes = sorted(range(g.dim), key=lambda a: -g.node_shape[a])  # slowest first
            idx = np.indices(g.node_shape).reshape(g.dim, -1)
            rank = np.empty(g.n_nodes, dtype=np.int64)
            rank[np.lexsort(tuple(idx[a] for a in reversed(axes)))] = np.arange(g.n_nodes)  # lexsort: last key slowest
            dof_rank = (g.dim * rank[:, None] + np.arange(g.dim)).reshape(-1)  # (n_dofs,)
            order = np.argsort(dof_rank[self.free], kind="stable")
            position = np.empty(order.size, dtype=np.int64)
            position[order] = np.arange(order.size)
            _, _, indices, indptr, _ = self._sparsity()
            rows = position[np.repeat(np.arange(order.size), np.diff(indptr))]
            cols = position[indices]
            w = int(np.abs(rows - cols).max())
            upper = np.flatnonzero(rows <= cols)
            slots = (w + rows[upper] - cols[upper]) + (w + 1) * cols[upper]
            self._band = (order, slots, upper, w)
        return self._band

    def _band_solver(self, F: np.ndarray):
        """``(moduli (n_elements,), worker) -> u (nf, L)``: LAPACK's band Cholesky in the order of
        :meth:`band_layout`, then one step of iterative refinement; ``F`` ``(nf, L)`` the free-dof
        loads."""
        order, slots, upper, w = self.band_layout()
        Fb = F[order]

        def solve_one(moduli: np.ndarray, worker: int) -> np.ndarray:
            K = self.stiffness(moduli)
            ab = np.zeros((w + 1, order.size), order="F")
            ab.reshape(-1, order="F")[slots] = K.data[upper]
            cf, info = band.factor(ab)
            if info != 0:
                raise RuntimeError(f"ElasticitySolver: the stiffness is not positive definite (LAPACK dpbtrf info {info})")
            x = np.empty_like(F)
            x[order] = band.solve(cf, Fb)
            x[order] += band.solve(cf, (F - K @ x)[order])
            return x

        return solve_one

    def _torch_data(self, device: torch.device) -> _DeviceData:
        key = str(device)
        if key not in self._torch_cache:
            clamped = self._clamped()
            self._torch_cache[key] = _DeviceData(
                K0=torch.as_tensor(self.K0, device=device),
                edof=torch.as_tensor(self.grid.element_dofs, device=device),
                free=torch.as_tensor(~self.fixed, device=device, dtype=torch.float64),
                forces=torch.as_tensor(self.forces, device=device),
                local_forces=torch.as_tensor(self.local_forces, device=device),
                active=torch.as_tensor(np.flatnonzero(self.active), device=device),
                active_mask=torch.as_tensor(self.active, device=device),
                solved=torch.as_tensor(~self.held, device=device, dtype=torch.float64),
                active_edof=torch.as_tensor(self.grid.element_dofs[self.active], device=device),
                clamped=torch.as_tensor(~clamped, device=device, dtype=torch.float64),
                framed=torch.as_tensor(clamped & ~self.held, device=device, dtype=torch.float64),
            )
        return self._torch_cache[key]

    def _clamped(self) -> np.ndarray:
        """``(n_dofs,)`` bool: :attr:`held` and every degree of freedom of a framed node (the
        multigrid preconditioner's held set: its hierarchy is Cartesian)."""
        out = self.held.copy()
        out.reshape(-1, self.grid.dim)[self.frames.nodes] = True
        return out

    def apply(self, moduli: torch.Tensor, U: torch.Tensor) -> torch.Tensor:
        """``K(E) u`` of the CG methods, matrix-free, for moduli ``(B, n_elements)`` and displacements
        ``(B, L, n_dofs)`` (float64) in the nodes' frames (Cartesian where no node has a normal):
        the active elements only, the rows and columns of :attr:`held` degrees of freedom removed
        (zero there)."""
        d = self._torch_data(U.device)
        U = U * d.solved
        if self.frames.nodes.size:
            return self.frames.to_local(self._apply_cartesian(moduli, self.frames.to_cartesian(U), d)) * d.solved
        return self._apply_cartesian(moduli, U, d) * d.solved

    def _apply_cartesian(self, moduli: torch.Tensor, U: torch.Tensor, d: _DeviceData) -> torch.Tensor:
        Ue = U[:, :, d.active_edof]  # (B, L, n_active, k)
        Fe = torch.matmul(Ue, d.K0) * moduli[:, d.active][:, None, :, None]
        out = torch.zeros_like(U)
        out.index_add_(2, d.active_edof.reshape(-1), Fe.reshape(*Fe.shape[:2], -1))
        return out

    def _apply_clamped(self, moduli: torch.Tensor, U: torch.Tensor) -> torch.Tensor:
        """The multigrid's element-grid operator: Cartesian, the framed nodes held (:meth:`_clamped`)."""
        d = self._torch_data(U.device)
        return self._apply_cartesian(moduli, U * d.clamped, d) * d.clamped

    def multigrid(self) -> Multigrid:
        """The geometric multigrid hierarchy of the grid and its fixed degrees of freedom (Cartesian:
        every degree of freedom of a node with a frame of its own held, :meth:`_clamped`)."""
        if self._mg is None:
            self._mg = Multigrid(self.grid, self.K0, self._clamped(), self.active)
        return self._mg

    def _diagonal(self, E: torch.Tensor) -> torch.Tensor:
        """``(B, n_dofs)`` the diagonal of ``K(E)`` in the nodes' frames."""
        d = self._torch_data(E.device)
        B = E.shape[0]
        diag = torch.zeros(B, self.grid.n_dofs, dtype=torch.float64, device=E.device)
        diag.index_add_(1, d.edof.reshape(-1), (E[:, :, None] * torch.diagonal(d.K0)[None, None, :]).reshape(B, -1))
        if self.frames.elements.size:
            el = torch.as_tensor(self.frames.elements, device=E.device)
            turned = torch.as_tensor(np.diagonal(self.frames.K0, axis1=1, axis2=2) - np.diag(self.K0)[None], device=E.device)
            diag.index_add_(1, d.edof[el].reshape(-1), (E[:, el, None] * turned[None]).reshape(B, -1))
        return diag

    def _solve_cg(self, E: torch.Tensor, multigrid: bool) -> torch.Tensor:
        d = self._torch_data(E.device)
        forces, free = d.local_forces, d.solved
        B, L, n = E.shape[0], self.n_loads, self.grid.n_dofs
        tiny = torch.finfo(torch.float64).tiny
        E = torch.where(torch.as_tensor(self.active, device=E.device), E, 0.0)
        if multigrid and not self.frames.nodes.size:
            precondition = self.multigrid().hierarchy(E, lambda U: self.apply(E, U)).precondition
            every = 1
        elif multigrid:
            # the cycle of the problem with the framed nodes held, and Jacobi on the framed nodes'
            # free degrees of freedom: the sum is symmetric positive definite on the solved ones
            cycle = self.multigrid().hierarchy(E, lambda U: self._apply_clamped(E, U)).precondition
            jacobi = (d.framed / self._diagonal(E).clamp_min(tiny))[:, None, :]

            def precondition(r: torch.Tensor) -> torch.Tensor:
                return cycle(r * d.clamped) * d.clamped + jacobi * r

            every = 1
        else:
            diag = self._diagonal(E)
            inv = torch.where(free > 0, 1.0 / diag.clamp_min(tiny), 0.0)[:, None, :]

            def precondition(r: torch.Tensor) -> torch.Tensor:
                return inv * r

            every = 10
        f = (forces * free).expand(B, L, n)
        x = self._warm.get(("cg", B, str(E.device)))
        x = torch.zeros_like(f) if x is None else x.clone()
        r = f - self.apply(E, x)
        fnorm = f.norm(dim=-1, keepdim=True).clamp_min(tiny)
        self.iterations = 0
        if bool(torch.all(r.norm(dim=-1, keepdim=True) <= self.rtol * fnorm)):
            return self.frames.to_cartesian(x) if self.frames.nodes.size else x
        z = precondition(r)
        p = z.clone()
        rz = (r * z).sum(-1, keepdim=True)
        for it in range(self.max_iter):
            Ap = self.apply(E, p)
            alpha = rz / (p * Ap).sum(-1, keepdim=True).clamp_min(tiny)
            x = x + alpha * p
            r = r - alpha * Ap
            if it % every == every - 1 and bool(torch.all(r.norm(dim=-1, keepdim=True) <= self.rtol * fnorm)):
                break
            z = precondition(r)
            rz_new = (r * z).sum(-1, keepdim=True)
            p = z + (rz_new / rz.clamp_min(tiny)) * p
            rz = rz_new
        else:
            worst = float((r.norm(dim=-1, keepdim=True) / fnorm).max())
            raise RuntimeError(f"ElasticitySolver: CG reached {self.max_iter} iterations at relative residual {worst:.2e}")
        self.iterations = it + 1
        self._warm[("cg", B, str(E.device))] = x
        return self.frames.to_cartesian(x) if self.frames.nodes.size else x

    def warm_state(self) -> dict[str, torch.Tensor]:
        """CG's warm starts (``{batch size: displacements}``), for a checkpoint: a resumed run then
        solves from the same start and repeats the uninterrupted one bit for bit."""
        return {str(key[1]): x.detach().cpu() for key, x in self._warm.items() if key[0] == "cg"}

    def load_warm_state(self, state: dict[str, torch.Tensor], device: torch.device) -> None:
        """Restore :meth:`warm_state` onto ``device``."""
        self._warm = {("cg", int(b), str(device)): x.to(device) for b, x in state.items()}

    # --- quantities of a solution ---------------------------------------------------------------

    def element_energy(self, U: torch.Tensor) -> torch.Tensor:
        """``u_e^T K0 u_e`` ``(B, L, n_elements)`` of displacements ``(B, L, n_dofs)``: twice the strain
        energy of each element at unit modulus (zero at the elements left out)."""
        d = self._torch_data(U.device)
        Ue = U[:, :, d.edof]
        energy = (torch.matmul(Ue, d.K0) * Ue).sum(-1)
        if d.active.numel() < self.grid.n_elements:
            energy = torch.where(d.active_mask, energy, 0.0)
        return energy

    def work(self, U: torch.Tensor) -> torch.Tensor:
        """``f^T u`` ``(B, L)``: the compliance of each shape and load case."""
        d = self._torch_data(U.device)
        return ((d.forces * d.free)[None] * U).sum(-1)
