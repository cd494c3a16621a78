"""Constraint losses against analytic fields, the zero-level-set projection, and the diversity loss."""

import math

import pytest
import torch

from ginn.fields import as_field, evaluate
from ginn.levelset import project_to_zero
from ginn.losses import constraints as C
from ginn.losses.diversity import aggregate_min, aggregate_sum, cross_values, distance_matrix, diversity

D = torch.float64


def disk(c, r):
    c = torch.tensor(c, dtype=D)
    return as_field(lambda x: (x - c).norm(dim=-1) - r)


def test_design_region_zero_for_shape_inside(gen):
    # E = [-0.9, 0.9] x [-0.4, 0.4]; a disk of radius 0.3 at the origin lies inside E
    x = torch.rand(20000, 2, dtype=D, generator=gen) * torch.tensor([2.0, 1.0], dtype=D) - torch.tensor([1.0, 0.5], dtype=D)
    outside = (x[:, 0].abs() > 0.9) | (x[:, 1].abs() > 0.4)
    f = disk([0.0, 0.0], 0.3)(x[outside])
    assert C.DesignRegionLoss()(f).item() == 0.0


def test_design_region_disk_poking_out_known_value(gen):
    """Disk of radius r centred on the half-plane boundary y = 0 (E = {y < 0}): the part outside
    is a half disk, where min(0, f)^2 = (r - rho)^2. Its integral is pi r^4 / 12, so the mean over
    the sampled outside box [−1,1]x[0,1] (area 2) is pi r^4 / 24."""
    r = 0.5
    n = 400000
    x = torch.rand(n, 2, dtype=D, generator=gen) * torch.tensor([2.0, 1.0], dtype=D) - torch.tensor([1.0, 0.0], dtype=D)
    val = C.DesignRegionLoss()(disk([0.0, 0.0], r)(x)).item()
    exact = math.pi * r**4 / 24
    assert val == pytest.approx(exact, rel=0.02)
    # the exact (power 1) penalty: integral of (r - rho) over the half disk is pi r^3 / 6
    val1 = C.DesignRegionLoss(power=1)(disk([0.0, 0.0], r)(x)).item()
    assert val1 == pytest.approx(math.pi * r**3 / 12, rel=0.02)
    assert C.ObstacleLoss(power=1)(torch.tensor([0.2, -0.1, -0.3], dtype=D)).item() == pytest.approx(0.4 / 3)


def test_eikonal_zero_for_exact_sdf(gen):
    x = torch.randn(500, 3, dtype=D, generator=gen) + 2.0
    v = evaluate(disk([0.0, 0.0, 0.0], 1.0), x, create_graph=False)
    assert C.EikonalLoss()(v.grad).item() < 1e-20
    v2 = evaluate(as_field(lambda p: 2 * p.norm(dim=-1)), x, create_graph=False)
    assert C.EikonalLoss()(v2.grad).item() == pytest.approx(1.0, abs=1e-12)


def test_interface_and_normal_losses(gen):
    # the circle of radius 0.5 passes through interface samples on it; normals outward
    t = torch.rand(300, dtype=D, generator=gen) * 2 * math.pi
    xi = 0.5 * torch.stack([t.cos(), t.sin()], -1)
    n_out = xi / 0.5
    v = evaluate(disk([0.0, 0.0], 0.5), xi, create_graph=False)
    assert C.InterfaceLoss()(v.f).item() < 1e-28
    assert C.NormalLoss()(v.grad, n_out).item() == pytest.approx(0.0, abs=1e-24)
    assert C.NormalLoss()(v.grad, -n_out).item() == pytest.approx(4.0, abs=1e-12)
    # a circle of radius 0.6: interface loss is 0.1^2
    v6 = evaluate(disk([0.0, 0.0], 0.6), xi, create_graph=False)
    assert C.InterfaceLoss()(v6.f).item() == pytest.approx(0.01, rel=1e-9)
    # per-sample weights: a weighted mean
    w = torch.ones(300, dtype=D)
    w[:10] = 5
    assert C.InterfaceLoss()(v6.f, w).item() == pytest.approx(0.01, rel=1e-9)


