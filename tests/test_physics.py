"""The structural solver against exact solutions: element matrices, the patch test, a bar's
extension, a slender cantilever against beam theory, the compliance gradient against central
differences, the three solve methods against each other, and the SIMP reference optimiser against
the compliances Andreassen et al. (2011) publish for the half MBB beam."""

import numpy as np
import pytest
import torch

from ginn.physics import (
    DensityFilter,
    ElasticitySolver,
    ElementGrid,
    compliance,
    elasticity_matrix,
    element_stiffness,
    simp,
    strain_matrix,
)


def _solver(grid, fixed_nodes, forces, method="direct", nu=0.3, axes=None):
    fixed = np.zeros((grid.n_nodes, grid.dim), bool)
    fixed[fixed_nodes] = True if axes is None else np.isin(np.arange(grid.dim), axes)
    return ElasticitySolver(grid, nu, fixed.reshape(-1), np.asarray(forces).reshape(-1, grid.n_dofs), method=method)


def _rigid_body_modes(x):
    """``(n dim, 3 or 6)`` translations and linearised rotations at points ``x`` ``(n, dim)``."""
    n, d = x.shape
    modes = [np.tile(np.eye(d)[k], n) for k in range(d)]
    for a, b in [(0, 1)] if d == 2 else [(0, 1), (1, 2), (0, 2)]:
        m = np.zeros((n, d))
        m[:, a], m[:, b] = -x[:, b], x[:, a]
        modes.append(m.reshape(-1))
    return np.stack(modes, axis=1)


@pytest.mark.parametrize("dim", [2, 3])
def test_element_matrix_null_space_and_energy(dim):
    h = np.array([0.7, 1.3, 0.9][:dim])
    K = element_stiffness(h, 0.3)
    k = K.shape[0]
    assert np.allclose(K, K.T, atol=0)
    corners = np.array([[(c >> a) & 1 for a in range(dim)] for c in range(2**dim)]) * h
    R = _rigid_body_modes(corners)
    assert np.abs(K @ R).max() < 1e-12
    eig = np.linalg.eigvalsh(K)
    assert (eig > 1e-8).sum() == k - R.shape[1]  # positive definite away from the rigid modes
    # a linear displacement u = A x has constant strain: energy u^T K u = volume * eps^T D eps
    rng = np.random.default_rng(0)
    A = rng.normal(size=(dim, dim))
    u = (corners @ A.T).reshape(-1)
    eps = strain_matrix(h, np.full((1, dim), 0.3))[0] @ u
    if dim == 2:
        exact = np.array([A[0, 0], A[1, 1], A[0, 1] + A[1, 0]])
    else:
        exact = np.array([A[0, 0], A[1, 1], A[2, 2], A[1, 2] + A[2, 1], A[0, 2] + A[2, 0], A[0, 1] + A[1, 0]])
    assert np.allclose(eps, exact, atol=1e-13)
    assert u @ K @ u == pytest.approx(np.prod(h) * exact @ elasticity_matrix(dim, 0.3) @ exact, rel=1e-13)


@pytest.mark.parametrize("dim", [2, 3])
def test_patch_test_linear_field_exact(dim):
    """Boundary nodes displaced by a linear field: the interior nodes follow it exactly."""
    g = ElementGrid((0.0,) * dim, (2.0, 1.0, 1.5)[:dim], (5, 4, 3)[:dim])
    s = ElasticitySolver(g, 0.25, np.zeros(g.n_dofs, bool), np.zeros((1, g.n_dofs)))
    rng = np.random.default_rng(1)
    E = np.full(g.n_elements, 1.7)
    K = s.stiffness(E).tocsr()
    A, b = rng.normal(size=(dim, dim)), rng.normal(size=dim)
    u = (g.nodes @ A.T + b).reshape(-1)
    on_boundary = np.any(np.isclose(g.nodes, g.lo) | np.isclose(g.nodes, g.hi), axis=1)
    bd = np.repeat(on_boundary, dim)
    interior = np.flatnonzero(~bd)
    rhs = -K[interior][:, np.flatnonzero(bd)] @ u[bd]
    ui = np.linalg.solve(K[interior][:, interior].toarray(), rhs)
    assert np.abs(ui - u[interior]).max() < 1e-12
    assert np.abs(K @ u)[interior].max() < 1e-12  # a linear field is in equilibrium inside


