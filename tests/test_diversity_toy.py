"""Figure 13 of the paper on its toy: N points in a partial annulus maximise a diversity.

Minimal aggregation with p <= 1 (concave) spreads the points evenly; p = 2 (convex) forms
clusters; total aggregation pushes every point to the boundary of the feasible set. Measured by
spread statistics of the final configuration (projected, normalised gradient ascent, 400 steps).
"""

import math

import pytest
import torch

from ginn.losses.diversity import aggregate_min, aggregate_sum

R_IN, R_OUT, TH = 0.5, 1.0, math.pi  # K = {R_IN <= r <= R_OUT, 0 <= theta <= TH}


def project(p):
    r = p.norm(dim=-1).clamp(R_IN, R_OUT)
    th = torch.atan2(p[:, 1], p[:, 0])
    th = torch.where(th < -math.pi / 2, th + 2 * math.pi, th).clamp(0.0, TH)  # angles in (-pi/2, 3pi/2]
    return torch.stack([r * th.cos(), r * th.sin()], -1)


def optimise(kind, p_exp, n=16, steps=400, lr=0.02, seed=0):
    g = torch.Generator().manual_seed(seed)
    r = R_IN + (R_OUT - R_IN) * torch.rand(n, generator=g, dtype=torch.float64)
    th = TH * torch.rand(n, generator=g, dtype=torch.float64)
    x = torch.stack([r * th.cos(), r * th.sin()], -1)
    for _ in range(steps):
        x = x.detach().requires_grad_(True)
        D = torch.cdist(x, x)
        delta = aggregate_min(D, p_exp) if kind == "min" else aggregate_sum(D, p_exp)
        (grad,) = torch.autograd.grad(delta, x)
        with torch.no_grad():
            x = project(x + lr * grad / grad.norm().clamp_min(1e-12) * math.sqrt(n))
    return x.detach()


def nn_dist(x):
    D = torch.cdist(x, x) + torch.eye(x.shape[0], dtype=x.dtype) * 1e9
    return D.min(dim=1).values


def on_boundary(x, tol=1e-6):
    r = x.norm(dim=-1)
    th = torch.atan2(x[:, 1], x[:, 0])
    return ((r - R_IN).abs() < tol) | ((r - R_OUT).abs() < tol) | (th.abs() < tol) | ((th - TH).abs() < tol)


@pytest.mark.parametrize("p_exp", [0.5, 1.0])
def test_min_aggregation_concave_spreads_evenly(p_exp):
    x = optimise("min", p_exp)
    d = nn_dist(x)
    assert d.min() / d.mean() > 0.6  # nobody is crowded: nearest-neighbour distances are similar
    assert d.std() / d.mean() < 0.3


def test_min_aggregation_p2_forms_clusters():
    x = optimise("min", 2.0)
    d = nn_dist(x)
    even = nn_dist(optimise("min", 0.5))
    assert d.std() / d.mean() > 3 * (even.std() / even.mean())  # far less uniform than p = 0.5
    assert d.min() / d.mean() < 0.1  # some points merge into clusters


@pytest.mark.parametrize("p_exp", [0.5, 1.0, 2.0])
def test_total_aggregation_pushes_to_boundary(p_exp):
    x = optimise("sum", p_exp)
    assert on_boundary(x).float().mean() >= 0.95
    even = optimise("min", 0.5)
    assert on_boundary(even).float().mean() < on_boundary(x).float().mean()
