"""Critical points, surface network, connectedness losses and b0 on analytic fields (float64).

The fields are smooth unions of disks/spheres: ``softmin_k(sqrt(|x - c_i|^2 + delta^2) - r_i)``
(the square root removes the cone point at the centres, the log-sum-exp soft minimum the kink on
the medial axis), so their critical points are known exactly: a minimum at every centre and,
for two equal disks, a saddle at the midpoint by symmetry.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from ginn.config import ConnectednessConfig
from ginn.extract.grid import label_components
from ginn.geometry.base import Box, Region
from ginn.topology import (
    MAXIMUM,
    MINIMUM,
    SADDLE,
    ConnectednessLoss,
    CriticalPointOptions,
    PersistenceOptions,
    SurfaceNetworkLossOptions,
    b0,
    b0_of_mask,
    component_sizes,
    count_components,
    death_points,
    find_critical_points,
    make_connectedness_loss,
    trace_surface_network,
)
from ginn.topology.penalties import ShapeGraph, saddle_penalties

DT = torch.float64


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    """Tiny tensors: intra-op threads only add contention on a shared machine."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)

K, DELTA = 0.05, 0.05
TIGHT = SurfaceNetworkLossOptions(critical=CriticalPointOptions(tol=1e-10))


def blobs(centres, radii, k=K, delta=DELTA, shift=None):
    """Smooth union of balls; ``shift`` (a tensor/parameter) is added to the field."""
    C = torch.as_tensor(centres, dtype=DT)
    R = torch.as_tensor(radii, dtype=DT).expand(C.shape[0])

    def field(x, z=None):
        d = torch.sqrt(((x[:, None, :] - C[None]) ** 2).sum(-1) + delta**2) - R
        f = -k * torch.logsumexp(-d / k, dim=1)
        return f if shift is None else f + shift

    return field


def boundary_crossing(field, a, b, n=60):
    """The point where ``field`` crosses 0 on the segment from ``a`` (f > 0) to ``b`` (f < 0)."""
    a, b = torch.as_tensor(a, dtype=DT), torch.as_tensor(b, dtype=DT)
    lo, hi = 0.0, 1.0
    for _ in range(n):
        mid = 0.5 * (lo + hi)
        if field((a + mid * (b - a))[None])[0] > 0:
            lo = mid
        else:
            hi = mid
    return a + lo * (b - a)


BOX2 = Box((-1.0, -1.0), (1.0, 1.0))
BOX3 = Box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))


def _sorted_rows(x):
    x = x.detach().numpy()
    return x[np.lexsort(x.T[::-1])]


# --- critical points ------------------------------------------------------------------------


def test_two_disks_critical_points():
    c1, c2 = [-0.45, -0.2], [0.5, 0.25]
    f = blobs([c1, c2], 0.25)
    cp = find_critical_points(f, None, BOX2, 16, options=TIGHT.critical, generator=torch.Generator().manual_seed(0), dtype=DT)
    kind = cp.kind
    assert int((kind == MINIMUM).sum()) == 2
    assert int((kind == SADDLE).sum()) == 1
    assert int((kind == MAXIMUM).sum()) == 0
    minima = _sorted_rows(cp.x[kind == MINIMUM])
    np.testing.assert_allclose(minima, np.array([c1, c2]), atol=1e-3)
    saddle = cp.x[kind == SADDLE][0].numpy()
    np.testing.assert_allclose(saddle, (np.array(c1) + np.array(c2)) / 2, atol=1e-3)
    assert float(cp.grad_norm.max()) < 1e-8


def test_two_spheres_critical_points_3d():
    c1, c2 = [-0.45, 0.1, -0.1], [0.45, -0.1, 0.2]
    f = blobs([c1, c2], 0.25)
    cp = find_critical_points(f, None, BOX3, 10, options=TIGHT.critical, generator=torch.Generator().manual_seed(0), dtype=DT)
    kind = cp.kind
    assert int((kind == MINIMUM).sum()) == 2
    assert int((kind == SADDLE).sum()) == 1
    assert int(cp.index[kind == SADDLE][0]) == 1  # one descending direction
    np.testing.assert_allclose(_sorted_rows(cp.x[kind == MINIMUM]), np.array([c1, c2]), atol=1e-3)
    np.testing.assert_allclose(cp.x[kind == SADDLE][0].numpy(), (np.array(c1) + np.array(c2)) / 2, atol=1e-3)


def test_batch_of_shapes_keeps_points_apart():
    """Two shapes in one batch (latent shifts the second pair): each gets its own points."""
    C = torch.tensor([[-0.5, 0.0], [0.5, 0.0]], dtype=DT)

    def field(x, z):
        c = C[None] + z[:, None, :] * torch.tensor([0.0, 0.3], dtype=DT)
        d = torch.sqrt(((x[:, None, :] - c) ** 2).sum(-1) + DELTA**2) - 0.25
        return -K * torch.logsumexp(-d / K, dim=1)

    Z = torch.tensor([[0.0], [1.0]], dtype=DT)
    cp = find_critical_points(field, Z, BOX2, 16, options=TIGHT.critical, generator=torch.Generator().manual_seed(0))
    counts = cp.counts(2)
    np.testing.assert_array_equal(counts["minima"], [2, 2])
    np.testing.assert_array_equal(counts["saddles"], [1, 1])
    s1 = cp.x[(cp.kind == SADDLE) & (cp.shape == 1)][0].numpy()
    np.testing.assert_allclose(s1, [0.0, 0.3], atol=1e-3)


def test_field_without_critical_points():
    f = lambda x, z=None: x[:, 0] + 0.5 * x[:, 1]  # noqa: E731
    cp = find_critical_points(f, None, BOX2, 8, dtype=DT)
    assert cp.m == 0


