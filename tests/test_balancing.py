"""Combining loss terms: constraints with tolerances and adaptive multipliers on problems with
known constrained optima."""

import math

import numpy as np
import pytest
import torch

from ginn.config import BalancingConfig, LossTerm
from ginn.train.balancing import AdaptiveMultipliers, Balance, CheckedMultipliers, WeightedSum, make_balancer


class _Adam:
    """Adam (torch's defaults) on a NumPy vector: the optimiser of these small problems, whose
    gradients are written out."""

    def __init__(self, x: np.ndarray, lr: float):
        self.x, self.lr, self.m, self.v, self.t = x.astype(np.float64), lr, np.zeros_like(x), np.zeros_like(x), 0

    def step(self, g: np.ndarray) -> None:
        self.t += 1
        self.m = 0.9 * self.m + 0.1 * g
        self.v = 0.999 * self.v + 0.001 * g * g
        m, v = self.m / (1 - 0.9**self.t), self.v / (1 - 0.999**self.t)
        self.x = self.x - self.lr * m / (np.sqrt(v) + 1e-8)


def _solve(scale: float, eps: float, iterations: int = 12000):
    """min |x|^2 s.t. scale * (x_0 - 1)^2 <= scale * eps, and x_1^2 <= 1 (inactive at the optimum),
    each step the gradient of the balancer's combination (its weights times the terms' gradients)."""
    terms = {"objective": LossTerm(weight=1.0), "c": LossTerm(weight=1.0), "loose": LossTerm(weight=1.0)}
    b = make_balancer(terms, BalancingConfig(method="adaptive"), Balance(targets={"c": scale * eps, "loose": 1.0}))
    opt = _Adam(np.array([0.0, 0.5, 0.3]), lr=1e-2)
    for it in range(iterations):
        x = opt.x
        grads = {"objective": 2 * x, "c": np.array([2 * scale * (x[0] - 1), 0, 0]), "loose": np.array([0, 2 * x[1], 0])}
        opt.step(sum(b.weight(k) * g for k, g in grads.items()))
        b.observe({"objective": float(x @ x), "c": scale * (x[0] - 1) ** 2, "loose": x[1] ** 2}, it)
    return torch.from_numpy(opt.x), b


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


def _checked():
    terms = {"interface": LossTerm(weight=3.0), "design_region": LossTerm(weight=2.0), "obstacle": LossTerm(weight=5.0),
             "eikonal": LossTerm(weight=0.1)}
    groups = {"interface": ("interface",), "volume_outside": ("design_region", "obstacle"), "connected": ("connectedness",)}
    return make_balancer(terms, BalancingConfig(method="feasibility"), Balance(groups=groups))


def test_checks_raise_the_multipliers_of_a_constraint_off_track_only():
    b = _checked()
    assert isinstance(b, CheckedMultipliers)
    assert "connected" not in b.groups  # no connectedness term: nothing to raise
    assert b.on_check({"interface": 3.0, "volume_outside": 0.5}, 5) == {}  # the first check only records
    # interface 2.8 (2.8 / 3)^4 = 2.1 > 1: off track, raised by min(2.8^2, 2) = 2; the volume is met
    assert b.on_check({"interface": 2.8, "volume_outside": 0.4}, 4) == {"interface": 2.0}
    # interface 1.5 (1.5 / 2.8)^3 = 0.23: on track; volume 1.2 (1.2 / 0.4)^3 > 1: raised by 1.2^2
    assert b.on_check({"interface": 1.5, "volume_outside": 1.2}, 3) == pytest.approx({"volume_outside": 1.44})
    m = b.multipliers()
    assert m == pytest.approx({"interface": 6.0, "design_region": 2.88, "obstacle": 7.2, "eikonal": 0.1})
    # an undefined value (an empty shape's CD1) is off track whatever came before: the largest
    # step; volume 1.1 (1.1 / 1.2)^2 = 0.92 is on track with two checks to come
    assert b.on_check({"interface": None, "volume_outside": 1.1}, 2) == {"interface": 2.0}
    # the same volume one check later is stalled: 1.1 (1.1 / 1.1)^1 > 1
    assert b.on_check({"interface": 0.5, "volume_outside": 1.1}, 1) == pytest.approx({"volume_outside": 1.21})
    assert b.weight("interface") == 12.0 and b.weight("obstacle") == pytest.approx(5.0 * 1.44 * 1.21)
    total = b.combine({"interface": torch.tensor(1.0), "eikonal": torch.tensor(2.0)}, 0)
    assert total.item() == pytest.approx(12.0 + 0.2)
    c = _checked()
    c.load_state_dict(b.state_dict())
    assert c.multipliers() == b.multipliers()
    assert c.on_check({"interface": 1.0, "volume_outside": 2.0}, 0) == b.on_check({"interface": 1.0, "volume_outside": 2.0}, 0)
    assert c.state_dict() == b.state_dict()


