"""Combining loss terms into one objective: fixed weights, or an augmented Lagrangian.

Fixed weights (the paper): ``L = sum_i lambda_i l_i``.

Augmented Lagrangian (optional; the paper names the sensitivity to the many weights as a main
limitation). The constraint terms ``c_i >= 0`` (interface, design region, normal, obstacle, ...)
are driven to zero while the objective terms (eikonal, curvature, strain, connectedness,
diversity, with their configured weights) are minimised::

    L = sum_obj w_j l_j + sum_con ( lambda_i c_i + mu / 2 c_i^2 )

Every ``update_every`` iterations the multipliers take a dual ascent step
``lambda_i <- lambda_i + lambda_lr * mu * mean(c_i since the last update)`` and ``mu`` grows by
``mu_growth`` (capped at ``mu_max``). The initial multipliers are the configured weights, so a
problem's hand-tuned weights are a starting point, not a requirement.
"""

from __future__ import annotations

from torch import Tensor

from ..config import BalancingConfig, LossTerm


class WeightedSum:
    """``sum_i w_i l_i`` with the configured weights."""

    def __init__(self, terms: dict[str, LossTerm]):
        self.weights = {k: t.weight for k, t in terms.items()}

    def combine(self, losses: dict[str, Tensor], step: int) -> Tensor:
        total = None
        for k, v in losses.items():
            if k.startswith("_"):
                continue
            t = self.weights.get(k, 0.0) * v
            total = t if total is None else total + t
        if total is None:
            raise ValueError("no active loss term")
        return total

    def observe(self, losses: dict[str, float], step: int) -> None:
        pass

    def multipliers(self) -> dict[str, float]:
        return dict(self.weights)

    def state_dict(self) -> dict:
        return {}

    def load_state_dict(self, state: dict) -> None:
        pass


class AugmentedLagrangian(WeightedSum):
    """Constraints as targets (``c_i -> 0``), objectives minimised; see the module docstring."""

    def __init__(self, terms: dict[str, LossTerm], cfg: BalancingConfig):
        super().__init__(terms)
        self.cfg = cfg
        self.objectives = set(cfg.objectives)
        self.lam = {k: w for k, w in self.weights.items() if k not in self.objectives}
        self.mu = cfg.mu
        self._acc: dict[str, float] = {}
        self._count = 0

    def combine(self, losses: dict[str, Tensor], step: int) -> Tensor:
        total = None
        for k, v in losses.items():
            if k.startswith("_"):
                continue
            if k in self.objectives:
                t = self.weights.get(k, 0.0) * v
            else:
                t = self.lam.get(k, 0.0) * v + 0.5 * self.mu * v * v
            total = t if total is None else total + t
        if total is None:
            raise ValueError("no active loss term")
        return total

    def observe(self, losses: dict[str, float], step: int) -> None:
        for k, v in losses.items():
            if k in self.lam:
                self._acc[k] = self._acc.get(k, 0.0) + float(v)
        self._count += 1
        if self._count >= self.cfg.update_every:
            for k, s in self._acc.items():
                self.lam[k] += self.cfg.lambda_lr * self.mu * s / self._count
            self.mu = min(self.mu * self.cfg.mu_growth, self.cfg.mu_max)
            self._acc, self._count = {}, 0

    def multipliers(self) -> dict[str, float]:
        out = {k: w for k, w in self.weights.items() if k in self.objectives}
        out.update(self.lam)
        return out

    def state_dict(self) -> dict:
        return {"lam": dict(self.lam), "mu": self.mu, "acc": dict(self._acc), "count": self._count}

    def load_state_dict(self, state: dict) -> None:
        self.lam = {k: float(v) for k, v in state["lam"].items()}
        self.mu = float(state["mu"])
        self._acc = {k: float(v) for k, v in state["acc"].items()}
        self._count = int(state["count"])


def make_balancer(terms: dict[str, LossTerm], cfg: BalancingConfig) -> WeightedSum:
    if cfg.method == "weighted":
        return WeightedSum(terms)
    return AugmentedLagrangian(terms, cfg)