def test_surface_network_two_disks():
    f = blobs([[-0.5, 0.0], [0.5, 0.0]], 0.25)
    cp = find_critical_points(f, None, BOX2, 16, options=TIGHT.critical, dtype=DT)
    net = trace_surface_network(f, None, BOX2, cp, 16)
    s = int(torch.nonzero(cp.kind == SADDLE)[0])
    desc = net.path_descending & (net.path_end >= 0)
    ends = sorted(net.path_end[desc].tolist())
    assert ends == sorted(torch.nonzero(cp.kind == MINIMUM).squeeze(-1).tolist())
    assert (net.path_start[desc] == s).all()
    # outside part of each descending path = distance from the saddle to the disk's boundary
    edge = boundary_crossing(f, [0.0, 0.0], [0.5, 0.0])
    np.testing.assert_allclose(net.path_outside_length[desc], float(edge.norm()), rtol=1e-3)
    A = net.adjacency()
    assert A.shape == (3, 3) and A.nnz == 4


# --- connectedness loss ---------------------------------------------------------------------


def test_loss_two_disks_all_penalty_on_saddle():
    shift = torch.nn.Parameter(torch.zeros((), dtype=DT))
    f = blobs([[-0.45, -0.2], [0.5, 0.25]], 0.25, shift=shift)
    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(), dtype=DT, options=TIGHT)
    loss = loss_fn(f, None)
    x, sh, p = loss_fn.penalised_points()
    assert x.shape == (1, 2)
    np.testing.assert_allclose(x[0].numpy(), [0.025, 0.025], atol=1e-3)
    np.testing.assert_allclose(p.numpy(), [1.0])
    assert loss.item() == pytest.approx(f(x)[0].item(), abs=1e-12)
    assert loss_fn.last_info["n_components"] == [2]
    loss.backward()
    assert float(shift.grad) == pytest.approx(1.0)


def test_loss_three_disks_inverse_gap_weights():
    centres = [[-0.7, 0.0], [0.0, 0.0], [0.8, 0.0]]
    r = 0.2
    f = blobs(centres, r)
    eps = 0.01
    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(eps=eps), dtype=DT, options=TIGHT)
    loss_fn(f, None)
    x, _, p = loss_fn.penalised_points()
    order = torch.argsort(x[:, 0])
    x, p = x[order].numpy(), p[order].numpy()
    assert x.shape == (2, 2)
    # the gaps between the boundaries, measured on the field itself
    a1 = boundary_crossing(f, x[0], [-0.7, 0.0])[0]
    b1 = boundary_crossing(f, x[0], [0.0, 0.0])[0]
    a2 = boundary_crossing(f, x[1], [0.0, 0.0])[0]
    b2 = boundary_crossing(f, x[1], [0.8, 0.0])[0]
    g1, g2 = float(b1 - a1), float(b2 - a2)
    # Algorithm 1: pairs (A,B) and (B,C) through one saddle each, (A,C) through both
    w1 = 1 / (g1 + eps) + 1 / (g1 + g2 + eps)
    w2 = 1 / (g2 + eps) + 1 / (g1 + g2 + eps)
    np.testing.assert_allclose(p, [w1 / (w1 + w2), w2 / (w1 + w2)], rtol=1e-3)
    assert p[0] > p[1]  # the nearer gap (left, 0.3 vs 0.4 between centres) weighs more


def test_loss_two_spheres_3d():
    c1, c2 = [-0.45, 0.1, -0.1], [0.45, -0.1, 0.2]
    f = blobs([c1, c2], 0.25)
    loss_fn = ConnectednessLoss(BOX3, None, ConnectednessConfig(grid=10), dtype=DT, options=TIGHT)
    loss = loss_fn(f, None)
    x, _, p = loss_fn.penalised_points()
    np.testing.assert_allclose(x.numpy(), [(np.array(c1) + np.array(c2)) / 2], atol=1e-3)
    np.testing.assert_allclose(p.numpy(), [1.0])
    assert float(loss) == pytest.approx(float(f(x)[0]), abs=1e-12)


def test_connected_shape_gives_zero_loss_with_a_graph():
    w = torch.nn.Parameter(torch.ones((), dtype=DT))
    base = blobs([[-0.2, 0.0], [0.2, 0.0]], 0.25)
    f = lambda x, z=None: w * base(x)  # noqa: E731
    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(), dtype=DT, options=TIGHT)
    loss = loss_fn(f, None)
    assert loss.item() == 0.0 and loss.requires_grad
    assert loss_fn.last_info["n_components"] == [1]


def test_batch_mean_over_shapes():
    """Shape 0 disconnected, shape 1 connected: loss = f_0(saddle) / 2."""
    C = torch.tensor([[-0.5, 0.0], [0.5, 0.0]], dtype=DT)

    def field(x, z):
        c = C[None] * (1 - 0.7 * z[:, None, :])
        d = torch.sqrt(((x[:, None, :] - c) ** 2).sum(-1) + DELTA**2) - 0.25
        return -K * torch.logsumexp(-d / K, dim=1)

    Z = torch.tensor([[0.0], [1.0]], dtype=DT)
    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(), dtype=DT, options=TIGHT)
    loss = loss_fn(field, Z)
    assert loss_fn.last_info["n_components"] == [2, 1]
    x, sh, p = loss_fn.penalised_points()
    assert sh.tolist() == [0]
    f0 = field(x, Z[sh])
    assert float(loss) == pytest.approx(float(f0[0]) / 2, abs=1e-12)


class _HalfPlane(Region):
    dim = 2

    def __init__(self, x0):
        self.x0 = x0

    def sdf(self, x):
        return self.x0 - x[:, 0]


def test_design_region_ignores_outside_components():
    """Three disks; the design region x >= -0.3 cuts off the left one: one pair is left."""
    f = blobs([[-0.7, 0.0], [0.0, 0.0], [0.8, 0.0]], 0.2)
    loss_fn = ConnectednessLoss(BOX2, _HalfPlane(-0.3), ConnectednessConfig(), dtype=DT, options=TIGHT)
    loss_fn(f, None)
    x, _, p = loss_fn.penalised_points()
    assert loss_fn.last_info["n_components"] == [2]
    np.testing.assert_allclose(x.numpy(), [[0.4, 0.0]], atol=1e-3)