def test_checked_multipliers_reach_a_tolerance_of_an_equality_constraint():
    """min |x|^2 + lambda (x_0 - 1)^2 has x_0 = lambda / (1 + lambda): the violation |x_0 - 1| =
    1 / (1 + lambda) meets a tolerance 0.01 once lambda >= 99. With lambda = 1 at first and the
    inner problem solved between 16 checks, a raise (by 2: q^2 > 2 until q < 1.42) is followed by
    a check that finds the violation on track (q = 50 -> 33: 33 (33 / 50)^13 < 1), and the next
    one finds it stalled, so lambda doubles every second check: 128 (q = 0.78) at check 14."""
    terms = {"objective": LossTerm(weight=1.0), "c": LossTerm(weight=1.0)}
    b = make_balancer(terms, BalancingConfig(method="feasibility"), Balance(groups={"equality": ("c",)}))
    opt = _Adam(np.array([0.0, 0.5]), lr=2e-2)
    history = []
    for check in range(16):
        for it in range(1500):
            x = opt.x
            opt.step(b.weight("objective") * 2 * x + b.weight("c") * np.array([2 * (x[0] - 1), 0.0]))
        x = torch.from_numpy(opt.x)
        lam = b.weight("c")
        assert x[0].item() == pytest.approx(lam / (1 + lam), abs=1e-4)
        history.append(lam)
        b.on_check({"equality": abs(x[0].item() - 1) / 0.01}, 15 - check)
    assert history == [1.0, 1.0, 2.0, 2.0, 4.0, 4.0, 8.0, 8.0, 16.0, 16.0, 32.0, 32.0, 64.0, 64.0, 128.0, 128.0]
    assert abs(x[0].item() - 1) < 0.01


def test_checks_raise_only_what_both_candidates_violate():
    from ginn.tasks.shape import candidate_ratios

    iterate = {"interface": 3.4, "volume_outside": 10.8, "connected": None, "topology": 2.0}
    mean = {"interface": 0.74, "volume_outside": 9.7, "connected": 1.0, "topology": None}
    assert candidate_ratios(iterate, mean) == {"interface": 0.74, "volume_outside": 9.7, "connected": 1.0,
                                               "topology": 2.0}
    assert candidate_ratios(iterate, None) == iterate
    # with the scripted rule: only the constraint that the mean violates too is raised
    m = CheckedMultipliers({"interface": LossTerm(weight=1.0), "design_region": LossTerm(weight=1.0)},
                           {"interface": ("interface",), "volume_outside": ("design_region",)})
    m.on_check(candidate_ratios({"interface": 3.0, "volume_outside": 3.0}, None), 5)
    raised = m.on_check(candidate_ratios({"interface": 3.0, "volume_outside": 3.0},
                                         {"interface": 0.9, "volume_outside": 3.0}), 4)
    assert raised == {"volume_outside": 2.0}


