"""A least diversity (``tolerances.diversity``) is a constraint on the set, read as the verdict
reads it: equation 6 over first-order distances between the shapes, zero once met."""

import dataclasses
import math

import numpy as np
import pytest
import torch

from ginn import runs
from ginn.eval.metrics import diversity_from_matrix
from ginn.losses.diversity import boundary_distances, distance_matrix, mean_diversity, shape_shares, take
from ginn.problems.derived import length_scale
from ginn.tasks.shape import ShapeTask

CENTRE = torch.tensor([0.75, 0.5])  # the middle of the cantilever's domain


class Rings(torch.nn.Module):
    """Concentric circles round CENTRE, radius ``0.3 + 0.1 z``, as a field twice as steep as a
    distance: ``f = 2 (|x - c| - r(z))``."""

    def forward(self, x, z):
        return 2.0 * ((x - CENTRE.to(x.dtype)).norm(dim=-1) - (0.3 + 0.1 * z[:, 0]))


def _ring_points(radii, m=64):
    a = torch.linspace(0, 2 * math.pi, m + 1, dtype=torch.float64)[:-1]
    return torch.stack([CENTRE.double() + r * torch.stack([a.cos(), a.sin()], dim=1) for r in radii])


def _expected(radii):
    """Equation 6 of concentric circles: every point of one lies ``|r_i - r_j|`` from the other,
    so ``D_ij = sqrt(2) |r_i - r_j|``."""
    r = np.asarray(radii)
    D = math.sqrt(2.0) * np.abs(r[:, None] - r[None, :])
    return diversity_from_matrix(D)


def test_mean_diversity_is_the_verdicts_aggregation():
    g = np.random.default_rng(0)
    A = g.uniform(0.0, 1.0, (6, 6))
    D = A + A.T
    np.fill_diagonal(D, g.uniform(0, 1, 6))  # the diagonal is ignored
    assert float(mean_diversity(torch.as_tensor(D))) == pytest.approx(diversity_from_matrix(D), rel=1e-12)
    assert float(mean_diversity(torch.zeros(1, 1))) == 0.0


def test_boundary_distances_of_concentric_circles_and_their_gradient():
    radii = torch.tensor([0.3, 0.4, 0.5], dtype=torch.float64, requires_grad=True)
    x = _ring_points(radii.detach().tolist(), m=720)
    r = (x - CENTRE.double()).norm(dim=-1)  # (S, m)
    f = 2.0 * (r - radii[:, None])  # each shape's field at its own samples: zero, with a graph
    g = 2.0 * (x - CENTRE.double()) / r[..., None]
    V = boundary_distances(x, None, f, g)
    want = (radii[:, None] - radii[None, :]).abs().detach()
    assert torch.allclose(V.detach(), want[:, :, None].expand_as(V), atol=1e-12)  # samples on the same rays
    delta = mean_diversity(distance_matrix(V))
    assert float(delta.detach()) == pytest.approx(_expected([0.3, 0.4, 0.5]), rel=1e-10)
    delta.backward()
    eps = 1e-6
    for s in range(3):  # the boundary sensitivity is the derivative in the radii
        up, dn = [0.3, 0.4, 0.5], [0.3, 0.4, 0.5]
        up[s] += eps
        dn[s] -= eps
        fd = (_expected(up) - _expected(dn)) / (2 * eps)
        assert float(radii.grad[s]) == pytest.approx(fd, rel=1e-6, abs=1e-9)


def test_take_has_one_gradient_on_any_thread_count():
    """Many samples share a nearest sample of another shape, so the distances gather the field's
    values with repeated indices. ``take``'s gradient adds the repeats one after another: the same
    on every call on two threads, and on one thread the same bits as plain indexing's."""
    g = torch.Generator().manual_seed(0)
    S, m = 16, 512
    src = torch.randn(S, m, generator=g)
    index = torch.arange(S)[None, :, None] * m + torch.randint(0, m, (S, S, m), generator=g)
    w = torch.randn(S, S, m, generator=g)

    def grad(gather) -> torch.Tensor:
        x = src.clone().requires_grad_(True)
        return torch.autograd.grad((gather(x) * w).sum(), x)[0]

    before = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        plain = grad(lambda x: x.reshape(-1)[index])
        assert torch.equal(grad(lambda x: take(x, index)), plain)
        torch.set_num_threads(2)
        for _ in range(5):
            assert torch.equal(grad(lambda x: take(x, index)), plain)
    finally:
        torch.set_num_threads(before)
    assert torch.equal(take(src, index), src.reshape(-1)[index])