class _WithoutDisk(Region):
    """The plane minus a disk of radius r at the origin (an obstacle)."""

    dim = 2

    def __init__(self, r):
        self.r = r

    def sdf(self, x):
        return self.r - x.norm(dim=-1)


def test_fallback_when_the_saddle_lies_in_an_obstacle():
    """Two disks either side of an obstacle: the separating saddle (the origin) lies outside E,
    the surface network has no path inside E; the fallback penalises a PH death node in E."""
    f = blobs([[-0.5, 0.0], [0.5, 0.0]], 0.25)
    region = _WithoutDisk(0.15)
    loss_fn = ConnectednessLoss(BOX2, region, ConnectednessConfig(), dtype=DT, options=TIGHT)
    loss = loss_fn(f, None)
    info = loss_fn.last_info
    assert info["n_components"] == [2] and info["unreachable_pairs"] == 1 and info["n_fallback"] >= 1
    x, _, p = loss_fn.penalised_points()
    assert bool(region.contains(x).all())
    assert float(p.sum()) == pytest.approx(1.0)
    # the death node is where the gap is narrowest inside E: just outside the obstacle, on y = 0
    # is impossible (inside it), so at the obstacle's rim
    assert float(x.norm(dim=-1).min()) == pytest.approx(0.15, abs=2 * 2.0 / 32)
    assert loss.item() == pytest.approx(float((p * f(x)).sum()), abs=1e-12)
    off = ConnectednessLoss(
        BOX2, region, ConnectednessConfig(), dtype=DT,
        options=SurfaceNetworkLossOptions(critical=TIGHT.critical, fallback=False),
    )
    assert off(f, None).item() == 0.0 and off.last_info["n_penalised"] == 0


def test_component_touching_the_domain_boundary():
    """A half-plane x <= -0.8 (no interior minimum) and a disk: found through the grid labels,
    the saddle between them penalised."""
    disk = blobs([[0.3, 0.0]], 0.2)

    def f(x, z=None):
        a = x[:, 0] + 0.8
        b = disk(x)
        return -K * torch.logsumexp(torch.stack([-a / K, -b / K], 1), dim=1)

    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(), dtype=DT, options=TIGHT)
    loss_fn(f, None)
    assert loss_fn.last_info["n_components"] == [2]
    x, _, p = loss_fn.penalised_points()
    assert x.shape == (1, 2) and abs(float(x[0, 1])) < 1e-3
    # the saddle is where the two distances are equal: x + 0.8 = |x - 0.3| - r_eff
    r_eff = np.sqrt(0.2**2 - DELTA**2)
    # (up to ~2e-3: the smoothing makes |grad| slightly below 1 near the disk)
    assert float(x[0, 0]) == pytest.approx((0.3 - r_eff - 0.8) / 2, abs=5e-3)
    pure = ConnectednessLoss(
        BOX2, None, ConnectednessConfig(), dtype=DT,
        options=SurfaceNetworkLossOptions(critical=TIGHT.critical, label_grid=0),
    )
    pure(f, None)
    assert pure.last_info["n_components"] == [1]  # the surface network alone misses it


def test_warm_update_and_fallback():
    shift = torch.zeros(2, dtype=DT)

    def f(x, z=None):
        return blobs([[-0.5 + float(shift[0]), 0.0], [0.5, float(shift[1])]], 0.25)(x)

    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=100), dtype=DT, options=TIGHT)
    loss_fn(f, None)
    assert loss_fn.last_info["update"] == "full"
    shift[0] = 0.02  # the saddle moves to x = 0.01
    loss = loss_fn(f, None)
    assert loss_fn.last_info["update"] == "warm"
    x, _, _ = loss_fn.penalised_points()
    np.testing.assert_allclose(x.numpy(), [[0.01, 0.0]], atol=1e-6)
    assert float(loss) == pytest.approx(float(f(x)[0]), abs=1e-10)
    # a drastic change: the disks merge, the saddle disappears -> it is dropped, and the next
    # scheduled build (call 100) finds one piece
    shift[0], shift[1] = 0.6, 0.0
    loss = loss_fn(f, None)
    assert loss_fn.last_info["update"] == "warm" and loss_fn.last_info["warm_failed"] == 1
    assert float(loss) == 0.0 and loss_fn.penalised_points()[0].shape[0] == 0
    while loss_fn.step < 100:
        assert float(loss_fn(f, None)) == 0.0 and loss_fn.last_info["update"] == "warm"
    loss_fn(f, None)
    assert loss_fn.last_info["update"] == "full" and loss_fn.last_info["n_components"] == [1]


def test_pair_joined_only_through_a_maximum_goes_to_the_fallback():
    """Two minima whose only link in G_a is a maximum: no saddle to lower, so the pair counts as
    one the surface network cannot penalise (the grid fallback's input), not as connected; with
    the middle vertex a saddle it takes the whole weight."""

    def graph(middle: int) -> ShapeGraph:
        return ShapeGraph(
            x=np.array([[-0.5, 0.0], [0.5, 0.0], [0.0, 0.5]]), f=np.array([-1.0, -1.0, 0.3]),
            kind=np.array([MINIMUM, MINIMUM, middle]), valid=np.ones(3, dtype=bool),
            start=np.array([2, 2]), end=np.array([0, 1]), length=np.array([0.7, 0.7]),
            outside_length=np.array([0.3, 0.3]), end_label=np.zeros(2, dtype=np.int64),
            vertex_label=np.zeros(3, dtype=np.int64))

    p = saddle_penalties(graph(MAXIMUM), 1e-2)
    assert p.n_components == 2 and p.unreachable_pairs == 1
    np.testing.assert_array_equal(p.weights, [0.0, 0.0, 0.0])
    q = saddle_penalties(graph(SADDLE), 1e-2)
    assert q.n_components == 2 and q.unreachable_pairs == 0
    np.testing.assert_allclose(q.weights, [0.0, 0.0, 1.0])
    assert q.raw_total == pytest.approx(1.0 / (0.6 + 1e-2))


