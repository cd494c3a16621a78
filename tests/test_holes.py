"""The loss toward target Betti numbers (ginn.topology.holes) on analytic fields with known
persistence: a ring's hole is born on the ring (at minus half its width) and dies at its centre
(at the hole's radius)."""

import numpy as np
import pytest
import torch

from ginn.geometry import csg
from ginn.geometry.base import Box
from ginn.geometry.primitives import AABox, Ball
from ginn.topology import betti_numbers
from ginn.topology.holes import HoleCountLoss, feature_moves, ring_cells

N = 65
XS = np.linspace(-1, 1, N)
X, Y = np.meshgrid(XS, XS, indexing="ij")
R = np.hypot(X, Y)
M = 2 / (N - 1)  # the margin: one cell


def ring(radius, half_width, cx=0.0):
    return np.abs(np.hypot(X - cx, Y) - radius) - half_width


def _at(cell):
    return np.array([XS[cell[0]], XS[cell[1]]])


def test_a_thin_ring_is_opened_and_a_thick_one_filled():
    # thin: opening needs m + 0.05, filling m + 0.55: the birth cell (on the ring) goes up
    mv = feature_moves(ring(0.6, 0.05), {1: 0}, M)
    assert mv.counts == {1: 1} and len(mv.index) == 1 and mv.raise_.tolist() == [True]
    assert abs(np.hypot(*_at(mv.index[0])) - 0.6) <= 0.05 + M
    # thick ring round a hole of radius 0.1: filling needs m + 0.1, opening m + 0.35: the death cell (centre) goes down
    mv = feature_moves(ring(0.45, 0.35), {1: 0}, M)
    assert mv.raise_.tolist() == [False] and np.hypot(*_at(mv.index[0])) <= M


def test_a_hole_round_a_part_outside_E_can_only_be_opened():
    outside = R <= 0.15
    values = ring(0.45, 0.35).copy()
    top = float(np.abs(values).max()) + 1.0
    values[outside] = top
    mv = feature_moves(values, {1: 0}, M, outside, top)
    assert mv.counts == {1: 1} and mv.raise_.tolist() == [True]
    assert np.hypot(*_at(mv.index[0])) > 0.15  # a cell of the ring, not of the region outside E


def test_kept_missing_and_surplus_holes():
    wide = ring(0.6, 0.2)  # born at -0.2, dies at 0.4: held with the margin, nothing to do
    mv = feature_moves(wide, {1: 1}, M)
    assert mv.counts == {1: 1} and len(mv.index) == 0
    # a disk with a bump inside that stays below 0: a hole that died at -0.3; a target of 1 raises it
    dimple = R - 0.7 + 0.4 * np.exp(-(R / 0.15) ** 2)
    mv = feature_moves(dimple, {1: 1}, M)
    assert mv.counts == {1: 0} and mv.raise_.tolist() == [True] and np.hypot(*_at(mv.index[0])) <= M
    # two rings, one wanted: one goes (opened: the thin rings are cheaper to open than to fill)
    two = np.minimum(ring(0.25, 0.1, 0.45), ring(0.3, 0.1, -0.45))
    mv = feature_moves(two, {1: 1}, M)
    assert mv.counts == {1: 2} and mv.raise_.tolist() == [True]
    assert feature_moves(two, {1: 2}, M).index.shape == (0, 2)

def test_a_solid_part_is_seeded_at_the_centres_of_disjoint_inscribed_balls():
    # a disk has no dimension-1 feature at any level: its hole is opened at its centre, the deepest node
    mv = feature_moves(R - 0.5, {1: 1}, M)
    up = mv.index[mv.raise_]
    assert mv.counts == {1: 0} and len(up) == 1 and np.hypot(*_at(up[0])) <= 1e-12
    # a 1.6 x 0.4 bar (depth 0.2 along its axis): two holes wanted, two seeds at least 0.4 apart on the axis
    bar = np.maximum(np.abs(X) - 0.8, np.abs(Y) - 0.2)
    mv = feature_moves(bar, {1: 2}, M)
    up = mv.index[mv.raise_]
    assert len(up) == 2
    a, b = _at(up[0]), _at(up[1])
    assert abs(a[1]) <= 1e-12 and abs(b[1]) <= 1e-12 and abs(a[0] - b[0]) >= 0.4 - 1e-12
    assert max(abs(a[0]), abs(b[0])) <= 0.6 + 1e-12  # depth 0.2 within 0.6 of the centre
    # a part thinner than the margin cannot host a hole
    assert feature_moves(np.maximum(np.abs(X) - 0.8, np.abs(Y) - 0.5 * M), {1: 1}, M).index.shape == (0, 2)


