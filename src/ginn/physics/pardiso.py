"""Sparse Cholesky factorisation by Intel MKL's PARDISO (optional: ``pip install ginn[pardiso]``).

The 3D direct method of :class:`~ginn.physics.solve.ElasticitySolver` factorises each shape's
stiffness with it when :func:`available` (``pypardiso``, which loads MKL's runtime library from
the ``mkl`` wheel; x86-64 only), and with SciPy's SuperLU otherwise. PARDISO orders the unknowns by
nested dissection (METIS) and factorises supernodes with dense kernels: on the ``bracket-loads``
grid (29,205 unknowns) a factorisation took 0.45 s on one thread against SuperLU's 18 s
(``docs/structural.md``, "The solver").

A :class:`PardisoCholesky` serves every matrix of one sparsity pattern (a grid's stiffness for any
moduli): the ordering and symbolic analysis run once, each matrix is then a numeric factorisation,
and the factor's memory stays allocated between them (a fresh analysis, allocation and
factorisation per matrix took 0.98 s there). Each call runs on one MKL thread, set for the
calling thread only, so that the shapes of a batch factorise side by side on the solver's threads
and a shape's solution is the same bit for bit on any thread count (two MKL threads per
factorisation give other round-off).

Public names: :func:`available`, :class:`PardisoCholesky`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["available", "PardisoCholesky"]

_SPD = 2  # PARDISO's matrix type: real symmetric positive definite (the upper triangle is given)
_ANALYSE, _FACTOR, _SOLVE = 11, 22, 33  # PARDISO's phases


def available() -> bool:
    """Whether ``pypardiso`` imports and finds MKL's runtime library."""
    try:
        import pypardiso  # noqa: F401
    except (ImportError, OSError):
        return False
    return True


class PardisoCholesky:
    """Cholesky factors of symmetric positive definite matrices of one sparsity pattern, one
    matrix at a time.

    Arguments:
        indices, indptr: the CSR pattern of the matrices' upper triangle (diagonal included),
            ``n`` rows, columns sorted within each row.

    :meth:`factor` takes a matrix's values in that pattern, :meth:`solve` solves with the last
    one factorised. Use one object from one thread at a time; :meth:`close` (or the object's
    collection) releases MKL's memory.
    """

    def __init__(self, indices: np.ndarray, indptr: np.ndarray) -> None:
        import pypardiso

        self._solver = pypardiso.PyPardisoSolver(mtype=_SPD)
        n = indptr.size - 1
        self._matrix = sp.csr_matrix((np.ones(indices.size), indices, indptr), shape=(n, n))
        self._matrix.has_sorted_indices = True
        self._analysed = False

    def _call(self, phase: int, b: np.ndarray) -> np.ndarray:
        mkl = self._solver.libmkl
        previous = mkl.MKL_Set_Num_Threads_Local(1)  # this thread only
        try:
            self._solver.set_phase(phase)
            return self._solver._call_pardiso(self._matrix, b)
        finally:
            mkl.MKL_Set_Num_Threads_Local(previous)

    def factor(self, data: np.ndarray) -> None:
        """Factorise the matrix with values ``data`` ``(nnz,)`` in the pattern's order."""
        self._matrix.data = np.ascontiguousarray(data, dtype=np.float64)
        b = np.zeros((self._matrix.shape[0], 1), order="F")
        if not self._analysed:
            self._call(_ANALYSE, b)
            self._analysed = True
        self._call(_FACTOR, b)

    def solve(self, B: np.ndarray) -> np.ndarray:
        """``X = A^-1 B`` ``(n, L)`` for right-hand sides ``B`` ``(n, L)``, ``A`` the last matrix
        factorised."""
        return self._call(_SOLVE, np.asfortranarray(B, dtype=np.float64)).reshape(B.shape)

    def close(self) -> None:
        """Release MKL's memory of the analysis and the factor."""
        if self._solver is not None and self._analysed:
            self._solver.free_memory(everything=True)  # PARDISO's phase -1
        self._solver = None

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 -- interpreter shutdown: MKL may be gone already
            pass