def test_warm_update_drops_a_merged_saddle():
    """Three disks in a row, both saddles penalised (weight 1/2 each). A tilt f + 0.3 x pushes the
    left saddle inside the shape (f = 0.05 - 0.09 < 0): the warm update keeps the right saddle,
    re-converged to where a full build finds it, and drops the merged one; the loss is that
    saddle's value at its old weight 1/2 (half the rebuilt loss, which renormalises to 1)."""
    tilt = torch.zeros(1, dtype=DT)
    base = blobs([[-0.6, 0.0], [0.0, 0.0], [0.6, 0.0]], 0.25)

    def f(x, z=None):
        return base(x) + float(tilt[0]) * x[:, 0]

    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=100), dtype=DT, options=TIGHT)
    loss_fn(f, None)
    _, _, p = loss_fn.penalised_points()
    np.testing.assert_allclose(p.numpy(), [0.5, 0.5])
    tilt[0] = 0.3
    warm = loss_fn(f, None)
    assert loss_fn.last_info["update"] == "warm" and loss_fn.last_info["n_merged"] == 1
    x, _, p = loss_fn.penalised_points()
    fresh = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=100), dtype=DT, options=TIGHT)
    rebuilt = fresh(f, None)
    assert fresh.last_info["n_components"] == [2]
    xf, _, pf = fresh.penalised_points()
    np.testing.assert_allclose(x.numpy(), xf.numpy(), atol=1e-8)
    assert float(x[0, 0]) > 0.3  # the right saddle, moved by the tilt
    np.testing.assert_allclose(p.numpy(), [0.5])
    np.testing.assert_allclose(pf.numpy(), [1.0])
    assert float(warm) == pytest.approx(0.5 * float(rebuilt), abs=1e-10)


def test_state_dict_round_trip(tmp_path):
    """A loss restored from a checkpoint continues exactly as the original: the same kind of update
    (warm, not a rebuild) and the same value, bitwise; the state is pickle-free (weights_only)."""
    f = blobs([[-0.45, -0.2], [0.5, 0.25]], 0.25)
    a = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=10), dtype=DT, options=TIGHT)
    la = a(f, None)
    assert float(la) > 0 and a.last_info["n_components"] == [2]
    torch.save(a.state_dict(), tmp_path / "state.pt")
    state = torch.load(tmp_path / "state.pt", weights_only=True)
    b = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=10), dtype=DT, options=TIGHT)
    b.load_state_dict(state)
    la2, lb = a(f, None), b(f, None)
    assert a.last_info["update"] == b.last_info["update"] == "warm"
    assert float(lb) == float(la2)
    assert int(b.state_dict()["step"]) == 2
    # the first format (points only) still loads: the next call rebuilds from the stored points
    old = {"points_x": state["points"]["x"], "points_shape": state["points"]["shape"], "latents": state["latents"],
           "step": torch.tensor(1), "last_full": torch.tensor(0)}
    c = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=10), dtype=DT, options=TIGHT)
    c.load_state_dict(old)
    lc = c(f, None)
    assert c.last_info["update"] == "full"
    assert float(lc) == pytest.approx(float(la), abs=1e-10)


# --- persistent homology --------------------------------------------------------------------


def test_death_points_of_a_small_array():
    a = np.ones((5, 9))
    a[2, 1], a[2, 7] = -1.0, -2.0
    a[2, 2:7] = [0.2, 0.2, 0.5, 0.3, 0.3]
    dp = death_points(a)
    assert dp.n_components == 2
    np.testing.assert_array_equal(dp.index, [[2, 4]])
    np.testing.assert_allclose(dp.value, [0.5])
    np.testing.assert_allclose(dp.birth, [-1.0])


def test_persistent_homology_finds_the_same_saddle():
    f = blobs([[-0.45, -0.2], [0.5, 0.25]], 0.25)
    cfg = ConnectednessConfig(method="persistent-homology", grid=65)
    ph = make_connectedness_loss(BOX2, None, cfg, dtype=DT)
    loss = ph(f, None)
    x, _, p = ph.last_points
    h = 2.0 / 64
    assert x.shape == (1, 2)
    assert np.abs(x[0].numpy() - [0.025, 0.025]).max() <= h
    np.testing.assert_allclose(p.numpy(), [1.0])
    assert ph.last_info["n_components"] == [2]
    assert float(loss) == pytest.approx(float(f(x)[0]), abs=1e-12)
    refined = make_connectedness_loss(BOX2, None, cfg, dtype=DT, options=PersistenceOptions(refine_steps=8))
    refined(f, None)
    np.testing.assert_allclose(refined.last_points[0][0].numpy(), [0.025, 0.025], atol=1e-4)


def test_factory_switch():
    sn = make_connectedness_loss(BOX2, None, ConnectednessConfig(), dtype=DT)
    assert isinstance(sn, ConnectednessLoss)
    with pytest.raises(ValueError):
        make_connectedness_loss(BOX2, None, ConnectednessConfig().model_copy(update={"method": "nope"}))


# --- component counting ---------------------------------------------------------------------


def test_label_components_2d_and_3d():
    m = np.zeros((6, 6), dtype=bool)
    m[0:2, 0:2] = True
    m[3:6, 4] = True
    m[2, 2] = True  # touches the first block only diagonally
    labels, n = label_components(m)
    assert n == 3 and b0_of_mask(m) == 3 and b0_of_mask(m, connectivity=2) == 2
    np.testing.assert_array_equal(np.sort(component_sizes(labels, n)), [1, 3, 4])
    v = np.zeros((4, 4, 4), dtype=bool)
    v[0, 0, 0] = v[3, 3, 3] = v[0, 3, 0] = True
    v[1, 3, 0] = True
    assert b0_of_mask(v) == 3
    assert b0_of_mask(np.zeros((3, 3), dtype=bool)) == 0