def test_curvature_and_strain_losses_on_sphere(gen):
    r = 0.8
    p = torch.randn(200, 3, dtype=D, generator=gen)
    p = r * p / p.norm(dim=-1, keepdim=True)
    v = evaluate(disk([0.0, 0.0, 0.0], r), p, grad=False, hessian_at=True, create_graph=False)
    assert C.MeanCurvatureLoss()(v.hessian_grad, v.hessian).item() == pytest.approx((2 / r) ** 2, rel=1e-9)
    assert C.StrainLoss()(v.hessian_grad, v.hessian).item() == pytest.approx(2 / r**2, rel=1e-9)
    assert C.StrainLoss(clip=1.0)(v.hessian_grad, v.hessian).item() == pytest.approx(1.0)


def test_projection_lands_on_circle(gen):
    r = 0.37
    fld = as_field(lambda x: x.norm(dim=-1) ** 2 - r**2)  # not an SDF: Newton still converges
    x0 = torch.rand(1000, 2, dtype=D, generator=gen) * 2 - 1
    proj = project_to_zero(fld, x0, steps=12, tol=1e-9)
    assert proj.n_converged == 1000
    assert (proj.x.norm(dim=-1) - r).abs().max() < 1e-5


def test_projection_settled_points_stop_moving(gen):
    """With ``settle`` a point stops after a step shorter than it: the result stays within about
    the square of that length of the full projection, and the later steps evaluate only the
    points still moving (here the ones started far from the circle)."""
    r = 0.37
    sizes = []

    def f(x):
        sizes.append(x.shape[0])
        return x.norm(dim=-1) ** 2 - r**2

    fld = as_field(f)
    near = torch.nn.functional.normalize(torch.randn(500, 2, dtype=D, generator=gen), dim=-1) * (r + 1e-3)
    far = torch.nn.functional.normalize(torch.randn(500, 2, dtype=D, generator=gen), dim=-1) * 0.9
    x0 = torch.cat([near, far])
    full = project_to_zero(fld, x0, steps=8, tol=1e-5)
    sizes.clear()
    settled = project_to_zero(fld, x0, steps=8, tol=1e-5, settle=1e-3)
    assert settled.n_converged == full.n_converged == 1000
    assert (settled.x - full.x).norm(dim=-1).max() < 1e-5
    # the near points settle after two steps, the far ones need more: later passes are smaller
    assert sizes[0] == 1000 and sizes[2] == 500 and min(sizes[:-1]) > 0
    assert sum(sizes[:-1]) < 8 * 1000 * 0.6


def test_projection_reports_failures(gen):
    fld = as_field(lambda x: x.norm(dim=-1) - 0.5)
    x0 = torch.rand(100, 2, dtype=D, generator=gen) * 2 - 1
    lo, hi = torch.tensor([-0.1, -1.0], dtype=D), torch.tensor([1.0, 1.0], dtype=D)
    proj = project_to_zero(fld, x0, steps=5, tol=1e-8, bounds=(lo, hi))
    assert 0 < proj.n_converged < 100
    assert torch.all(proj.x[proj.converged][:, 0] >= -0.1)


# --- diversity (Appendix E) -------------------------------------------------------------------


def _circle_points(r, m, c=(0.0, 0.0)):
    t = torch.arange(m, dtype=D) * 2 * math.pi / m
    return torch.stack([c[0] + r * t.cos(), c[1] + r * t.sin()], -1)


def latent_circles(x, z):
    """f(x; z) = |x| - z: concentric circles of radius z (exact SDFs)."""
    return x.norm(dim=-1) - z[:, 0]


def test_distance_of_field_to_itself_is_zero():
    Z = torch.tensor([[0.3], [0.3]], dtype=D)
    xb = torch.stack([_circle_points(0.3, 64), _circle_points(0.3, 64)])
    Dm = distance_matrix(cross_values(latent_circles, xb, Z))
    assert Dm[0, 1].item() <= 1e-6  # the floor sqrt(1e-12) that keeps the gradient finite


