"""The parabolic mirror: exact optics of the reflection loss, params validation, and training."""

import time

import numpy as np
import pytest
import torch
from torch import nn

from ginn.config import build_config
from ginn.errors import ConfigError
from ginn.tasks.mirror import MirrorTask, parse_mirror_params
from ginn.tasks.mirror.optics import evaluate_mirror, focus_distance, reflected_direction, reflection_residual


class Poly(nn.Module):
    """h(x) = a x^2 + b x^3 + c as a field (x (n, 1), z) -> (n,), float64."""

    def __init__(self, a, b=0.0, c=0.0):
        super().__init__()
        self.p = nn.Parameter(torch.tensor([a, b, c], dtype=torch.float64))

    def forward(self, x, z=None):
        t = x[:, 0]
        return self.p[0] * t * t + self.p[1] * t**3 + self.p[2]


def _task(**params):
    cfg = build_config({"model": {"kind": "mlp", "hidden": [40, 40]}, "params": {"kind": "mirror", **params}})
    return MirrorTask(cfg, "cpu", torch.float64)


@pytest.mark.parametrize("F", [1.0, 0.5, 2.5])
def test_reflection_loss_vanishes_for_exact_parabola(F, gen):
    task = _task(focus=F)
    model = Poly(1.0 / (4 * F))
    L = task.loss_terms(model, 0, {"interface", "reflection"}, gen)
    assert L["reflection"].item() <= 1e-20  # squared distance; distance <= 1e-10
    assert L["interface"].item() == 0.0
    x = torch.linspace(-1, 1, 101, dtype=torch.float64)
    d = reflection_residual(model, x, F, create_graph=False)
    assert d.abs().max().item() <= 1e-10


def test_reflection_loss_positive_for_perturbed_mirror(gen):
    task = _task(focus=1.0)
    for m in (Poly(0.25, b=0.01), Poly(0.26), Poly(0.25, c=0.01)):
        L = task.loss_terms(m, 0, {"reflection"}, gen)
        assert L["reflection"].item() > 1e-7
    # a flat mirror sends the ray at x straight back up: distance |x| from the focus line
    x = torch.linspace(-1, 1, 11, dtype=torch.float64)
    d = focus_distance(x, torch.zeros_like(x), torch.zeros_like(x), 1.0)
    assert torch.allclose(d.abs(), x.abs(), atol=1e-15)


def test_reflected_direction_is_mirror_image():
    dh = torch.tensor([0.0, 1.0, -0.5, 3.0], dtype=torch.float64)
    r = reflected_direction(dh)
    assert torch.allclose(r.norm(dim=-1), torch.ones(4, dtype=torch.float64), atol=1e-15)
    # slope 1 (45 degrees): a downward ray leaves horizontally to the left
    assert torch.allclose(r[1], torch.tensor([-1.0, 0.0], dtype=torch.float64), atol=1e-15)
    # law of reflection: incoming and outgoing make equal angles with the normal
    n = torch.stack([-dh, torch.ones_like(dh)], -1) / (1 + dh * dh).sqrt()[:, None]
    d = torch.tensor([0.0, -1.0], dtype=torch.float64)
    assert torch.allclose((r * n).sum(-1), -(d * n).sum(-1), atol=1e-14)


def test_exact_solution_evaluates_to_zero_error():
    res = evaluate_mirror(Poly(0.5), {"focus": 0.5})
    assert res["max_abs_error_vs_exact"] <= 1e-15
    assert res["max_focus_distance"] <= 1e-12
    res = evaluate_mirror(Poly(0.25, c=0.003), {"focus": 1.0})
    assert abs(res["max_abs_error_vs_exact"] - 0.003) <= 1e-12
    assert abs(res["interface_error"] - 0.003) <= 1e-12


def test_params_validation():
    assert parse_mirror_params({"focus": 2}).focus == 2.0
    with pytest.raises(ConfigError, match="params.focus"):
        parse_mirror_params({"focus": -1})
    with pytest.raises(ConfigError, match="unknown key"):
        parse_mirror_params({"focal": 1})
    with pytest.raises(ConfigError, match="x_min"):
        parse_mirror_params({"x_min": 1, "x_max": 0})
    with pytest.raises(ConfigError):
        _task(sampling="grid")
    with pytest.raises(ConfigError, match="model.kind"):
        MirrorTask(build_config({"model": {"kind": "siren"}}), "cpu", torch.float32).build_model()


def test_stratified_samples_cover_aperture(gen):
    from ginn.tasks.mirror import sample_rays

    p = parse_mirror_params({"n_samples": 64})
    x = sample_rays(p, 64, gen, "cpu", torch.float64)
    cell = torch.floor((x + 1) / 2 * 64).long()
    assert torch.equal(cell, torch.arange(64))


def test_finalize_writes_profile_and_figure(tmp_path):
    task = _task(focus=1.0, n_eval=11)
    paths = task.results.finalize(Poly(0.25), tmp_path)
    names = sorted(p.name for p in paths)
    assert names == ["explorer.html", "mirror.png", "mirror_profile.csv", "mirror_profile.npy"]
    tab = np.load(tmp_path / "mirror_profile.npy")
    assert tab.shape == (11, 3)
    assert np.allclose(tab[:, 1], tab[:, 2], atol=1e-15)
    assert np.allclose(np.loadtxt(tmp_path / "mirror_profile.csv", delimiter=",", skiprows=1), tab)


def _train(F: float, seed: int = 0) -> tuple[dict, float]:
    """The preset's setting with a plain Adam loop (same schedule as the trainer's)."""
    from ginn.problems.loader import load_spec
    from ginn.tasks import make_task

    torch.set_num_threads(1)
    spec = load_spec("mirror")
    cfg = spec.config(None, {"params": {"focus": F}, "seed": seed})
    task = make_task(spec, cfg)
    torch.manual_seed(seed)
    model = task.build_model()
    t = cfg.training
    opt = torch.optim.Adam(model.parameters(), lr=t.lr)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda it: t.lr_decay ** (it / t.lr_decay_every))
    gen = torch.Generator().manual_seed(seed)
    terms = task.terms()
    t0 = time.perf_counter()
    for step in range(t.iterations):
        active = {k for k, v in terms.items() if v.weight > 0 and step >= v.start}
        L = task.loss_terms(model, step, active, gen)
        loss = sum(terms[k].weight * L[k] for k in active)
        opt.zero_grad()
        loss.backward()
        nn.utils.clip_grad_norm_(model.parameters(), t.grad_clip)
        opt.step()
        sched.step()
    return evaluate_mirror(model, task.params), time.perf_counter() - t0


@pytest.mark.slow
@pytest.mark.parametrize("F", [1.0, 0.5])
def test_training_reaches_the_parabola(F):
    res, _ = _train(F)
    assert res["max_abs_error_vs_exact"] <= 2e-3