def test_count_components_with_region():
    vals = np.array([[-1, 1, -1, 1, -1]], dtype=float)
    assert count_components(vals) == 3
    assert count_components(vals, region_mask=np.array([[1, 1, 1, 0, 0]], dtype=bool)) == 2
    assert count_components(vals, level=1.0) == 1


def test_b0_of_fields():
    f2 = blobs([[-0.5, 0.0], [0.5, 0.0]], 0.25)
    f3 = blobs([[-0.7, 0.0], [0.0, 0.0], [0.8, 0.0]], 0.2)
    assert b0(f2, None, BOX2, 64).tolist() == [2]
    assert b0(f3, None, BOX2, 64).tolist() == [3]
    assert b0(f3, None, BOX2, 64, region=_HalfPlane(-0.3)).tolist() == [2]
    s3 = blobs([[-0.45, 0.1, -0.1], [0.45, -0.1, 0.2]], 0.25)
    assert b0(s3, None, BOX3, 24).tolist() == [2]

    def batched(x, z):
        return f2(x) - 0.3 * z[:, 0]  # z = 1 grows both disks until they touch

    assert b0(batched, torch.tensor([[0.0], [1.0]], dtype=DT), BOX2, 64).tolist() == [2, 1]


# --- training ---------------------------------------------------------------------------------