@pytest.mark.parametrize("dim", [2, 3])
def test_uniform_bar_extension_exact(dim):
    """A bar pulled by a uniform traction at one end, on rollers at the other: u_x = s x / E and
    the lateral contraction -nu s y / E at every node (plane stress in 2D)."""
    E, nu, sigma = 3.0, 0.3, 0.2
    L = (4.0, 1.0, 0.5)[:dim]
    g = ElementGrid((0.0,) * dim, L, (8, 3, 2)[:dim])
    x = g.nodes
    fixed = np.zeros((g.n_nodes, dim), bool)
    fixed[np.isclose(x[:, 0], 0), 0] = True
    for a in range(1, dim):  # the lateral faces through the origin on rollers along their normals
        fixed[np.isclose(x[:, a], 0), a] = True
    end = np.isclose(x[:, 0], L[0])
    area_share = np.ones(g.n_nodes)
    for a in range(1, dim):  # consistent nodal forces of a uniform traction on the end face
        area_share *= np.where(np.isclose(x[:, a], 0) | np.isclose(x[:, a], L[a]), 0.5, 1.0) * g.h[a]
    F = np.zeros((g.n_nodes, dim))
    F[end, 0] = sigma * area_share[end]
    s = ElasticitySolver(g, nu, fixed.reshape(-1), F.reshape(1, -1))
    U = s.solve(torch.full((g.n_elements,), E, dtype=torch.float64))[0, 0].numpy().reshape(-1, dim)
    exact = np.zeros_like(x)
    exact[:, 0] = sigma * x[:, 0] / E
    for a in range(1, dim):
        exact[:, a] = -nu * sigma * x[:, a] / E
    assert np.abs(U - exact).max() < 1e-12
    c = float(s.work(torch.from_numpy(U.reshape(1, 1, -1)))[0, 0])
    assert c == pytest.approx(sigma**2 / E * np.prod(L), rel=1e-12)  # f^T u = 2 x strain energy


def test_slender_cantilever_tip_deflection_beam_theory():
    """A 20:1 cantilever (clamped, a shear load at the tip): tip deflection within 2 % of
    Timoshenko beam theory, P L^3 / (3 E I) + P L / (k G A)."""
    L, H, P, E, nu = 10.0, 0.5, 1.0, 1.0, 0.3
    g = ElementGrid((0.0, 0.0), (L, H), (200, 10))
    x = g.nodes
    tip = np.isclose(x[:, 0], L)
    F = np.zeros((g.n_nodes, 2))
    F[tip, 1] = -P / 10
    F[tip & (np.isclose(x[:, 1], 0) | np.isclose(x[:, 1], H)), 1] = -P / 20
    s = _solver(g, np.isclose(x[:, 0], 0), F.reshape(1, -1))
    U = s.solve(torch.full((g.n_elements,), E, dtype=torch.float64))[0, 0].numpy().reshape(-1, 2)
    beam = P * L**3 / (3 * E * H**3 / 12) + P * L / (5 / 6 * E / (2 * (1 + nu)) * H)
    assert -U[tip, 1].mean() == pytest.approx(beam, rel=0.02)


def _small_case(dim, loads=2, method="direct"):
    g = ElementGrid((0.0,) * dim, (3.0, 1.0, 1.0)[:dim], (6, 3, 2)[:dim])
    x = g.nodes
    rng = np.random.default_rng(2)
    F = np.zeros((loads, g.n_nodes, dim))
    end = np.flatnonzero(np.isclose(x[:, 0], 3.0))
    F[:, end] = rng.normal(size=(loads, end.size, dim))
    return g, _solver(g, np.isclose(x[:, 0], 0), F.reshape(loads, -1), method=method)


