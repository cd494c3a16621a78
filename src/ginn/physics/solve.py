"""Linear elasticity on an :class:`~ginn.physics.grid.ElementGrid`: the stiffness of every shape of a
batch from its element moduli, solved for every load case.

``K(E) = sum_e E_e K0_e`` with ``K0`` the unit-modulus element matrix
(:func:`~ginn.physics.elements.element_stiffness`), the same for every element of the grid. The
fixed degrees of freedom are removed (zero displacement there); a load case is a vector of nodal
forces. Two methods solve ``K u = f``:

* ``direct``: the assembled sparse matrix of the free degrees of freedom (one scatter of the element
  matrices into a precomputed CSR pattern), factorised once per shape and solved for every load
  case; the shapes of a batch on as many threads as torch uses (the factorisations release the
  GIL; each shape's solve is the same on any count). In 2D the factoriser is QDLDL (``qdldl``:
  ``L D L^T`` of the symmetric positive definite matrix, its approximate-minimum-degree ordering
  and symbolic analysis done once per thread, since every shape has the grid's pattern, then one
  step of iterative refinement); in 3D, where its fill is larger, SciPy's SuperLU (minimum-degree
  ordering of ``A^T + A``);
* ``cg``: matrix-free conjugate gradients in torch, preconditioned by the diagonal, every shape and
  load case of the batch in one set of tensor operations on the moduli's device, warm-started from
  the previous solve of a batch of the same size.

``auto`` picks ``direct`` for 2D grids on the CPU and ``cg`` for 3D grids and on accelerators
(``docs/structural.md``, "The solver", has the measurements).

Public names: :class:`ElasticitySolver`, :data:`METHODS`.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import qdldl
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import torch

from .elements import element_stiffness
from .grid import ElementGrid

__all__ = ["ElasticitySolver", "METHODS"]

METHODS = ("auto", "direct", "cg")


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
    """

    def __init__(self, grid: ElementGrid, nu: float, fixed: np.ndarray, forces: np.ndarray, *,
                 method: str = "auto", rtol: float = 1e-10, max_iter: int = 20_000) -> None:
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
        self.K0 = element_stiffness(grid.h, nu)  # (k, k)
        self.fixed = fixed
        self.free = np.flatnonzero(~fixed)
        self.forces = forces
        self._pattern: tuple | None = None
        self._warm: dict = {}
        self._torch_cache: dict = {}
        self._ldl: dict[int, qdldl.Solver] = {}  # the direct method's QDLDL solvers, one per thread

    @property
    def n_loads(self) -> int:
        return self.forces.shape[0]

    def resolved_method(self, device: torch.device) -> str:
        if self.method != "auto":
            return self.method
        return "direct" if device.type == "cpu" and self.grid.dim == 2 else "cg"

    # --- assembly -------------------------------------------------------------------------------

    def _sparsity(self) -> tuple:
        """The CSR pattern of the free-dof matrix and, per kept (element, a, b) entry, its slot."""
        if self._pattern is None:
            g = self.grid
            k = self.K0.shape[0]
            index = np.full(g.n_dofs, -1, dtype=np.int64)
            index[self.free] = np.arange(self.free.size)
            edof = index[g.element_dofs]  # (ne, k)
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
        vals = (np.asarray(moduli, dtype=np.float64)[:, None] * self.K0.reshape(1, -1)).reshape(-1)[keep]
        data = np.bincount(slot, weights=vals, minlength=nnz)
        n = self.free.size
        return sp.csr_matrix((data, indices, indptr), shape=(n, n))

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
        if method == "cg":
            return self._solve_cg(E.to(torch.float64))
        En = E.to(torch.float64).cpu().numpy()
        U = np.zeros((En.shape[0], self.n_loads, self.grid.n_dofs))
        F = self.forces[:, self.free]  # (L, nf)

        workers = min(En.shape[0], torch.get_num_threads())
        chunks = np.array_split(np.arange(En.shape[0]), workers)

        def run(k: int) -> None:  # chunk k of the shapes, with QDLDL solver k
            for b in chunks[k]:
                if self.grid.dim == 3:
                    lu = spla.splu(self.stiffness(En[b]).tocsc(), permc_spec="MMD_AT_PLUS_A")
                    U[b][:, self.free] = lu.solve(np.ascontiguousarray(F.T)).T
                    continue
                ldl, K = self._factorised(k, En[b])
                for c in range(self.n_loads):
                    u = ldl.solve(F[c])
                    U[b, c, self.free] = u + ldl.solve(F[c] - K @ u)  # one step of iterative refinement

        if workers > 1:  # the factorisations release the GIL and run side by side
            with ThreadPoolExecutor(workers) as pool:
                list(pool.map(run, range(workers)))
        else:
            run(0)
        return torch.from_numpy(U).to(E.device)

    def _factorised(self, slot: int, moduli: np.ndarray) -> tuple[qdldl.Solver, sp.csr_matrix]:
        """QDLDL solver ``slot`` holding the factorisation of the stiffness of ``moduli`` (its
        symbolic analysis from the first matrix, kept for every later one: the pattern is the
        grid's), and the stiffness."""
        K = self.stiffness(moduli)
        A = sp.csc_matrix((K.data, K.indices, K.indptr), shape=K.shape)  # K is symmetric: its CSR is its CSC
        ldl = self._ldl.get(slot)
        if ldl is None:
            self._ldl[slot] = ldl = qdldl.Solver(A)
        else:
            ldl.update(A)
        return ldl, K

    def _torch_data(self, device: torch.device) -> tuple[torch.Tensor, ...]:
        key = str(device)
        if key not in self._torch_cache:
            self._torch_cache[key] = (
                torch.as_tensor(self.K0, device=device),
                torch.as_tensor(self.grid.element_dofs, device=device),
                torch.as_tensor(~self.fixed, device=device, dtype=torch.float64),
                torch.as_tensor(self.forces, device=device),
            )
        return self._torch_cache[key]

    def apply(self, moduli: torch.Tensor, U: torch.Tensor) -> torch.Tensor:
        """``K(E) u`` matrix-free for moduli ``(B, n_elements)`` and displacements ``(B, L, n_dofs)``
        (float64), the fixed rows and columns removed (zero there)."""
        K0, edof, free, _ = self._torch_data(U.device)
        U = U * free
        Ue = U[:, :, edof]  # (B, L, ne, k)
        Fe = torch.matmul(Ue, K0) * moduli[:, None, :, None]
        out = torch.zeros_like(U)
        out.index_add_(2, edof.reshape(-1), Fe.reshape(*Fe.shape[:2], -1))
        return out * free

    def _solve_cg(self, E: torch.Tensor) -> torch.Tensor:
        K0, edof, free, forces = self._torch_data(E.device)
        B, L, n = E.shape[0], self.n_loads, self.grid.n_dofs
        diag = torch.zeros(B, n, dtype=torch.float64, device=E.device)
        diag.index_add_(1, edof.reshape(-1), (E[:, :, None] * torch.diagonal(K0)[None, None, :]).reshape(B, -1))
        inv = torch.where(free > 0, 1.0 / diag.clamp_min(torch.finfo(torch.float64).tiny), 0.0)[:, None, :]
        f = (forces * free).expand(B, L, n)
        x = self._warm.get(("cg", B, str(E.device)))
        x = torch.zeros_like(f) if x is None else x.clone()
        r = f - self.apply(E, x)
        z = inv * r
        p = z.clone()
        rz = (r * z).sum(-1, keepdim=True)
        fnorm = f.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(torch.float64).tiny)
        for it in range(self.max_iter):
            Ap = self.apply(E, p)
            alpha = rz / (p * Ap).sum(-1, keepdim=True).clamp_min(torch.finfo(torch.float64).tiny)
            x = x + alpha * p
            r = r - alpha * Ap
            if it % 10 == 9 and bool(torch.all(r.norm(dim=-1, keepdim=True) <= self.rtol * fnorm)):
                break
            z = inv * r
            rz_new = (r * z).sum(-1, keepdim=True)
            p = z + (rz_new / rz.clamp_min(torch.finfo(torch.float64).tiny)) * p
            rz = rz_new
        else:
            worst = float((r.norm(dim=-1, keepdim=True) / fnorm).max())
            raise RuntimeError(f"ElasticitySolver: CG reached {self.max_iter} iterations at relative residual {worst:.2e}")
        self._warm[("cg", B, str(E.device))] = x
        return x

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
        energy of each element at unit modulus."""
        K0, edof, _, _ = self._torch_data(U.device)
        Ue = U[:, :, edof]
        return (torch.matmul(Ue, K0) * Ue).sum(-1)

    def work(self, U: torch.Tensor) -> torch.Tensor:
        """``f^T u`` ``(B, L)``: the compliance of each shape and load case."""
        _, _, free, forces = self._torch_data(U.device)
        return ((forces * free)[None] * U).sum(-1)