def _fitted_two_disk_siren(steps=600):
    from ginn.models import Siren

    torch.manual_seed(0)
    C = torch.tensor([[-0.5, 0.0], [0.5, 0.0]])
    model = Siren(2, [32, 32, 32], w0_first=2.0)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    sched = torch.optim.lr_scheduler.StepLR(opt, steps // 3, 0.3)
    g = torch.Generator().manual_seed(0)
    for _ in range(steps):
        x = torch.rand(1024, 2, generator=g) * 2 - 1
        target = ((x[:, None, :] - C[None]).norm(dim=-1) - 0.25).min(dim=1).values
        loss = ((model(x) - target) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
    th = torch.linspace(-np.pi / 2, np.pi / 2, 64)
    right = torch.stack([0.5 + 0.25 * torch.cos(th), 0.25 * torch.sin(th)], 1)
    interface = torch.cat([right * torch.tensor([-1.0, 1.0]), right])  # the outer half circles
    return model, interface


@pytest.mark.slow
@pytest.mark.parametrize("method", ["surface-network", "persistent-homology"])
def test_training_connects_two_disks(method):
    """A SIREN fitted to two disks (b0 = 2); interface loss on their outer halves plus the
    connectedness loss: b0 becomes 1 within 300 Adam steps; without it, it stays 2."""
    box = BOX2
    results = {}
    for weight in (0.0, 0.1):
        model, xi = _fitted_two_disk_siren()
        assert b0(model, None, box, 128).tolist() == [2]
        cfg = ConnectednessConfig(method=method, every=10, grid=16 if method == "surface-network" else 64)
        conn = make_connectedness_loss(box, None, cfg)
        opt = torch.optim.Adam(model.parameters(), lr=1e-4)
        steps = None
        for i in range(300 if weight > 0 else 60):
            loss = (model(xi) ** 2).mean() + weight * conn(model, None)
            opt.zero_grad()
            loss.backward()
            opt.step()
            if b0(model, None, box, 128).tolist() == [1]:
                steps = i + 1
                break
        results[weight] = steps
    assert results[0.0] is None  # the interface loss alone keeps the two components
    assert results[0.1] is not None and results[0.1] <= 300


@pytest.mark.cuda
@pytest.mark.parametrize("method", ["surface-network", "persistent-homology"])
def test_losses_on_cuda(method):
    """Both losses with the field and latents on a GPU: same penalised saddle as on the CPU."""
    C = torch.tensor([[-0.5, 0.0], [0.5, 0.0]], dtype=DT, device="cuda")

    def field(x, z):
        c = C[None] + z[:, None, :] * torch.tensor([0.0, 0.3], dtype=DT, device="cuda")
        d = torch.sqrt(((x[:, None, :] - c) ** 2).sum(-1) + DELTA**2) - 0.25
        return -K * torch.logsumexp(-d / K, dim=1)

    Z = torch.tensor([[0.0], [1.0]], dtype=DT, device="cuda")
    cfg = ConnectednessConfig(method=method, grid=16 if method == "surface-network" else 65)
    loss_fn = make_connectedness_loss(BOX2, _HalfPlane(-0.95), cfg, device="cuda", dtype=DT)
    loss = loss_fn(field, Z)
    assert loss.device.type == "cuda"
    assert loss_fn.last_info["n_components"] == [2, 2]
    x = loss_fn.penalised_points()[0] if method == "surface-network" else loss_fn.last_points[0]
    x = x.cpu().numpy()
    expected = np.array([[0.0, 0.0], [0.0, 0.3]])
    tol = 1e-3 if method == "surface-network" else 2.0 / 64
    assert np.abs(np.sort(x, axis=0) - expected).max() <= tol


def test_margin_sees_a_thin_neck_as_a_gap():
    """Two disks of radius 0.25 whose smooth union has a thin neck (saddle value about -0.02):
    the paper's loss ({f <= 0}) sees one component and costs nothing; with a margin of 0.05 (the
    field shifted by +0.05, as ``connectedness.margin`` does) the neck is a gap: two components,
    all weight on the neck's saddle, loss = f(saddle) + 0.05 and d loss / d shift = 1."""
    from ginn.fields import Shifted

    shift = torch.nn.Parameter(torch.zeros((), dtype=DT))
    f = blobs([[-0.27, 0.0], [0.27, 0.0]], 0.25, shift=shift)
    saddle = torch.zeros(1, 2, dtype=DT)
    f0 = float(f(saddle)[0])
    assert -0.05 < f0 < 0  # a neck thinner than the margin
    plain = ConnectednessLoss(BOX2, None, ConnectednessConfig(), dtype=DT, options=TIGHT)
    assert plain(f, None).item() == 0.0 and plain.last_info["n_components"] == [1]
    margin = ConnectednessLoss(BOX2, None, ConnectednessConfig(), dtype=DT, options=TIGHT)
    loss = margin(Shifted(f, 0.05), None)
    assert margin.last_info["n_components"] == [2]
    x, _, p = margin.penalised_points()
    np.testing.assert_allclose(x.numpy(), [[0.0, 0.0]], atol=1e-6)
    assert loss.item() == pytest.approx(f0 + 0.05, abs=1e-10)
    loss.backward()
    assert float(shift.grad) == pytest.approx(1.0)


def test_region_lookup_answers_exactly_like_the_region():
    """The grid lookup of a CSG region (1-Lipschitz SDF) gives region.contains for every point,
    including points within a grid cell of the boundary and outside the grid's box."""
    from ginn.geometry import Difference, Disk, Polygon, Rectangle, Transformed, rotation_matrix
    from ginn.geometry.lookup import RegionLookup, fast_membership

    region = Difference(Rectangle((-0.8, -0.6), (0.8, 0.6)), Disk((0.2, 0.1), 0.3),
                        Transformed(Polygon([(0.0, 0.0), (0.3, 0.0), (0.15, 0.25)]), rotation_matrix(2, 30), (-0.5, -0.3)))
    assert region.lipschitz
    look = RegionLookup(region, BOX2, cells=32)
    g = torch.Generator().manual_seed(0)
    x = torch.rand(20000, 2, generator=g, dtype=DT) * 2.4 - 1.2  # beyond the box too
    # and points close to the boundary: on the disk's circle, pushed by less than a cell
    th = torch.rand(5000, generator=g, dtype=DT) * 2 * torch.pi
    near = torch.stack([0.2 + 0.3 * th.cos(), 0.1 + 0.3 * th.sin()], -1) + (torch.rand(5000, 2, generator=g, dtype=DT) - 0.5) * 0.02
    for pts in (x, near):
        assert torch.equal(look.contains(pts), region.contains(pts))
    assert fast_membership(_WithoutDisk(0.15), BOX2).__class__ is _WithoutDisk  # not Lipschitz: unchanged


def test_the_fastest_membership_is_the_region_or_its_lookup_and_samples_the_same_points():
    """Whichever answers faster, the samples outside E drawn through it are the very points drawn
    through E itself (the same accept decisions from the same random stream)."""
    from ginn.geometry import Difference, Disk, Rectangle, sampling
    from ginn.geometry.lookup import RegionLookup, fastest_membership

    region = Difference(Rectangle((-0.8, -0.6), (0.8, 0.6)), Disk((0.2, 0.1), 0.3), Disk((-0.4, -0.2), 0.1))
    chosen = fastest_membership(region, BOX2, cells=32)
    assert chosen is region or (isinstance(chosen, RegionLookup) and chosen.region is region)
    for R in (chosen, RegionLookup(region, BOX2, cells=32)):
        a = sampling.sample_outside(R, BOX2, 3000, torch.Generator().manual_seed(3), dtype=DT)
        b = sampling.sample_outside(region, BOX2, 3000, torch.Generator().manual_seed(3), dtype=DT)
        assert torch.equal(a, b)
    assert fastest_membership(_WithoutDisk(0.15), BOX2).__class__ is _WithoutDisk
    assert fastest_membership(None, BOX2) is None


def test_surface_network_is_the_same_with_the_region_lookup():
    """Tracing with the grid lookup of the design region gives the very same network (paths,
    lengths, anchors) as tracing with the region itself."""
    from ginn.geometry import Difference, Disk, Rectangle
    from ginn.geometry.lookup import RegionLookup

    f = blobs([[-0.7, 0.0], [0.0, 0.1], [0.8, 0.0]], 0.2)
    region = Difference(Rectangle((-0.95, -0.5), (0.95, 0.5)), Disk((0.4, -0.3), 0.12))
    cp = find_critical_points(f, None, BOX2, 16, options=TIGHT.critical, dtype=DT)
    a = trace_surface_network(f, None, BOX2, cp, 16, region=region)
    b = trace_surface_network(f, None, BOX2, cp, 16, region=RegionLookup(region, BOX2, cells=24))
    for k in ("path_start", "path_end", "path_descending", "path_length", "path_outside_length", "ends"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    np.testing.assert_array_equal(np.isnan(a.path_anchor), np.isnan(b.path_anchor))
    np.testing.assert_array_equal(np.nan_to_num(a.path_anchor), np.nan_to_num(b.path_anchor))
    assert np.isfinite(a.path_anchor).any()


def test_anchor_is_each_paths_last_candidate_in_the_region():
    """Anchors are resolved after the tracing from the candidates in the order they were reached:
    the last one inside the region per path, NaN for a path with none."""
    from ginn.geometry import Rectangle
    from ginn.topology.surface_network import _last_inside

    left = Rectangle((-1.0, -1.0), (0.0, 1.0))  # x <= 0
    path = torch.tensor([0, 1, 0, 2, 0, 1])
    x = torch.tensor([[-0.5, 0.0], [-0.2, 0.1], [-0.1, 0.3], [0.4, 0.0], [0.3, 0.2], [-0.6, -0.4]], dtype=DT)
    a = _last_inside(path, x, 4, left)
    # path 0: candidates 0, 2 (inside) and 4 (outside) -> 2; path 1: 1 and 5 -> 5; path 2: only 3 (outside)
    assert torch.equal(a[0], x[2]) and torch.equal(a[1], x[5])
    assert torch.isnan(a[2]).all() and torch.isnan(a[3]).all()
    b = _last_inside(path, x, 4, None)  # no region: every candidate counts
    assert torch.equal(b[0], x[4]) and torch.equal(b[2], x[3])


def test_paths_are_traced_only_from_saddles_in_E_with_the_same_penalties():
    """Paths from a saddle outside E join nothing (shape_components, saddle_penalties): tracing
    from the saddles in E alone gives exactly the other paths, the same components and penalties."""
    from ginn.topology.penalties import batch_penalties

    f = blobs([[-0.7, 0.0], [-0.1, 0.0], [0.35, 0.2], [0.8, -0.1]], 0.18)
    region = _HalfPlane(-0.3)
    cp = find_critical_points(f, None, BOX2, 16, options=TIGHT.critical, dtype=DT)
    valid = region.contains(cp.x)
    every = trace_surface_network(f, None, BOX2, cp, 16, region=region)
    some = trace_surface_network(f, None, BOX2, cp, 16, region=region, sources=valid)
    kept = valid.numpy()[every.path_start]
    assert 0 < some.n_paths == int(kept.sum()) < every.n_paths
    for k in ("path_start", "path_end", "path_descending", "path_length", "path_outside_length", "ends"):
        np.testing.assert_array_equal(getattr(every, k)[kept], getattr(some, k))
    a, ra = batch_penalties(every, valid.numpy(), 1, 0.01)
    b, rb = batch_penalties(some, valid.numpy(), 1, 0.01)
    np.testing.assert_array_equal(a, b)
    assert ra[0].n_components == rb[0].n_components == 3 and a.sum() == pytest.approx(1.0)
    # the loss traces from its saddles in E: its penalties are those of tracing every saddle
    loss_fn = ConnectednessLoss(BOX2, region, ConnectednessConfig(), dtype=DT, options=TIGHT)
    loss_fn(f, None)
    pts = loss_fn.points
    full = trace_surface_network(f, None, BOX2, pts, loss_fn.config.grid, TIGHT.paths, region=region)
    c, _ = batch_penalties(full, region.contains(pts.x).numpy(), 1, loss_fn.config.eps,
                           loss_fn._grid_labels(f, None), BOX2)
    np.testing.assert_array_equal(loss_fn.penalty, c)
    assert loss_fn.network.n_paths == full.n_paths - int((~region.contains(pts.x).numpy())[full.path_start].sum())


def test_full_builds_back_off_while_every_shape_is_whole():
    """Full builds at calls 0, 10, 30, 50 for one disk (every = 5: the interval doubles after
    each build with nothing to penalise, up to 4 x 5), and at every fifth call for two disks."""

    def builds(f) -> list[int]:
        loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=5), dtype=DT, options=TIGHT)
        out = []
        for call in range(60):
            loss_fn(f, None)
            if loss_fn.last_info["update"] == "full":
                out.append(call)
        return out

    assert builds(blobs([[0.0, 0.0]], 0.3)) == [0, 10, 30, 50]
    assert builds(blobs([[-0.5, 0.0], [0.5, 0.0]], 0.25)) == list(range(0, 60, 5))


def test_backoff_returns_to_every_when_a_shape_comes_apart():
    """After two idle builds (calls 0 and 10: interval 20) a shape that splits at call 16 is found
    by the scheduled build at call 30 and rebuilt every 5 calls from then on; the interval
    survives a state round trip."""
    apart = torch.zeros(1, dtype=DT)
    one, two = blobs([[0.0, 0.0]], 0.3), blobs([[-0.5, 0.0], [0.5, 0.0]], 0.25)

    def f(x, z=None):
        return two(x) if float(apart[0]) else one(x)

    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=5), dtype=DT, options=TIGHT)
    for _ in range(16):
        loss_fn(f, None)
    assert loss_fn.interval == 20
    restored = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=5), dtype=DT, options=TIGHT)
    restored.load_state_dict(loss_fn.state_dict())
    assert restored.interval == 20
    apart[0] = 1.0
    kinds = []
    for _ in range(30):
        restored(f, None)
        kinds.append(restored.last_info["update"])
    assert [i + 16 for i, k in enumerate(kinds) if k == "full"] == [30, 35, 40, 45]
    assert restored.last_info["n_components"] == [2] and restored.interval == 5