@pytest.mark.parametrize("dim", [2, 3])
def test_compliance_gradient_matches_central_differences(dim):
    g, s = _small_case(dim)
    rng = np.random.default_rng(3)
    E = torch.tensor(rng.uniform(0.2, 1.0, (2, g.n_elements)), dtype=torch.float64, requires_grad=True)
    w = torch.tensor([[1.0, 0.5], [0.3, 2.0]], dtype=torch.float64)
    c, sol = compliance(E, s)
    assert torch.allclose(c, sol.compliance) and torch.allclose(c, s.work(sol.displacement), rtol=1e-10)
    (c * w).sum().backward()
    step = 1e-6
    fd = np.zeros((2, g.n_elements))
    for b in range(2):
        for e in range(g.n_elements):
            d = torch.zeros_like(E)
            d[b, e] = step * E[b, e].item()
            plus = (compliance(E.detach() + d, s)[0] * w).sum().item()
            minus = (compliance(E.detach() - d, s)[0] * w).sum().item()
            fd[b, e] = (plus - minus) / (2 * d[b, e].item())
    assert np.abs(E.grad.numpy() - fd).max() <= 1e-6 * np.abs(fd).max()
    assert np.all(E.grad.numpy() < 0)  # a stiffer element never raises a compliance


@pytest.mark.parametrize("dim", [2, 3])
def test_methods_and_batching_agree(dim):
    g, direct = _small_case(dim, method="direct")
    rng = np.random.default_rng(4)
    E = torch.tensor(rng.uniform(1e-3, 1.0, (3, g.n_elements)), dtype=torch.float64)
    U = direct.solve(E)
    for b in range(3):  # the batch equals the shapes solved one by one
        assert torch.allclose(direct.solve(E[b])[0], U[b], rtol=0, atol=1e-12 * U.abs().max())
    _, cg = _small_case(dim, method="cg")
    V = cg.solve(E)
    assert (V - U).abs().max() <= 1e-8 * U.abs().max()
    V2 = cg.solve(E * 1.01)  # warm-started from the previous solve
    assert (V2 - U / 1.01).abs().max() <= 1e-8 * U.abs().max()


def test_band_follows_the_short_axis_and_solves_either_orientation():
    """The 2D direct method numbers its band along the grid's short axis, whichever axis that is:
    a grid and its mirror image across the diagonal (the same problem, the axes swapped) have
    the same half-bandwidth, at most ``2 n_short + 5``, and the same compliances, with solid
    elements beside void ones a million times softer (islands of solid in void move a million
    times as far as the clamped part); the backward error is at round-off."""
    rng = np.random.default_rng(5)
    solid = rng.random((12, 5)) < 0.6
    solid[:2] = True  # the clamped end solid
    moduli = np.where(solid, 1.0, 1e-6)
    F = np.zeros((2, 13, 6, 2))
    F[0, -1, :, 1] = -1.0
    F[1, -1, 2, 0] = 1.0
    out = []
    for swap in (False, True):
        g = ElementGrid((0.0, 0.0), (1.25, 3.0) if swap else (3.0, 1.25), (5, 12) if swap else (12, 5))
        Fg = F.transpose(0, 2, 1, 3)[..., ::-1] if swap else F
        E = moduli.T if swap else moduli
        s = _solver(g, np.isclose(g.nodes[:, 1 if swap else 0], 0), Fg.reshape(2, -1))
        U = s.solve(torch.tensor(E.reshape(1, -1)))
        K = s.stiffness(E.reshape(-1))
        f = s.forces[:, s.free].T
        u = U[0].numpy()[:, s.free].T
        assert np.abs(f - K @ u).max() <= 1e-14 * abs(K).sum(axis=1).max() * np.abs(u).max()
        assert s.band_layout()[3] <= 2 * 5 + 5
        out.append(s.work(U)[0].numpy())
    assert out[0] == pytest.approx(out[1], rel=1e-10)


