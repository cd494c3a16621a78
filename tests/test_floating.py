"""The floating pieces' rigid motions (``ginn.physics.floating``): which pieces float, their coarse
operator against the Galerkin product ``Z^T A Z``, and the CG iterations they save."""

import numpy as np
import pytest
import torch

from ginn.physics import ElasticitySolver, ElementGrid, FloatingModes, Multigrid


def _solver(g, method="cg"):
    """Clamped at x = 0, pulled down at the middle of the far end."""
    d = g.dim
    x = g.nodes
    fixed = np.zeros((g.n_nodes, d), bool)
    fixed[np.isclose(x[:, 0], 0.0)] = True
    F = np.zeros((1, g.n_nodes, d))
    end = np.isclose(x[:, 0], g.hi[0]) & np.all(np.abs(x[:, 1:] - 0.5) < 0.15, axis=1)
    F[0, end, 1] = -1.0 / end.sum()
    return ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(1, -1), method=method)


def _design(g, blocks):
    """A bar along x through the middle (the two middle elements along every other axis), clamped
    and loaded, and solid ``blocks`` (slices of the element grid) in void 1e-6."""
    solid = np.zeros(g.shape, bool)
    solid[(slice(None),) + tuple(slice(n // 2 - 1, n // 2 + 1) for n in g.shape[1:])] = True
    for block in blocks:
        solid[block] = True
    return torch.tensor(np.where(solid, 1.0, 1e-6).reshape(-1))[None]


def test_the_pieces_are_the_face_connected_solid_parts_without_a_support():
    """On 12 x 10 elements of 0.1 (the bar: rows 4 and 5): a block apart from the bar, one touching
    it at a corner only (a hinge: a piece of its own) and one sharing a face with it (part of the
    bar's piece)."""
    g = ElementGrid((0.0, 0.0), (1.2, 1.0), (12, 10))
    assert np.flatnonzero(_design(g, [])[0].reshape(12, 10)[0] == 1).tolist() == [4, 5]
    blocks = [np.s_[1:4, 0:2],  # apart
              np.s_[2:4, 6:8],  # above the bar, sharing faces with it
              np.s_[4:6, 8:10],  # its corner (4, 8) meets the last block's (3, 7) only
              np.s_[9:11, 0:4]]  # under the bar, sharing faces with it
    s = _solver(g)
    E = _design(g, blocks)
    fm = FloatingModes(g, s.K0, s.fixed, E)
    assert fm.n_pieces.tolist() == [2] and fm.G == 2 and fm.m == 3
    only_bar = FloatingModes(g, s.K0, s.fixed, _design(g, blocks[1:2] + blocks[3:]))
    assert only_bar.G == 0 and only_bar.n_pieces.tolist() == [0]
    # the largest pieces first where the coarse space is limited
    assert FloatingModes(g, s.K0, s.fixed, E, limit=3).n_pieces.tolist() == [1]


@pytest.mark.parametrize("shape", [(12, 10), (8, 6, 6)])
def test_the_coarse_operator_is_the_galerkin_product_and_the_modes_are_rigid(shape):
    d = len(shape)
    g = ElementGrid((0.0,) * d, (1.2, 1.0, 1.0)[:d], shape)
    blocks = [(slice(1, 4),) + (slice(0, 1),) * (d - 1), (slice(5, 8),) + (slice(-1, None),) * (d - 1)]
    s = _solver(g)
    E = _design(g, blocks) * torch.tensor(np.random.default_rng(0).uniform(0.5, 1.0, g.n_elements))
    fm = FloatingModes(g, s.K0, s.fixed, E)
    assert fm.G >= 2
    Z = fm.basis(g.n_dofs)  # (1, G m, n)
    AZ = s.apply(E, Z)
    Ac = torch.einsum("bin,bjn->bij", Z, AZ)
    stored = fm.chol @ fm.chol.transpose(1, 2)
    # to the round-off of the solid's stiffness (1e-15 of it: the operator applied to Z sums the
    # pieces' own elements, whose rigid motions the assembly leaves out as exactly unstrained)
    assert float(Ac.abs().max()) > 1e-7
    assert torch.allclose(stored, Ac, rtol=1e-9, atol=1e-13 * float(E.max()))
    # a piece's modes strain only the void around it: its energy is the void's share
    solid_only = torch.where(E >= 0.5, E, 0.0)
    assert float(torch.einsum("bin,bin->bi", Z, s.apply(solid_only, Z)).abs().max()) <= 1e-10


def test_the_balanced_cycle_is_symmetric_positive_definite():
    g = ElementGrid((0.0, 0.0, 0.0), (1.2, 1.0, 1.0), (10, 8, 8))
    s = _solver(g)
    E = _design(g, [np.s_[1:4, 0:2, 0:2], np.s_[6:9, 6:8, 5:8]])
    H = s.multigrid().hierarchy(E, lambda U: s.apply(E, U))
    assert H.modes.G == 2
    R = torch.randn(1, 8, g.n_dofs, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    R = R * torch.as_tensor(~s.held, dtype=torch.float64)
    M = H.precondition(R)
    G = torch.einsum("bin,bjn->bij", R, M)[0]
    assert torch.allclose(G, G.T, rtol=0, atol=1e-10 * float(G.abs().max()))
    assert float(torch.linalg.eigvalsh(0.5 * (G + G.T)).min()) > 0


def test_the_rigid_modes_save_most_of_cg_s_iterations():
    """A clamped bar and four blocks floating in void 1e-6 (16 x 8 x 8): CG with the balanced cycle
    reaches the direct solve in a third of the plain cycle's iterations or fewer (measured 38 vs
    212 on 24 x 12 x 12)."""
    g = ElementGrid((0.0, 0.0, 0.0), (2.0, 1.0, 1.0), (16, 8, 8))
    blocks = [np.s_[2:4, 0:2, 0:2], np.s_[6:9, 6:8, 0:2], np.s_[10:13, 0:2, 6:8], np.s_[2:5, 6:8, 6:8]]
    E = _design(g, blocks)
    U = _solver(g, "direct").solve(E)
    with_modes = _solver(g)
    V = with_modes.solve(E)
    plain = _solver(g)
    plain._mg = Multigrid(g, plain.K0, plain.held, plain.active, floating=False)
    W = plain.solve(E)
    for X in (V, W):
        assert (X - U).abs().max() <= 1e-7 * U.abs().max()
    assert with_modes.iterations * 3 <= plain.iterations
