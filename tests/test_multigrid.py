"""The geometric multigrid preconditioner of the CG method (``ginn.physics.multigrid``): its
interpolation, its Galerkin coarse operators against the assembled product ``P^T A P``, the
symmetry and positivity CG needs of a V-cycle, and the CG solves against the direct method,
with and without elements left out."""

import numpy as np
import pytest
import torch

from ginn.physics import ElasticitySolver, ElementGrid, compliance
from ginn.physics.multigrid import Multigrid, interpolation_1d


def _case(shape, method="cg", active=None, contrast=True, seed=0):
    """A box clamped at x = 0 and pulled down at the far end, with a random solid/void design
    (void 1e-6) or random moduli in (0.1, 1)."""
    d = len(shape)
    g = ElementGrid((0.0,) * d, (2.0, 1.0, 0.7)[:d], shape)
    x = g.nodes
    fixed = np.zeros((g.n_nodes, d), bool)
    fixed[np.isclose(x[:, 0], 0.0)] = True
    F = np.zeros((2, g.n_nodes, d))
    end = np.isclose(x[:, 0], 2.0)
    F[0, end, 1] = -1.0 / end.sum()
    F[1, end, 0] = 1.0 / end.sum()
    rng = np.random.default_rng(seed)
    if contrast:
        c = g.centres
        solid = (np.abs(c[:, 1] - 0.5) < 0.2) | (np.abs(c[:, 1] - c[:, 0] / 2) < 0.15) | (c[:, 0] < 0.3)
        E = np.where(solid, 1.0, 1e-6) * rng.uniform(0.8, 1.0, g.n_elements)
    else:
        E = rng.uniform(0.1, 1.0, g.n_elements)
    s = ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(2, -1), method=method, active=active)
    return g, s, torch.tensor(E)[None]