def _band_case(n: int = 40, w: int = 4, seed: int = 0) -> np.ndarray:
    """LAPACK's upper band storage ``(w + 1, n)`` of a random diagonally dominant SPD band matrix."""
    rng = np.random.default_rng(seed)
    ab = rng.uniform(-1.0, 1.0, (w + 1, n))
    ab[w] = 2.0 * (w + 1)
    return np.asfortranarray(ab)


def test_band_cholesky_without_the_lock_equals_scipys_wrappers(monkeypatch):
    """The 2D direct method's band Cholesky, called through SciPy's LAPACK pointers with the
    interpreter lock released, gives SciPy's wrappers' factor and solutions bit for bit, solves
    the system to round-off, reports a matrix that is not positive definite as LAPACK does, and
    its fallback (the wrappers themselves) gives the same bits."""
    from scipy.linalg import lapack

    from ginn.physics import band

    assert band.releases_gil()  # the SciPy that ginn installs exports the pointers
    ab = _band_case()
    b = np.random.default_rng(1).normal(size=(40, 3))
    ref, info = lapack.dpbtrf(ab.copy(order="F"), lower=0)
    cf, info2 = band.factor(ab.copy(order="F"))
    assert info == info2 == 0 and np.array_equal(cf, ref)
    x = band.solve(cf, b)
    assert np.array_equal(x, lapack.dpbtrs(ref, b, lower=0)[0])
    assert np.array_equal(band.solve(cf, b[:, 0]), lapack.dpbtrs(ref, b[:, 0], lower=0)[0])
    n, w = ab.shape[1], ab.shape[0] - 1
    A = np.zeros((n, n))
    for i in range(n):
        for j in range(i, min(n, i + w + 1)):
            A[i, j] = A[j, i] = ab[w + i - j, j]
    assert np.abs(A @ x - b).max() <= 1e-13 * np.abs(b).max()
    bad = ab.copy(order="F")
    bad[w, 7] = -1.0  # the leading minor of order 8 is not positive definite
    assert band.factor(bad.copy(order="F"))[1] == lapack.dpbtrf(bad.copy(order="F"), lower=0)[1] == 8
    with pytest.raises(ValueError, match="Fortran"):
        band.factor(np.ascontiguousarray(ab))
    monkeypatch.setattr(band, "_routines", lambda: None)
    cf3, info3 = band.factor(ab.copy(order="F"))
    assert info3 == 0 and np.array_equal(cf3, ref) and np.array_equal(band.solve(cf3, b), x)


def test_direct_batch_on_threads_equals_one_by_one():
    """The 2D direct method's shapes side by side on two threads give each shape's solve alone
    bit for bit."""
    g, direct = _small_case(2, method="direct")
    E = torch.tensor(np.random.default_rng(6).uniform(1e-3, 1.0, (5, g.n_elements)), dtype=torch.float64)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        U = direct.solve(E)
    finally:
        torch.set_num_threads(before)
    for b in range(5):
        assert torch.equal(direct.solve(E[b])[0], U[b])


def test_bad_moduli_refused():
    g, s = _small_case(2)
    with pytest.raises(ValueError, match="positive"):
        s.solve(torch.zeros(g.n_elements, dtype=torch.float64))
    with pytest.raises(ValueError, match="moduli for"):
        s.solve(torch.ones(3, dtype=torch.float64))


def test_density_filter_preserves_constants_and_adjoint():
    f = DensityFilter((7, 5), 2.4)
    assert np.allclose(f(np.full(35, 0.4)), 0.4, atol=1e-15)
    rng = np.random.default_rng(5)
    x, y = rng.normal(size=35), rng.normal(size=35)
    assert f(x) @ y == pytest.approx(x @ f.adjoint(y), rel=1e-12)