def test_distance_between_concentric_circles_closed_form():
    r1, r2 = 0.3, 0.5
    Z = torch.tensor([[r1], [r2]], dtype=D)
    xb = torch.stack([_circle_points(r1, 128), _circle_points(r2, 128)])
    Dm = distance_matrix(cross_values(latent_circles, xb, Z))
    # mean over each circle of the other's SDF squared is (r1 - r2)^2: d = sqrt(2) |r1 - r2|
    assert Dm[0, 1].item() == pytest.approx(math.sqrt(2) * abs(r1 - r2), rel=1e-12)
    assert torch.allclose(Dm, Dm.T)


def test_smoothed_distance_bounds_the_gradient_at_a_collapse():
    """``eps``: sqrt(d^2 + eps^2) exactly; at coinciding shapes the diversity's gradient is finite
    with eps and of order 1/sqrt(TINY) without it."""
    r1, r2 = 0.3, 0.5
    Z = torch.tensor([[r1], [r2]], dtype=D)
    xb = torch.stack([_circle_points(r1, 128), _circle_points(r2, 128)])
    d0 = distance_matrix(cross_values(latent_circles, xb, Z))[0, 1]
    d1 = distance_matrix(cross_values(latent_circles, xb, Z), eps=0.05)[0, 1]
    assert d1.item() == pytest.approx(math.sqrt(d0.item() ** 2 + 0.05**2), rel=1e-12)

    def grad_norm(eps, gap):
        # two nearly coinciding circles and a third one far from both
        radii = [0.3, 0.3 + gap, 0.6]
        z = torch.tensor([[r] for r in radii], dtype=D, requires_grad=True)
        pts = torch.stack([_circle_points(r, 64) for r in radii])
        (g,) = torch.autograd.grad(diversity(latent_circles, pts, z, eps=eps), z)
        return g.norm().item()

    # paper distance: d delta / d d_1 = sqrt(delta / d_1) grows like gap^(-1/2)
    assert grad_norm(0.0, 1e-6) > 50 * grad_norm(0.0, 1e-2)
    # smoothed: bounded (about sqrt(delta / eps)) however close the shapes come
    assert grad_norm(0.01, 1e-6) < 2 * grad_norm(0.01, 1e-2)


def test_aggregations_on_hand_made_matrices():
    Dm = torch.tensor([[0.0, 1.0, 4.0], [1.0, 0.0, 9.0], [4.0, 9.0, 0.0]], dtype=D)
    # nearest: 1, 1, 4 -> (1 + 1 + 2)^2 = 16
    assert aggregate_min(Dm, 0.5).item() == pytest.approx(16.0)
    assert aggregate_min(Dm, 1.0).item() == pytest.approx(6.0)
    # totals: 5, 10, 13
    assert aggregate_sum(Dm, 1.0).item() == pytest.approx(28.0)
    assert aggregate_sum(Dm, 2.0).item() == pytest.approx(math.sqrt(25 + 100 + 169))
    assert aggregate_min(torch.zeros(1, 1, dtype=D)).item() == 0.0


def test_diversity_gradient_pushes_circles_apart():
    z = torch.tensor([[0.30], [0.32], [0.60]], dtype=D, requires_grad=True)
    xb = torch.stack([_circle_points(float(r), 64) for r in z.detach()[:, 0]])
    delta = diversity(latent_circles, xb, z)
    (-delta).backward()
    # gradient descent on -delta separates the two close circles
    assert z.grad[0, 0] > 0 and z.grad[1, 0] < 0


@pytest.mark.parametrize("S, masked, prefix", [(2, False, None), (3, True, None), (16, False, None), (16, True, 1),
                                                (16, True, 40), (9, False, 7)])