def test_a_copy_sampled_elsewhere_is_at_its_sagitta_and_an_end_at_its_distance():
    x = _ring_points([0.3], m=64)
    a = torch.tensor(math.pi / 64)  # the copy's samples halfway between the first's
    rot = torch.tensor([[a.cos(), -a.sin()], [a.sin(), a.cos()]], dtype=torch.float64)
    xs = torch.cat([x, (x - CENTRE.double()) @ rot.T + CENTRE.double()])
    g = (xs - CENTRE.double()) / 0.3
    V = boundary_distances(xs, None, torch.zeros(2, 64, dtype=torch.float64), g)
    sagitta = 0.3 * (1 - math.cos(math.pi / 64))  # 3.6e-4, against a half spacing's chord of 0.0147
    assert torch.allclose(V[0, 1], torch.full((64,), sagitta, dtype=torch.float64), atol=1e-12)
    # a segment on the x axis, sampled at 0, 0.1, ..., 1, and a point beyond its end on its line
    seg = torch.stack([torch.linspace(0, 1, 11, dtype=torch.float64), torch.zeros(11, dtype=torch.float64)], dim=1)
    pts = torch.cat([seg[:1] * 0 + torch.tensor([1.5, 0.0], dtype=torch.float64), seg[1:]])
    xs = torch.stack([seg, pts])
    g = torch.tensor([0.0, 1.0], dtype=torch.float64).expand(2, 11, 2)
    mask = torch.ones(2, 11, dtype=torch.bool)
    mask[0, 10] = False  # the end sample at 1 is invalid: the nearest is at 0.9, spaced 0.1
    V = boundary_distances(xs, mask, torch.zeros(2, 11, dtype=torch.float64), g)
    assert float(V[1, 0, 0]) == pytest.approx(1.5 - 0.9 - 0.1)  # not 0, the distance to the tangent


def _cantilever_task(bound):
    spec, cfg = runs.resolve("cantilever", None, sets=["latents.n_shapes=3", "sampling.n_domain=4096", "sampling.n_boundary=2048"])
    problem = spec.build()
    problem = dataclasses.replace(problem, tolerances=dataclasses.replace(problem.tolerances, diversity=bound))
    return ShapeTask(problem, cfg, "cpu", torch.float64)


@pytest.mark.parametrize("bound", [0.05, 0.2])
def test_the_term_is_the_shortfall_below_the_bound(bound):
    task = _cantilever_task(bound)
    term = next(c for c in task.constraints if c.name == "diversity")
    assert term.verdict is not None and task.balance().groups["diversity"] == ("diversity",)
    Z = torch.tensor([[0.0], [1.0], [2.0]], dtype=torch.float64)
    batch = task.draw_batch(3, {"diversity"}, torch.Generator().manual_seed(0), Z)
    batch.evaluate(Rings())
    loss = term.loss(batch)
    delta = _expected([0.3, 0.4, 0.5])  # 0.1276: met at 0.05, short at 0.2
    assert float(batch.diagnostics["_diversity_mean"]) == pytest.approx(delta, rel=0.01)  # 384 samples a shape
    # each shape's own mean distance to the others: sqrt(2) (0.15, 0.1, 0.15) = 0.212, 0.141, 0.212;
    # at 0.2 only the middle ring is short, by 0.293, a third of which is the set's loss
    want = np.maximum(0.0, 1.0 - _shares([0.3, 0.4, 0.5]) / bound).mean()
    assert float(loss.detach()) == pytest.approx(want, rel=0.02, abs=1e-12)
    assert (float(loss.detach()) > 0.09) == (bound == 0.2)


def _shares(radii):
    """Each concentric circle's mean distance to the others, ``sqrt(2) mean_j |r_i - r_j|``."""
    r = np.asarray(radii)
    return math.sqrt(2.0) * np.abs(r[:, None] - r[None, :]).sum(axis=1) / (len(r) - 1)


def test_shape_shares_are_the_rows_equation_6_aggregates():
    g = np.random.default_rng(1)
    A = g.uniform(0.0, 1.0, (5, 5))
    D = A + A.T
    np.fill_diagonal(D, 7.0)  # ignored
    rows = shape_shares(torch.as_tensor(D)).numpy()
    assert np.allclose(rows, (D.sum(axis=1) - 7.0) / 4, rtol=1e-14)
    assert float(np.sqrt(rows).mean() ** 2) == pytest.approx(float(mean_diversity(torch.as_tensor(D))), rel=1e-14)