def _mbb(nx=60, ny=20):
    g = ElementGrid((0.0, 0.0), (float(nx), float(ny)), (nx, ny))
    x = g.nodes
    fixed = np.zeros((g.n_nodes, 2), bool)
    fixed[np.isclose(x[:, 0], 0), 0] = True  # the symmetry line
    fixed[np.isclose(x[:, 0], nx) & np.isclose(x[:, 1], 0), 1] = True  # the roller
    F = np.zeros((g.n_nodes, 2))
    F[np.isclose(x[:, 0], 0) & np.isclose(x[:, 1], ny), 1] = -1.0
    return ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(1, -1), method="direct")


@pytest.mark.parametrize("filt,published", [("density", 233.71), ("sensitivity", 216.81)])
def test_simp_reproduces_the_88_line_code(filt, published):
    """top88(60, 20, 0.5, 3, 2.4, ft): the compliance of the last iteration as Andreassen et al. (2011) publish it."""
    res = simp(_mbb(), 0.5, penalty=3.0, filter_radius=2.4, filter=filt)
    assert res.history[-1] == pytest.approx(published, abs=0.01)
    assert res.volume_fraction == pytest.approx(0.5, abs=1e-3)
    assert res.history[-1] < 0.5 * res.history[0]


def test_simp_bar_in_tension_is_a_straight_bar():
    """A load pulling along the axis from a support: the optimum is a straight bar of the bound's volume
    between them (every element on the axis solid, every element off it void)."""
    nx, ny = 30, 15
    g = ElementGrid((0.0, 0.0), (float(nx), float(ny)), (nx, ny))
    x = g.nodes
    mid = np.abs(x[:, 1] - ny / 2) <= 1.5
    fixed = np.zeros((g.n_nodes, 2), bool)
    fixed[np.isclose(x[:, 0], 0) & mid] = True
    F = np.zeros((g.n_nodes, 2))
    load = np.isclose(x[:, 0], nx) & mid
    F[load, 0] = 1.0 / load.sum()
    s = ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(1, -1))
    res = simp(s, 0.2, filter_radius=1.2, max_iter=300)
    assert res.volume_fraction == pytest.approx(0.2, abs=1e-3)
    band = np.abs(g.centres[:, 1] - ny / 2) <= 1.5  # three rows of elements: 20 % of the domain
    densest = np.argsort(-res.density)[: band.sum()]
    assert set(densest) == set(np.flatnonzero(band))  # thresholded at the bound's volume: the straight bar
    beyond = np.abs(g.centres[:, 1] - ny / 2) > 2.5  # past the filter's grey rim
    assert res.density[beyond].max() < 1e-3


def _pinned_plate(method, nu=0.3):
    """A 6 x 4 plate on a frictionless pin at the origin (the nodes within half an element of a
    circle of radius 1, held along the radius), held along y at one node and loaded at another."""
    g = ElementGrid((-3.0, -2.0), (3.0, 2.0), (24, 16))
    x = g.nodes
    r = np.linalg.norm(x, axis=1)
    pin = np.abs(r - 1.0) <= 0.5 * g.h.max()
    normals = np.where(pin[:, None], x / np.maximum(r, 1e-300)[:, None], 0.0)
    link = int(np.argmin(np.linalg.norm(x - [-2.5, -1.5], axis=1)))
    tip = int(np.argmin(np.linalg.norm(x - [2.5, 1.5], axis=1)))
    fixed = np.zeros((g.n_nodes, 2), bool)
    fixed[link, 1] = True
    F = np.zeros((g.n_nodes, 2))
    F[tip] = [-1.0, -2.0]
    s = ElasticitySolver(g, nu, fixed.reshape(-1), F.reshape(1, -1), method=method, normals=normals)
    return g, s, pin, normals, link, tip, F