def test_a_seed_stays_where_it_was_put_until_its_node_leaves_the_shape():
    # a 1.6 x 0.4 bar: one hole wanted, seeded at the deepest node (on the axis, depth 0.2)
    bar = np.maximum(np.abs(X) - 0.8, np.abs(Y) - 0.2)
    first = feature_moves(bar, {1: 1}, M)
    cell = first.seeds[1][0]
    assert first.index[first.raise_].tolist() == [cell.tolist()] and abs(_at(cell)[1]) <= 1e-12
    # the push has dented the field there (depth 0.2 -> 0.05): afresh, a deeper node elsewhere is chosen
    dent = bar + 0.15 * np.exp(-(((X - _at(cell)[0]) ** 2 + Y**2) / 0.1**2))
    afresh = feature_moves(dent, {1: 1}, M)
    assert np.abs(_at(afresh.index[0]) - _at(cell)).max() >= 0.1
    # with the previous seeds the dent keeps being pushed
    kept = feature_moves(dent, {1: 1}, M, seeds=first.seeds)
    assert kept.index[kept.raise_].tolist() == [cell.tolist()]
    # two wanted: the kept seed first, the new one deepest among the nodes whose ball avoids the dent's
    two = feature_moves(dent, {1: 2}, M, seeds=first.seeds)
    up = two.index[two.raise_]
    assert up[0].tolist() == cell.tolist()
    assert np.hypot(*(_at(up[1]) - _at(cell))) >= 0.2 + 0.05 - 1e-12
    # once the node is outside the shape (the dent went through, f > 0) the seed is given up
    through = bar + 0.25 * np.exp(-(((X - _at(cell)[0]) ** 2 + Y**2) / 0.1**2))
    assert through[tuple(cell)] > 0
    after = feature_moves(through, {1: 2}, M, seeds=first.seeds)
    assert after.counts == {1: 1} and cell.tolist() not in after.seeds[1].tolist()


def test_a_seed_in_a_strip_thinner_than_its_wall_thickens_the_strip_round_the_hole():
    # a strip 0.1 wide (depth 0.05, under two cells): a smooth field raised at its axis node rises
    # across the strip's width; the wall keeps material round the hole
    strip = np.abs(Y) - 0.05
    mv = feature_moves(np.maximum(strip, np.abs(X) - 0.8), {1: 1}, M)
    up, down = mv.index[mv.raise_], mv.index[~mv.raise_]
    assert len(up) == 1 and abs(_at(up[0])[1]) <= 1e-12
    # the wall: every node 2 to 2 + sqrt(2) cells from the seed, all held at -m
    dist = np.hypot(*(np.stack([_at(c) for c in down]) - _at(up[0])).T)
    assert dist.min() >= 2 * M - 1e-12 and dist.max() < (2 + np.sqrt(2)) * M
    assert sorted(map(tuple, down.tolist())) == sorted(map(tuple, ring_cells(strip.shape, up[0], M, np.full(2, M)).tolist()))
    # with the moves made, the strip is one piece with one hole, walled two cells either side
    v = np.maximum(strip, np.abs(X) - 0.8)
    v[tuple(down.T)] = np.minimum(v[tuple(down.T)], -M)
    v[tuple(up.T)] = M
    assert list(betti_numbers(v <= 0)[:2]) == [1, 1]
    i, j = up[0]
    assert v[i, j + 2] <= -M and v[i, j - 2] <= -M and strip[i, j + 2] > 0