def test_every_shape_holds_its_share_of_the_bound():
    """The shortfall is each shape's own: on three shapes in a row whose set meets the bound, the
    middle one (mean distance 1.005 to the ends, under 1.2) is short, and its term moves it off
    the line (no pull along it, where its mean distance cannot grow) and the ends away from it."""
    h = 0.1
    p = torch.tensor([[-1.0, 0.0], [0.0, h], [1.0, 0.0]], dtype=torch.float64, requires_grad=True)
    D = (p[:, None, :] - p[None, :, :]).norm(dim=-1)
    assert float(mean_diversity(D.detach())) > 1.2  # the set's equation 6 meets the bound ...
    loss = torch.relu(1.0 - shape_shares(D) / 1.2).mean()
    middle = math.sqrt(1.0 + h * h)  # ... but the middle shape's share does not
    assert float(loss.detach()) == pytest.approx((1.0 - middle / 1.2) / 3, rel=1e-12)
    loss.backward()
    g = p.grad
    assert float(g[1, 0]) == pytest.approx(0.0, abs=1e-15)
    assert float(g[1, 1]) == pytest.approx(-h / middle / (3 * 1.2), rel=1e-12)  # descent lifts it
    assert float(g[0, 0]) == pytest.approx(1.0 / middle / (2 * 3 * 1.2), rel=1e-12)  # the ends move out
    assert float(g[2, 0]) == pytest.approx(-float(g[0, 0]), rel=1e-12)


def test_a_least_diversity_weighs_its_shortfall_like_a_volume_fraction():
    _, cfg = runs.resolve("cantilever", None)
    assert cfg.losses.diversity.weight == 10.0
    spec, cfg = runs.resolve("obstacle", None)
    assert cfg.losses.diversity.weight == pytest.approx(0.015 / length_scale(spec.build()))


def test_a_least_diversity_starts_the_set_alike():
    """With ``tolerances.diversity`` the first layer turns through ``d + 1`` radians over the latent
    range, so no first-layer neuron's phase moves by more than a radian from one end of Z to the
    other (its weights start within ``1 / fan_in``, ``fan_in = d + 1``); without, the paper's scale
    of 1 turns it through ``r w`` (45 radians on the cantilever); a scale the user sets stays."""
    from ginn.models import build_model

    _, cfg = runs.resolve("cantilever", None)
    r, w = cfg.latents.high - cfg.latents.low, cfg.model.w0_first
    assert cfg.model.latent_turns == 3.0
    assert cfg.model.latent_scale == pytest.approx(3.0 / (r * w), rel=1e-12)
    assert r * w == pytest.approx(45.0, abs=0.01)
    torch.manual_seed(0)
    net = build_model(cfg.model, 2, 1).double()
    x = torch.rand(64, 2, dtype=torch.float64)
    with torch.no_grad():
        ends = [net.preactivations(x, torch.full((64, 1), v, dtype=torch.float64))[0] for v in (cfg.latents.low, cfg.latents.high)]
    turn = (ends[1] - ends[0]).abs()
    assert float(turn.max()) <= 1.0 and float(turn.max()) > 0.8  # 64 neurons: the bound is nearly reached
    _, own = runs.resolve("cantilever", None, sets=["model.latent_scale=1"])
    assert own.model.latent_scale == 1.0
    _, obstacle = runs.resolve("obstacle", None)
    assert obstacle.model.latent_turns is None and obstacle.model.latent_scale == 1.0


def test_a_check_calibrates_the_term_on_the_verdicts_measurement():
    task = _cantilever_task(0.2)
    term = next(c for c in task.constraints if c.name == "diversity")
    Z = torch.tensor([[0.0], [1.0], [2.0]], dtype=torch.float64)
    batch = task.draw_batch(3, {"diversity"}, torch.Generator().manual_seed(0), Z)
    batch.evaluate(Rings())
    term.loss(batch)
    est = float(batch.diagnostics["_diversity_mean"])
    assert term.estimate() == pytest.approx(est, rel=1e-12)  # one step: the average is the step's
    term.checked({"diversity": 0.2 / 0.15})  # the verdict measured 0.15: a quarter short
    assert term.calibration == pytest.approx(est / 0.15)
    batch = task.draw_batch(3, {"diversity"}, torch.Generator().manual_seed(0), Z)
    batch.evaluate(Rings())
    # the shortfall the verdict would see: each share as the verdict measures it, against 0.2
    want = np.maximum(0.0, 1.0 - _shares([0.3, 0.4, 0.5]) * (0.15 / est) / 0.2).mean()
    assert float(term.loss(batch).detach()) == pytest.approx(want, rel=0.02)
    again = next(c for c in _cantilever_task(0.2).constraints if c.name == "diversity")
    again.load_state_dict(term.state_dict())
    assert again.calibration == term.calibration and again.estimate() == term.estimate()
    term.checked({"diversity": None})  # an empty shape: nothing to calibrate on
    assert again.calibration == term.calibration