@pytest.mark.parametrize("method", ["direct", "cg", "cg-diagonal"])
def test_pin_turns_freely_and_the_link_takes_the_moment(method):
    """A frictionless pin holds only along the rim's normals: its reactions have no moment about
    its centre, so the link alone balances the load's moment (statics, whatever the stiffness),
    and every pin node slides along the rim (zero radial displacement)."""
    g, s, pin, normals, link, tip, F = _pinned_plate(method)
    rng = np.random.default_rng(5)
    E = torch.tensor(rng.uniform(0.5, 2.0, g.n_elements), dtype=torch.float64)
    U = s.solve(E)[0, 0].numpy()
    K = ElasticitySolver(g, 0.3, np.zeros(g.n_dofs, bool), np.zeros((1, g.n_dofs))).stiffness(E.numpy())
    R = (K @ U - F.reshape(-1)).reshape(-1, 2)  # the supports' reactions
    x = g.nodes
    scale = np.abs(F).max()
    free = ~pin
    free[link] = False
    assert np.abs(R[free]).max() <= 1e-8 * scale  # equilibrium wherever nothing holds the node
    assert np.abs(R[link, 0]) <= 1e-8 * scale
    moment = x[tip, 0] * F[tip, 1] - x[tip, 1] * F[tip, 0]
    assert R[link, 1] == pytest.approx(-moment / x[link, 0], rel=1e-8)
    pin_moment = (x[pin, 0] * R[pin, 1] - x[pin, 1] * R[pin, 0]).sum()
    assert abs(pin_moment) <= 1e-8 * abs(moment)
    u = U.reshape(-1, 2)
    assert np.abs((u[pin] * normals[pin]).sum(axis=1)).max() <= 1e-12 * np.abs(u).max()
    assert np.abs((u[pin] * normals[pin][:, ::-1] * [-1, 1]).sum(axis=1)).max() > 1e-3 * np.abs(u).max()  # it slides
    c = compliance(E[None], s)[0]
    assert float(c[0, 0]) == pytest.approx(float(F.reshape(-1) @ U), rel=1e-10)


@pytest.mark.parametrize("dim", [2, 3])
def test_normals_along_the_axes_hold_as_fixed_axes(dim):
    """A normal along x at a node holds what fixing x holds: the same displacements (every
    method), the same compliance and its gradient."""
    g = ElementGrid((0.0,) * dim, (3.0, 1.0, 1.0)[:dim], (6, 3, 2)[:dim])
    x = g.nodes
    left = np.isclose(x[:, 0], 0)
    F = np.zeros((g.n_nodes, dim))
    F[np.isclose(x[:, 0], 3.0), 1] = -0.1
    fixed = np.zeros((g.n_nodes, dim), bool)
    fixed[left] = True  # clamped
    normals = np.zeros((g.n_nodes, dim))
    normals[left, 0] = -1.0
    only_axes = fixed.copy()
    only_axes[left, 0] = False  # x is held by the normals
    only_axes[np.flatnonzero(left)[:2], 0] = True  # and also by an axis at two nodes: both at once
    rng = np.random.default_rng(6)
    E = torch.tensor(rng.uniform(0.2, 1.0, (2, g.n_elements)), dtype=torch.float64, requires_grad=True)
    ref = ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(1, -1), method="direct")
    U = ref.solve(E.detach())
    c_ref = compliance(E, ref)[0].sum()
    (g_ref,) = torch.autograd.grad(c_ref, E)
    for method in ("direct", "cg", "cg-diagonal"):
        s = ElasticitySolver(g, 0.3, only_axes.reshape(-1), F.reshape(1, -1), method=method, normals=normals)
        V = s.solve(E.detach())
        assert (V - U).abs().max() <= 1e-8 * U.abs().max(), method
        c = compliance(E, s)[0].sum()
        (grad,) = torch.autograd.grad(c, E)
        assert float(c.detach()) == pytest.approx(float(c_ref.detach()), rel=1e-8)
        assert (grad - g_ref).abs().max() <= 1e-8 * g_ref.abs().max()