def test_the_wall_is_a_connected_shell_clipped_to_the_grid():
    # 2D: the 28 nodes with 4 <= i^2 + j^2 < (2 + sqrt 2)^2 = 11.66 (i, j integers)
    for d, n in ((2, 28), (3, 176)):
        cells = ring_cells((11,) * d, np.full(d, 5), 1.0, np.ones(d))
        dist = np.linalg.norm(cells - 5, axis=1)
        assert len(cells) == n and (dist >= 2).all() and (dist < 2 + np.sqrt(d)).all()
        grid = np.zeros((11,) * d, bool)
        grid[tuple(cells.T)] = True
        assert list(betti_numbers(grid)) == [1, 1] if d == 2 else [1, 0, 1]  # one loop / one closed surface
    # anisotropic spacing: distances in the units of the spacing
    wide = ring_cells((41, 41), np.array([20, 20]), 1.0, np.array([1.0, 0.5]))
    assert np.ptp(wide[:, 1]) == 2 * np.ptp(wide[:, 0])
    # at a corner only the nodes inside the grid remain
    corner = ring_cells((9, 9), np.array([0, 0]), 1.0, np.ones(2))
    assert (corner >= 0).all() and len(corner) == 9  # the quarter with i, j >= 0


def test_seeds_skip_nodes_outside_E_and_tunnels_are_not_seeded():
    outside = R <= 0.15  # the disk's deepest nodes lie outside E
    values = R - 0.5
    top = float(np.abs(values).max()) + 1.0
    values = np.where(outside, top, values)
    mv = feature_moves(values, {1: 2}, M, outside, top)
    assert mv.counts == {1: 1}  # the hole round the part outside E
    assert mv.raise_.any() and not outside[tuple(mv.index.T)].any()


def test_raising_the_seeds_gives_the_target_betti_numbers():
    bar = np.maximum(np.abs(X) - 0.8, np.abs(Y) - 0.2)
    for target in (1, 2, 3):
        mv = feature_moves(bar, {1: target}, M)
        v = bar.copy()
        v[tuple(mv.index.T)] = np.where(mv.raise_, M, np.minimum(v[tuple(mv.index.T)], -M))
        assert list(betti_numbers(v <= 0)[:2]) == [1, target]
    # 3D: a plate |z| <= 0.2 is pierced along z through its centre (a tunnel), a ball gets a cavity
    g = np.linspace(-1, 1, 21)
    h = g[1] - g[0]
    gx, gy, gz = np.meshgrid(g, g, g, indexing="ij")
    plate = np.maximum(np.maximum(np.abs(gx), np.abs(gy)) - 0.8, np.abs(gz) - 0.2 + 0.1 * (gx**2 + gy**2))
    mv = feature_moves(plate, {1: 1}, h)
    assert mv.raise_.all() and (mv.index[:, :2] == 10).all()
    assert set(range(8, 13)) <= set(mv.index[:, 2].tolist()) <= set(range(7, 14))
    v = plate.copy()
    v[tuple(mv.index.T)] = h
    assert list(betti_numbers(v <= 0)) == [1, 1, 0]
    ball = np.sqrt(gx**2 + gy**2 + gz**2) - 0.6
    mv = feature_moves(ball, {2: 1}, h)
    assert mv.index[mv.raise_].tolist() == [[10, 10, 10]]
    assert not mv.raise_[1:].any() and len(mv.index) > 1  # its wall, already inside the ball: held there
    v = ball.copy()
    v[10, 10, 10] = h
    assert list(betti_numbers(v <= 0)) == [1, 0, 1]


@pytest.mark.parametrize("seed", [0, 1])
def test_counts_are_the_betti_numbers_of_the_shape(seed):
    rng = np.random.default_rng(seed)
    from scipy.ndimage import gaussian_filter

    v = gaussian_filter(rng.standard_normal((N, N)), 3.0)
    v = v - np.median(v)
    assert feature_moves(v, {1: 0}, M).counts[1] == betti_numbers(v <= 0)[1]
    v3 = gaussian_filter(rng.standard_normal((24, 24, 24)), 2.0)
    v3 = v3 - np.median(v3)
    counts = feature_moves(v3, {1: 0, 2: 0}, 2 / 23).counts
    assert (counts[1], counts[2]) == tuple(betti_numbers(v3 <= 0)[1:])


