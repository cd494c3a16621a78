"""The 3D direct method on MKL's PARDISO: the same displacements as SuperLU and CG, the same bits on
any thread count, and the choice ``auto`` makes with it."""

import numpy as np
import pytest
import scipy.sparse as sp
import torch

import ginn.physics.solve as solve_module
from ginn.physics import ElasticitySolver, ElementGrid
from ginn.physics.pardiso import PardisoCholesky, available

pytest.importorskip("pypardiso")


def _bar(shape=(10, 6, 5), loads=2, seed=0):
    """A box clamped at x = 0, ``loads`` load cases at its far end, a solid/void design (void 1e-6)
    for three shapes, the elements of a slot through it left out."""
    g = ElementGrid((0.0, 0.0, 0.0), (2.0, 1.0, 0.8), shape)
    x = g.nodes
    fixed = np.zeros((g.n_nodes, 3), bool)
    fixed[np.isclose(x[:, 0], 0.0)] = True
    end = np.isclose(x[:, 0], 2.0)
    F = np.zeros((loads, g.n_nodes, 3))
    for l in range(loads):
        F[l, end, 1 + l % 2] = -1.0 / end.sum()
    c = g.centres
    active = ~((np.abs(c[:, 1] - 0.5) < 0.15) & (c[:, 0] > 0.5) & (c[:, 0] < 1.2))  # a slot out of the box
    rng = np.random.default_rng(seed)
    E = np.where(rng.uniform(size=(3, g.n_elements)) < 0.7, 1.0, 1e-6)
    E[:, c[:, 0] < 0.4] = 1.0
    return g, fixed.reshape(-1), F.reshape(loads, -1), active, torch.tensor(E)


def test_cholesky_matches_the_dense_solve_for_each_matrix_of_a_pattern():
    """One factoriser, two matrices of one pattern (the second twice): each solve is the dense
    solve's to 1e-12."""
    rng = np.random.default_rng(3)
    mask = rng.uniform(size=(40, 40)) < 0.2
    mask = mask | mask.T | np.eye(40, dtype=bool)
    upper = sp.triu(sp.csr_matrix(mask.astype(float))).tocsr()
    upper.sort_indices()
    chol = PardisoCholesky(upper.indices, upper.indptr)
    B = rng.standard_normal((40, 3))
    for seed in (0, 1, 0):
        values = np.random.default_rng(seed).uniform(-1.0, 1.0, upper.nnz)
        U = sp.csr_matrix((values, upper.indices, upper.indptr), shape=(40, 40)).toarray()
        A = U + U.T - np.diag(np.diag(U))
        np.fill_diagonal(A, np.abs(A).sum(1) + 1.0)  # diagonally dominant: positive definite
        chol.factor(A[upper.nonzero()])  # the upper triangle's values in CSR order
        X = chol.solve(B)
        assert np.abs(X - np.linalg.solve(A, B)).max() <= 1e-12 * np.abs(X).max()
    chol.close()


def test_pardiso_matches_superlu_and_cg(monkeypatch):
    g, fixed, F, active, E = _bar()
    pardiso = ElasticitySolver(g, 0.3, fixed, F, method="direct", active=active).solve(E)
    cg = ElasticitySolver(g, 0.3, fixed, F, method="cg", active=active).solve(E)
    monkeypatch.setattr(solve_module, "pardiso_available", lambda: False)
    superlu = ElasticitySolver(g, 0.3, fixed, F, method="direct", active=active).solve(E)
    scale = pardiso.abs().max()
    assert (pardiso - superlu).abs().max() <= 1e-9 * scale
    assert (pardiso - cg).abs().max() <= 1e-7 * scale
    assert torch.all(pardiso[..., ~np.isin(np.arange(g.n_dofs), _solved(g, fixed, active))] == 0)


def _solved(g, fixed, active):
    touched = np.zeros(g.n_dofs, bool)
    touched[g.element_dofs[active].reshape(-1)] = True
    return np.flatnonzero(touched & ~fixed)


def test_a_shape_solves_to_the_same_bits_on_one_thread_and_two():
    g, fixed, F, active, E = _bar()
    s = ElasticitySolver(g, 0.3, fixed, F, method="direct", active=active)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        one = s.solve(E)
        torch.set_num_threads(2)
        two = s.solve(E)
    finally:
        torch.set_num_threads(before)
    assert torch.equal(one, two)


def test_auto_keeps_cg_in_3d_without_pardiso(monkeypatch):
    """Without PARDISO ``auto`` does not factorise in 3D: SuperLU took 18 s for each of the
    bracket's four factorisations, 72 s a step against CG's 63 s for its 16 systems."""
    g, fixed, F, active, _ = _bar()
    monkeypatch.setattr(solve_module, "pardiso_available", lambda: False)
    assert ElasticitySolver(g, 0.3, fixed, F, active=active).resolved_method(torch.device("cpu")) == "cg"


def test_auto_factorises_where_a_factor_serves_several_load_cases():
    cpu, gpu = torch.device("cpu"), torch.device("cuda")
    g, fixed, F, active, _ = _bar()
    several = ElasticitySolver(g, 0.3, fixed, F, active=active)
    one = ElasticitySolver(g, 0.3, fixed, F[:1], active=active)
    assert available()
    assert several.resolved_method(cpu) == "direct" and several.resolved_method(gpu) == "cg"
    assert one.resolved_method(cpu) == "cg"
    g2 = ElementGrid((0.0, 0.0), (2.0, 1.0), (8, 4))
    fixed2 = np.zeros(g2.n_dofs, bool)
    fixed2[:2] = True
    assert ElasticitySolver(g2, 0.3, fixed2, np.ones((1, g2.n_dofs))).resolved_method(cpu) == "direct"