def test_nearest_neighbours_by_bounds_are_those_of_the_full_matrix(S, masked, prefix):
    """Branch and bound over partial sums finds each shape's nearest shape exactly (float64), and
    with shapes spread over the latent range it evaluates the field at fewer points than the full
    S x S x m computation."""
    from ginn.losses.diversity import distance_matrix, nearest_neighbours
    from ginn.models import Siren

    torch.manual_seed(S)
    net = Siren(2, [32, 32], latent_dim=1, w0_first=3.0).double()
    calls = []

    def f(x, z):
        calls.append(len(x))
        return net(x, z)

    m = 40
    xb = torch.rand(S, m, 2, dtype=torch.float64) * 2 - 1
    Z = torch.linspace(-1, 1, S, dtype=torch.float64)[:, None]
    mask = (torch.rand(S, m) > 0.25) if masked else None
    D = distance_matrix(cross_values(net, xb, Z), mask).masked_fill(torch.eye(S, dtype=torch.bool), float("inf"))
    near = nearest_neighbours(f, xb, Z, mask, prefix)
    assert torch.equal(near, D.argmin(dim=1))
    if S == 16 and prefix is None:  # circles of radius 0.3 centred at (z, 0), sampled on their boundaries
        calls.clear()

        def circles(x, z):
            calls.append(len(x))
            return torch.linalg.norm(x - torch.cat([z, torch.zeros_like(z)], dim=1), dim=1) - 0.3

        t = torch.rand(S, m, dtype=torch.float64) * 2 * math.pi
        xb = torch.stack([Z + 0.3 * torch.cos(t), 0.3 * torch.sin(t)], dim=-1)
        D = distance_matrix(cross_values(circles, xb, Z), mask).masked_fill(torch.eye(S, dtype=torch.bool), float("inf"))
        calls.clear()
        assert torch.equal(nearest_neighbours(circles, xb, Z, mask), D.argmin(dim=1))
        assert sum(calls) < 0.5 * S * S * m

        def saturating(x, z):  # distances level off: many pairs within a few times the nearest
            return torch.tanh(4.0 * circles(x, z))

        D = distance_matrix(cross_values(saturating, xb, Z), mask).masked_fill(torch.eye(S, dtype=torch.bool), float("inf"))
        calls.clear()
        assert torch.equal(nearest_neighbours(saturating, xb, Z, mask), D.argmin(dim=1))
        # block by block: 0.40 of S^2 m here; completing every pair the first quarter leaves open
        # at once evaluates 0.51
        assert sum(calls) < 0.45 * S * S * m


@pytest.mark.parametrize("eps, masked", [(0.0, False), (0.0, True), (0.01, True)])
def test_nearest_pair_diversity_equals_the_full_computation(eps, masked):
    """The minimal aggregation evaluated with a graph only through the nearest pairs has the same
    value and parameter gradient as the full S x S computation (float64), with ties of mutual
    nearest neighbours counted once."""
    from ginn.losses.diversity import diversity_nearest
    from ginn.models import Siren

    torch.manual_seed(0)
    f = Siren(2, [32, 32], latent_dim=1, w0_first=3.0).double()
    S, m = 7, 40
    xb = torch.rand(S, m, 2, dtype=torch.float64) * 2 - 1
    Z = torch.linspace(-1, 1, S, dtype=torch.float64)[:, None]
    mask = (torch.rand(S, m) > 0.25) if masked else None
    full = diversity(f, xb, Z, mask, "min", 0.5, eps)
    near = diversity_nearest(f, xb, Z, mask, 0.5, eps)
    assert float(near) == pytest.approx(float(full), rel=1e-13, abs=0)
    g_full = torch.autograd.grad(full, list(f.parameters()))
    g_near = torch.autograd.grad(near, list(f.parameters()))
    for a, b in zip(g_full, g_near):
        assert torch.allclose(a, b, rtol=1e-11, atol=1e-13)
    assert float(diversity_nearest(f, xb[:1], Z[:1], None)) == 0.0  # one shape: no diversity