class RingPlusBumps(torch.nn.Module):
    """An analytic ring SDF plus learnable Gaussian bumps on a 17 x 17 lattice (zero at first)."""

    def __init__(self, radius, half_width):
        super().__init__()
        self.radius, self.half_width = radius, half_width
        c = torch.linspace(-1, 1, 17, dtype=torch.float64)
        self.centres = torch.stack(torch.meshgrid(c, c, indexing="ij"), dim=-1).reshape(-1, 2)
        self.coef = torch.nn.Parameter(torch.zeros(len(self.centres), dtype=torch.float64))

    def forward(self, x, z=None):
        base = (x.norm(dim=-1) - self.radius).abs() - self.half_width
        phi = torch.exp(-((x[:, None, :] - self.centres[None]) ** 2).sum(-1) / 0.125**2)
        return base + phi @ self.coef


@pytest.mark.parametrize("radius, half_width, up", [(0.6, 0.05, True), (0.45, 0.35, False)])
def test_one_gradient_step_moves_the_field_at_the_chosen_cell(radius, half_width, up):
    """Thin ring: the field rises where the loss opens it (on the ring); thick ring: it falls at
    the centre, where the loss fills the hole; the largest change is at that cell."""
    field = RingPlusBumps(radius, half_width)
    loss_fn = HoleCountLoss(Box((-1.0, -1.0), (1.0, 1.0)), None, {1: 0}, resolution=N, dtype=torch.float64)
    loss = loss_fn(field, None)
    assert loss.item() > 0
    cell = loss_fn._cells[0][0]
    grid = torch.stack(torch.meshgrid(*(torch.linspace(-1, 1, 129, dtype=torch.float64),) * 2, indexing="ij"), -1).reshape(-1, 2)
    before = field(grid).detach()
    loss.backward()
    with torch.no_grad():
        field.coef -= 0.01 * field.coef.grad
    change = field(grid).detach() - before
    at = field(cell[None]).detach() - (RingPlusBumps(radius, half_width)(cell[None]))
    assert (at.item() > 0) == up and abs(at.item()) > 0
    peak = grid[change.abs().argmax()]
    assert (peak - cell).norm().item() <= 0.125  # one bump width


def test_loss_state_round_trips_and_is_zero_at_the_targets():
    box = Box((-1.0, -1.0), (1.0, 1.0))
    wide = RingPlusBumps(0.6, 0.2)
    done = HoleCountLoss(box, None, {1: 1}, resolution=N, dtype=torch.float64)
    assert done(wide, None).item() == 0.0 and done.last_info["counts"] == [{1: 1}]
    a = HoleCountLoss(box, None, {1: 0}, resolution=N, every=3, dtype=torch.float64)
    a(wide, None)
    b = HoleCountLoss(box, None, {1: 0}, resolution=N, every=3, dtype=torch.float64)
    b.load_state_dict(a.state_dict())
    for _ in range(4):  # the same cells, then the same recomputation
        assert a(wide, None).item() == b(wide, None).item()
    # the seeds in use travel with the state: a solid disk's hole stays at the seed it was given
    disk = RingPlusBumps(0.0, 0.6)
    c = HoleCountLoss(box, None, {1: 1}, resolution=N, dtype=torch.float64)
    c(disk, None)
    seed = c.state_dict()["seeds"][0][1]
    assert len(seed) == 1
    d = HoleCountLoss(box, None, {1: 1}, resolution=N, dtype=torch.float64)
    d.load_state_dict(c.state_dict())
    assert [{k: v.tolist() for k, v in sd.items()} for sd in d._seeds] == [{1: seed}]
    E = csg.Difference(AABox([-1.0, -1.0], [1.0, 1.0]), Ball([0.0, 0.0], 0.3))
    inside = HoleCountLoss(box, E, {1: 0}, resolution=N, dtype=torch.float64)
    inside(RingPlusBumps(0.45, 0.35), None)
    x = inside._cells[0]
    assert len(x) == 1 and x[0].norm().item() > 0.3  # the hole round the region outside E is opened