def _by_latent(*fields):
    """A two-shape field: ``fields[i]`` where the latent code is ``i``."""

    def f(x, z):
        which = z[:, 0].round().long()
        return torch.stack([g(x) for g in fields], dim=1).gather(1, which[:, None])[:, 0]

    return f


def test_each_shape_keeps_its_own_build_schedule():
    """Shape 0 one disk, shape 1 two: shape 0 is built at calls 0, 10, 30, 50 (its interval
    doubles up to 4 x 5 while nothing is penalised on it) and shape 1 at every fifth call; a build
    of shape 1 alone leaves shape 0's vertices and paths as they were and gives shape 1 the
    penalised saddle and weight a build of both finds."""
    one, two = blobs([[0.0, 0.0]], 0.3), blobs([[-0.5, 0.0], [0.5, 0.0]], 0.25)
    f, Z = _by_latent(one, two), torch.tensor([[0.0], [1.0]], dtype=DT)
    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=5), dtype=DT, options=TIGHT)
    built: list[list[int]] = [[], []]
    for call in range(60):
        loss_fn(f, Z)
        for s in (0, 1):
            if loss_fn.last_full[s] == call:
                built[s].append(call)
        if call == 5:
            assert loss_fn.last_info["update"] == "partial" and loss_fn.last_info["rebuilt"] == 1
            fresh = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=5), dtype=DT, options=TIGHT)
            fresh(f, Z)
            x, sh, p = loss_fn.penalised_points()
            xf, shf, pf = fresh.penalised_points()
            np.testing.assert_allclose(x.numpy(), xf.numpy(), atol=1e-8)
            assert sh.tolist() == shf.tolist() == [1]
            np.testing.assert_allclose(p.numpy(), pf.numpy())
            assert loss_fn.last_info["n_components"] == fresh.last_info["n_components"] == [1, 2]
            net = loss_fn.network
            assert net.points.shape.tolist() == sorted(net.points.shape.tolist())
            starts, ends = net.path_start, net.path_end[net.path_end >= 0]
            same = net.points.shape[torch.from_numpy(net.path_end[net.path_end >= 0])]
            assert same.tolist() == net.points.shape[torch.from_numpy(starts[net.path_end >= 0])].tolist()
            assert len(ends) == len(fresh.network.edges)
    assert built == [[0, 10, 30, 50], list(range(0, 60, 5))]
    assert loss_fn.interval.tolist() == [20, 5]
    restored = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=5), dtype=DT, options=TIGHT)
    restored.load_state_dict(loss_fn.state_dict())
    assert restored.interval.tolist() == [20, 5] and restored.last_full.tolist() == [50, 55]


