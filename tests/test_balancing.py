"""Combining loss terms: constraints with tolerances and adaptive multipliers on problems with
known constrained optima."""

import math

import pytest
import torch

from ginn.config import BalancingConfig, LossTerm
from ginn.train.balancing import AdaptiveMultipliers, WeightedSum, make_balancer


def _solve(scale: float, eps: float, iterations: int = 12000):
    """min |x|^2 s.t. scale * (x_0 - 1)^2 <= scale * eps, and x_1^2 <= 1 (inactive at the optimum)."""
    terms = {"objective": LossTerm(weight=1.0), "c": LossTerm(weight=1.0), "loose": LossTerm(weight=1.0)}
    b = make_balancer(terms, BalancingConfig(method="adaptive"), {"c": scale * eps, "loose": 1.0})
    x = torch.tensor([0.0, 0.5, 0.3], dtype=torch.float64, requires_grad=True)
    opt = torch.optim.Adam([x], lr=1e-2)
    for it in range(iterations):
        losses = {"objective": (x * x).sum(), "c": scale * (x[0] - 1) ** 2, "loose": x[1] ** 2}
        opt.zero_grad()
        b.combine(losses, it).backward()
        opt.step()
        b.observe({k: float(v.detach()) for k, v in losses.items()}, it)
    return x.detach(), b


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_active_constraint_reaches_the_kkt_point_whatever_the_scale(scale):
    """Optimum on the constraint's boundary: x = (1 - sqrt(eps), 0, 0); stationarity
    2 x_0 + lambda * scale * 2 (x_0 - 1) = 0 gives lambda = (1 - sqrt(eps)) / (sqrt(eps) * scale)."""
    eps = 1e-2
    x, b = _solve(scale, eps)
    assert x[0].item() == pytest.approx(1 - math.sqrt(eps), abs=2e-3)
    assert x[1:].abs().max().item() < 1e-3
    assert b.lam["c"] == pytest.approx((1 - math.sqrt(eps)) / (math.sqrt(eps) * scale), rel=0.05)
    assert b.lam["loose"] == 0.0  # inactive: its multiplier reaches exactly zero
    assert b.running("c") == pytest.approx(scale * eps, rel=0.05)


def test_objectives_keep_their_weights_and_state_round_trips():
    terms = {"eikonal": LossTerm(weight=0.1), "interface": LossTerm(weight=3.0)}
    b = AdaptiveMultipliers(terms, {"interface": 1e-4})
    for it in range(50):
        b.observe({"eikonal": 1.0, "interface": 1e-2}, it)
    assert b.multipliers()["eikonal"] == 0.1 and b.is_objective("eikonal") and not b.is_objective("interface")
    # violated 100-fold: every step multiplies by (1 + step * tanh(log 100)), about 1.01
    assert b.lam["interface"] == pytest.approx(3.0 * (1 + 0.01 * math.tanh(math.log(1e-2 / (1e-4 * 1.001)))) ** 50,
                                               rel=1e-3)
    c = AdaptiveMultipliers(terms, {"interface": 1e-4})
    c.load_state_dict(b.state_dict())
    for it in range(5):
        for m in (b, c):
            m.observe({"eikonal": 1.0, "interface": 3e-5}, 50 + it)
    assert b.state_dict() == c.state_dict()
    total = c.combine({"eikonal": torch.tensor(2.0), "interface": torch.tensor(1e-3)}, 0)
    assert total.item() == pytest.approx(0.1 * 2.0 + c.lam["interface"] * 1e-3)


def test_weighted_sum_is_the_papers_sum():
    b = make_balancer({"a": LossTerm(weight=2.0), "b": LossTerm(weight=0.5)}, BalancingConfig())
    assert isinstance(b, WeightedSum) and not isinstance(b, AdaptiveMultipliers)
    assert b.combine({"a": torch.tensor(1.0), "b": torch.tensor(4.0)}, 0).item() == 4.0