@pytest.mark.parametrize("n", [1, 2, 5, 8])
def test_interpolation_reproduces_linear_functions(n):
    P = interpolation_1d(n)
    nc = P.shape[1] - 1
    assert nc == -(-n // 2)
    coarse = 2.0 * np.arange(nc + 1)  # coarse node j at fine coordinate 2 j
    assert np.allclose(P @ (3.0 + 0.5 * coarse), 3.0 + 0.5 * np.arange(n + 1))
    assert np.allclose(P.sum(axis=1), 1.0)


def _assembled(g, mats, fixed=None):
    """The dense matrix of element matrices ``mats`` ``(ne, k, k)`` on grid ``g`` (masked by ``fixed``)."""
    n = g.n_dofs
    A = np.zeros((n, n))
    for e in range(g.n_elements):
        dofs = g.element_dofs[e]
        A[np.ix_(dofs, dofs)] += mats[e]
    if fixed is not None:
        A[fixed] = 0.0
        A[:, fixed] = 0.0
    return A


def _prolongation(g):
    Ps = [interpolation_1d(n) for n in g.shape]
    P = Ps[0]
    for Pa in Ps[1:]:
        P = np.kron(P, Pa)  # C order: the last axis fastest
    return np.kron(P, np.eye(g.dim))


@pytest.mark.parametrize("shape", [(9, 6), (5, 4, 3)])
def test_coarse_operators_are_the_galerkin_products(shape):
    """Every coarse level's element matrices assemble to ``P^T A P`` of the level below, the fixed
    degrees of freedom and the elements left out of the finest removed, on grids with odd counts."""
    d = len(shape)
    g = ElementGrid((0.0,) * d, (1.0,) * d, shape)
    rng = np.random.default_rng(1)
    fixed = np.zeros((g.n_nodes, d), bool)
    fixed[np.isclose(g.nodes[:, 0], 0.0)] = True
    fixed[np.isclose(g.nodes[:, 1], 1.0), 0] = True  # rollers on one face
    active = rng.uniform(size=g.n_elements) > 0.25
    E = torch.tensor(np.where(active, rng.uniform(1e-3, 1.0, g.n_elements), 0.0))[None]
    s = ElasticitySolver(g, 0.3, fixed.reshape(-1), np.zeros((1, g.n_dofs)), method="cg", active=active)
    mg = Multigrid(g, s.K0, s.held, active, coarsest=20)
    H = mg.hierarchy(E, lambda U: s.apply(E, U))
    assert mg.n_levels >= 3
    A = _assembled(g, E[0].numpy()[:, None, None] * s.K0, s.held)
    for li in range(1, mg.n_levels):
        P = _prolongation(mg.grids[li - 1])
        A = P.T @ A @ P
        Ah = _assembled(mg.grids[li], H.mats[li][0].numpy())
        assert np.abs(Ah - A).max() <= 1e-12 * np.abs(A).max()


def test_v_cycle_is_symmetric_positive_definite():
    g, s, E = _case((12, 7, 5))
    E = torch.where(torch.as_tensor(s.active), E, 0.0)
    H = s.multigrid().hierarchy(E, lambda U: s.apply(E, U))
    free = torch.as_tensor(~s.held, dtype=torch.float64)
    rng = torch.Generator().manual_seed(0)
    R = torch.randn(1, 6, g.n_dofs, generator=rng, dtype=torch.float64) * free
    Z = H.precondition(R)
    assert torch.all(Z[..., s.held] == 0)
    G = torch.einsum("bin,bjn->bij", R, Z)[0]  # <r_i, M r_j>
    assert torch.allclose(G, G.T, rtol=0, atol=1e-12 * G.abs().max())
    assert float(torch.linalg.eigvalsh(0.5 * (G + G.T)).min()) > 0


@pytest.mark.parametrize("shape", [(40, 20), (16, 8, 6)])
def test_multigrid_cg_matches_the_direct_solve_in_few_iterations(shape):
    """Solid members in void 1e-6 times as stiff: CG with the V-cycle reaches the direct solve's
    displacements in a fraction of the diagonal preconditioner's iterations, and stops at once from
    its own solution."""
    g, direct, E = _case(shape, method="direct")
    U = direct.solve(E)
    _, mg, _ = _case(shape)
    _, diag, _ = _case(shape, method="cg-diagonal")
    V, W = mg.solve(E), diag.solve(E)
    for X in (V, W):
        assert (X - U).abs().max() <= 1e-7 * U.abs().max()
    assert mg.iterations <= 60 and diag.iterations >= 5 * mg.iterations
    mg.solve(E)
    assert mg.iterations == 0


def test_elements_left_out_change_the_compliance_by_the_ersatz_share():
    """Every method leaves the inactive elements out: against the direct solve with them at the
    weak ersatz (1e-6), the compliance agrees to 1e-5, their energies are zero, and the direct and
    CG solves of the same active set agree to 1e-9."""
    shape = (14, 8, 5)
    g, _, E = _case(shape, contrast=False)
    c = g.centres
    active = ~((c[:, 1] > 0.7) & (c[:, 0] > 0.6) & (c[:, 0] < 1.4))  # a notch out of the box
    E = torch.where(torch.as_tensor(active), E, 1e-6)
    _, ersatz, _ = _case(shape, method="direct")
    _, direct, _ = _case(shape, method="direct", active=active)
    _, cg, _ = _case(shape, active=active)
    ce, _ = compliance(E, ersatz)
    cd, sold = compliance(E, direct)
    cc, sol = compliance(E, cg)
    assert torch.allclose(cc, ce, rtol=1e-5) and not torch.allclose(cc, ce, rtol=1e-12)
    assert torch.allclose(cc, cd, rtol=1e-9)
    for s in (sol, sold):
        assert torch.all(s.energy[..., ~active] == 0)
    held = cg.held.reshape(-1, 3).all(axis=1) & ~cg.fixed.reshape(-1, 3).any(axis=1)
    assert held.sum() > 0  # nodes inside the notch are held, not solved


def test_a_load_on_a_node_with_no_active_element_is_refused():
    g = ElementGrid((0.0, 0.0), (2.0, 1.0), (4, 2))
    fixed = np.zeros(g.n_dofs, bool)
    fixed[:2] = True
    F = np.zeros((1, g.n_dofs))
    F[0, -1] = 1.0  # the far corner node, whose one element is left out
    active = np.ones(g.n_elements, bool)
    active[-1] = False
    with pytest.raises(ValueError, match="no active element"):
        ElasticitySolver(g, 0.3, fixed, F, method="cg", active=active)