def test_moving_codes_are_held_between_builds_and_back_off_as_fixed_ones():
    """Codes that move at every call (a lattice draw): each shape is judged at the code of its last
    build until its next one (the loss evaluates the field only there), and a shape found whole
    waits twice as long for its next build, up to four times ``every``, as with fixed codes."""
    one, two = blobs([[0.0, 0.0]], 0.3), blobs([[-0.5, 0.0], [0.5, 0.0]], 0.25)
    seen: list[float] = []

    def f(x, z):
        seen.extend(z[:, 0].tolist())
        return torch.where(z[:, 0] < 0.5, one(x), two(x))

    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=5), dtype=DT, options=TIGHT)
    built: list[list[int]] = [[], []]
    codes = torch.zeros(2, 1, dtype=DT)
    for call in range(30):
        z = torch.tensor([[0.1 + 0.01 * call], [0.6 + 0.01 * call]], dtype=DT)
        seen.clear()
        loss_fn(f, z)
        for k in (0, 1):
            if loss_fn.last_full[k] == call:
                built[k].append(call)
                codes[k] = z[k]
        assert torch.equal(loss_fn._latents, codes)  # each shape at the code of its last build
        if loss_fn.last_info["update"] == "warm":
            assert set(seen) <= set(codes[:, 0].tolist())
    assert built == [[0, 10], [0, 5, 10, 15, 20, 25]]  # whole: 10 then 20 calls; in two pieces: every 5
    assert loss_fn.interval.tolist() == [20, 5]


def test_a_saddle_the_warm_update_loses_is_dropped_until_the_scheduled_build():
    """Both shapes two disks, penalised saddles; shape 1 then becomes one disk at the origin (its
    saddle is now a minimum: the warm update cannot re-converge it). Its weight goes to 0 while
    shape 0's saddle is re-converged and keeps its weight; nothing is built before the next
    scheduled call (every 4th), where both shapes, penalised at their last build, are built and
    shape 1 is one piece."""
    merged = torch.zeros(1, dtype=DT)
    two, joined = blobs([[-0.5, 0.0], [0.5, 0.0]], 0.25), blobs([[0.0, 0.0]], 0.35)

    def second(x):
        return joined(x) if float(merged[0]) else two(x)

    f, Z = _by_latent(two, second), torch.tensor([[0.0], [1.0]], dtype=DT)
    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(every=4), dtype=DT, options=TIGHT)
    loss_fn(f, Z)
    assert loss_fn.last_info["n_components"] == [2, 2]
    x0, _, _ = loss_fn.penalised_points()
    merged[0] = 1.0
    loss = loss_fn(f, Z)
    info = loss_fn.last_info
    assert info["update"] == "warm" and info["warm_failed"] == 1 and loss_fn.last_full.tolist() == [0, 0]
    x, sh, p = loss_fn.penalised_points()
    assert sh.tolist() == [0] and float(p[0]) == 1.0
    np.testing.assert_allclose(x.numpy(), x0[:1].numpy(), atol=1e-8)
    assert float(loss) == pytest.approx(float(two(x)[0]) / 2, abs=1e-10)  # the mean over 2 shapes
    loss_fn(f, Z), loss_fn(f, Z)
    assert loss_fn.last_info["update"] == "warm"
    loss_fn(f, Z)
    assert loss_fn.last_info["update"] == "full" and loss_fn.last_info["n_components"] == [2, 1]


def test_grid_splits_joined_between_the_nodes_are_not_penalised():
    """A death node of the label grid is a split of the shape only when no saddle of the field
    with f <= 0 lies within two cells: two disks whose smooth union has its neck saddle at
    f = -0.010 are joined (left out), the same disks 0.06 farther apart (saddle f = +0.019) are
    not; a node outside E is always left out (lowering f there joins nothing inside E)."""
    loss_fn = ConnectednessLoss(BOX2, None, ConnectednessConfig(), dtype=DT, options=TIGHT)
    pos = torch.tensor([[0.04, 0.03]], dtype=DT)
    joined, apart = blobs([[-0.27, 0.0], [0.27, 0.0]], 0.25), blobs([[-0.3, 0.0], [0.3, 0.0]], 0.25)
    assert float(joined(torch.zeros(1, 2, dtype=DT))[0]) == pytest.approx(-0.0101, abs=1e-3)
    assert float(apart(torch.zeros(1, 2, dtype=DT))[0]) == pytest.approx(0.0190, abs=1e-3)
    inside = np.array([True])
    assert loss_fn._real_splits(joined, None, np.zeros(1, np.int64), pos, inside, 0.0625).tolist() == [False]
    assert loss_fn._real_splits(apart, None, np.zeros(1, np.int64), pos, inside, 0.0625).tolist() == [True]
    assert loss_fn._real_splits(apart, None, np.zeros(1, np.int64), pos, ~inside, 0.0625).tolist() == [False]