def test_a_hard_bound_is_raised_by_the_full_factor_until_met():
    """min (x - 0.5)^2 + lambda relu(x - 0.48) has x = max(0.48, 0.5 - lambda / 2): the exact
    penalty meets the bound exactly once lambda >= 0.04. From lambda = 0.001 the violation's ratio
    to the bound stays near 1.04, so q^2 raises lambda by about 8 % a check and 16 checks leave it
    at 0.003, 4 % over the bound; as a hard bound it doubles at every check that finds it off
    track (once the violation halves within a check, the next is on track) and is met from the
    eleventh check on."""
    def run(hard):
        m = CheckedMultipliers({"volume": LossTerm(weight=0.001)}, {"volume_fraction": ("volume",)},
                               hard=("volume_fraction",) if hard else ())
        ratios = []
        for check in range(16):
            x = max(0.48, 0.5 - m.weight("volume") / 2)
            ratios.append(x / 0.48)
            m.on_check({"volume_fraction": x / 0.48}, 15 - check)
        return ratios, m.weight("volume")

    soft, lam_soft = run(False)
    hard, lam_hard = run(True)
    assert min(soft) > 1.038 and lam_soft < 0.004
    assert max(hard[10:]) == 1.0 and min(hard[:10]) > 1.008
    assert lam_hard == pytest.approx(0.064)
    b = make_balancer({"volume": LossTerm(weight=1.0)}, BalancingConfig(method="feasibility"),
                      Balance(groups={"volume_fraction": ("volume",)}, hard=("volume_fraction",)))
    assert b.hard == ("volume_fraction",)


def test_a_gated_objective_acts_in_proportion_to_the_constraints_targets():
    """The mean curvature's weight is ``w min(1, eps / m)``: ``m`` the bias-corrected running
    average of the interface loss (target ``eps = 0.01``); the eikonal's target enforces no
    constraint of the verdict and does not gate."""
    terms = {"interface": LossTerm(weight=1.0), "eikonal": LossTerm(weight=1.0), "mean_curvature": LossTerm(weight=2.0)}
    balance = Balance(targets={"interface": 0.01, "eikonal": 0.01}, groups={"interface": ("interface",)},
                      gated=("mean_curvature",))
    b = make_balancer(terms, BalancingConfig(method="feasibility"), balance)
    assert b.gate_targets == {"interface": 0.01}
    assert b.weight("mean_curvature") == 2.0  # nothing seen yet
    b.observe({"interface": 0.04, "eikonal": 5.0}, 0)
    assert b.gate() == pytest.approx(0.25)  # the first average is the value itself
    assert b.weight("mean_curvature") == pytest.approx(0.5) and b.weight("eikonal") == 1.0
    b.observe({"interface": 0.0}, 1)  # (0.99 * 0.01 * 0.04) / (1 - 0.99^2) = 0.0199
    assert b.gate() == pytest.approx(0.01 / (0.99 * 0.01 * 0.04 / (1 - 0.99 ** 2)))
    total = b.combine({"interface": torch.tensor(1.0), "mean_curvature": torch.tensor(3.0)}, 2)
    assert total.item() == pytest.approx(1.0 + 3.0 * 2.0 * b.gate())
    c = make_balancer(terms, BalancingConfig(method="feasibility"), balance)
    c.load_state_dict(b.state_dict())
    assert c.gate() == b.gate() and c.state_dict() == b.state_dict()
    for step in range(2, 2000):  # the constraint meets its target: full weight
        b.observe({"interface": 0.001}, step)
    assert b.gate() == 1.0 and b.weight("mean_curvature") == 2.0
    assert b.multipliers()["mean_curvature"] == 2.0


def test_a_term_of_two_constraints_has_the_larger_factor():
    """The interface enforces its own constraint and the reference verdict's: a check that finds
    both violated off track doubles it once, one that finds only the reference so doubles that
    factor, which then leads."""
    b = CheckedMultipliers({"interface": LossTerm(weight=1.0)}, {"interface": ("interface",), "reference": ("interface",)})
    b.on_check({"interface": 3.0, "reference": 3.0}, 5)
    assert b.on_check({"interface": 3.0, "reference": 3.0}, 4) == {"interface": 2.0, "reference": 2.0}
    assert b.weight("interface") == 2.0
    assert b.on_check({"interface": 0.5, "reference": 3.0}, 3) == {"reference": 2.0}
    assert b.weight("interface") == 4.0
