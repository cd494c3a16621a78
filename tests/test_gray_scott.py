"""The Gray-Scott generative PINN task: params, losses, derivative options, distances, verification."""

import math

import numpy as np
import pytest
import torch
from torch import nn

from ginn.config import GSParams, build_config
from ginn.errors import ConfigError
from ginn.tasks.gray_scott import (
    GrayScottField,
    GrayScottTask,
    parse_params,
    pattern_distance,
    sample_grid,
    shift_invariant_sq_distance,
)
from ginn.tasks.gray_scott.checks import translation_invariant_distance, verify_fields


def _cfg(**params):
    return build_config({
        "problem": "gray-scott",
        "model": {"kind": "siren", "hidden": [16, 8], "w0_first": 1.0},
        "latents": {"n_shapes": 3, "dim": 2},
        "params": {"kind": "gray-scott", "grid": 32, **params},
    })


class _Analytic(nn.Module):
    """A smooth band-limited periodic field of (x, z): ``a + b sin(2 pi (m . x) + z_0)``."""

    def __init__(self, a, b, m):
        super().__init__()
        self.a, self.b, self.m = a, b, m
        self.dummy = nn.Parameter(torch.zeros((), dtype=torch.float64))

    def forward(self, x, z):
        ph = 2 * math.pi * (self.m[0] * x[:, 0] + self.m[1] * x[:, 1]) + z[:, 0]
        return self.a + self.b * torch.sin(ph) + self.dummy


def _terms(task, model, seed=0):
    g = torch.Generator().manual_seed(seed)
    return task.loss_terms(model, 0, {"residual", "gradient", "diversity"}, g)


def test_params_defaults_and_errors():
    p = parse_params({})
    assert p.gs == GSParams(D_v=1.2e-5, D_u=2.4e-5, alpha=0.028, beta=0.057)
    assert p.losses.residual.weight == 1.0 and p.losses.gradient.weight == 1e-4 and p.losses.diversity.weight == 1e-7
    with pytest.raises(ConfigError, match=r"params\.bogus"):
        parse_params({"bogus": 1})
    with pytest.raises(ConfigError, match=r"params\.alpha"):
        parse_params({"alpha": -1})
    with pytest.raises(ConfigError, match=r"params\.derivatives"):
        parse_params({"derivatives": "magic"})
    with pytest.raises(ConfigError, match=r"params\.losses\.gradient\.weight"):
        parse_params({"losses": {"gradient": {"weight": -1}}})


def test_analytic_loss_values():
    """Residual and gradient reward of a known field, all three derivative options, exact up to FD symbols."""
    a_u, b_u, a_v, b_v, m = 0.8, 0.1, 0.2, 0.05, (3, 2)
    k2 = (2 * math.pi) ** 2 * (m[0] ** 2 + m[1] ** 2)
    n = 32
    for method in ["spectral", "autograd", "fd"]:
        task = GrayScottTask(_cfg(derivatives=method), torch.device("cpu"), torch.float64)
        model = GrayScottField(_Analytic(a_u, b_u, m), _Analytic(a_v, b_v, m))
        t = _terms(task, model)
        # reference computed in float64 on the same translated grid
        g = torch.Generator().manual_seed(0)
        off = torch.rand(2, generator=g, dtype=torch.float64)
        i = torch.arange(n, dtype=torch.float64)
        X0, X1 = torch.meshgrid((i + off[0]) / n, (i + off[1]) / n, indexing="ij")
        p = task.params.gs
        if method == "fd":
            lap_sym = -sum((2 - 2 * math.cos(2 * math.pi * mi / n)) * n * n for mi in m)
            grad2_sym = sum((math.sin(2 * math.pi * mi / n) * n) ** 2 for mi in m)
        else:
            lap_sym, grad2_sym = -k2, k2
        res, g2 = 0.0, []
        for z0 in task.Z[:, 0]:
            ph = 2 * math.pi * (m[0] * X0 + m[1] * X1) + z0
            u, v = a_u + b_u * torch.sin(ph), a_v + b_v * torch.sin(ph)
            Ru = p.D_u * lap_sym * (u - a_u) - u * v * v + p.alpha * (1 - u)
            Rv = p.D_v * lap_sym * (v - a_v) + u * v * v - (p.alpha + p.beta) * v
            res += ((Ru**2).mean() + (Rv**2).mean()) / 3
            g2.append(((b_u**2 + b_v**2) * grad2_sym * torch.cos(ph) ** 2).mean())
        assert t["residual"].item() == pytest.approx(res.item(), rel=1e-10)
        expect_grad = -torch.clamp(torch.stack(g2), max=1.0).mean()
        assert t["gradient"].item() == pytest.approx(expect_grad.item(), rel=1e-10)


def test_gradient_reward_is_capped():
    task = GrayScottTask(_cfg(derivatives="spectral", gradient_cap=1.0), torch.device("cpu"), torch.float64)
    big = GrayScottField(_Analytic(0.5, 1.0, (4, 0)), _Analytic(0.2, 1.0, (0, 4)))  # mean |grad|^2 >> 1
    assert _terms(task, big)["gradient"].item() == pytest.approx(-1.0, abs=1e-12)
    small = GrayScottField(_Analytic(0.5, 1e-3, (1, 0)), _Analytic(0.2, 1e-3, (0, 1)))
    expect = (2 * math.pi) ** 2 * 1e-6 * 0.5 * 2
    assert _terms(task, small)["gradient"].item() == pytest.approx(-expect, rel=1e-9)


def test_fd_and_autograd_agree_on_a_smooth_network():
    cfg_fd = _cfg(derivatives="spectral", grid=48)
    torch.manual_seed(0)
    task = GrayScottTask(cfg_fd, torch.device("cpu"), torch.float64)
    model = task.build_model()  # SIREN with w0_first = 1 on the periodic encoding: smooth
    t_spec = _terms(task, model)
    t_auto = _terms(GrayScottTask(_cfg(derivatives="autograd", grid=48), torch.device("cpu"), torch.float64), model)
    t_fd = _terms(GrayScottTask(_cfg(derivatives="fd", grid=48), torch.device("cpu"), torch.float64), model)
    assert t_spec["residual"].item() == pytest.approx(t_auto["residual"].item(), rel=1e-8)
    assert t_spec["gradient"].item() == pytest.approx(t_auto["gradient"].item(), rel=1e-8)
    assert t_fd["residual"].item() == pytest.approx(t_auto["residual"].item(), rel=2e-2)
    assert t_fd["gradient"].item() == pytest.approx(t_auto["gradient"].item(), rel=2e-2)


def test_shift_invariant_distance_ignores_translations():
    n = 32
    g = torch.Generator().manual_seed(3)
    A = torch.randn(n, n, generator=g, dtype=torch.float64)
    B = torch.roll(A, shifts=(5, -9), dims=(0, 1))
    C = torch.randn(n, n, generator=g, dtype=torch.float64)
    V = torch.stack([A, B, C])
    D = shift_invariant_sq_distance(V, V)
    assert D[0, 1].item() == pytest.approx(0.0, abs=1e-12)
    assert D[0, 2].item() == pytest.approx(D[2, 0].item(), rel=1e-10)
    brute = min(((A - torch.roll(C, (i, j), (0, 1))) ** 2).mean().item() for i in range(n) for j in range(n))
    assert D[0, 2].item() == pytest.approx(brute, rel=1e-10)
    R = pattern_distance(V, "rms")
    assert R[0, 1].item() > 1.0
    Dn = translation_invariant_distance(V.numpy())
    assert Dn[0, 1] < 1e-6 and Dn[0, 2] == pytest.approx(math.sqrt(brute), rel=1e-8)


def test_verify_fields_flags_uniform_and_noise():
    n = 32
    rng = np.random.default_rng(0)
    uniform = np.stack([np.ones((n, n)), np.zeros((n, n))])
    noise = np.stack([1 - 0.3 * rng.random((n, n)), 0.3 * rng.random((n, n))])
    out = verify_fields(np.stack([uniform, noise]), GSParams())
    a, b = out["latents"]
    assert a["residual_u"] == 0.0 and a["residual_v"] == 0.0 and a["rel"] == 0.0  # the uniform state solves eq. 3
    assert a["change"] == 0.0 and a["checks"]["stationary"]  # ... and is a fixed point of the solver
    assert not a["checks"]["nontrivial"]
    assert b["checks"]["nontrivial"] and not b["checks"]["residual"] and not b["checks"]["stationary"]
    assert out["latents_passing"] == 0
    assert out["distance_matrix"][0][1] > 0.05


def test_finalize_and_verify_run_write_files(tmp_path):
    torch.manual_seed(0)
    task = GrayScottTask(_cfg(resolution=16, n_interpolation=3), torch.device("cpu"), torch.float32)
    model = task.build_model()
    files = task.results.finalize(model, tmp_path)
    names = {f.name for f in files}
    assert {"u_00.npy", "v_02.npy", "v_01.png", "patterns_v.png", "interpolation_v.png"} <= names
    v0 = np.load(tmp_path / "patterns" / "v_00.npy")
    assert v0.shape == (16, 16)
    from ginn.tasks.gray_scott.checks import Thresholds, verify_run

    out = verify_run(model, task.latents(), task.cfg.params, resolution=16, out_dir=tmp_path,
                     thresholds=Thresholds(t_final=10.0))
    assert out["n_latents"] == 3 and 0 <= out["latents_passing"] <= 3
    assert np.load(tmp_path / "verify_u_02.npy").shape == (16, 16)
    # the sampled grid is the same one finalize used (x = (i, j) / n)
    assert np.allclose(np.load(tmp_path / "verify_v_00.npy"), v0, atol=1e-6)


@pytest.mark.slow
def test_quick_preset_acceptance(tmp_path):
    """The acceptance of the quick preset: >= 8 latents pass all four checks."""
    from ginn.problems.loader import get_spec
    from ginn.tasks import make_task
    from ginn.tasks.gray_scott.checks import verify_run
    from ginn.train.trainer import Trainer

    spec = get_spec("gray-scott")
    cfg = spec.config("quick")
    task = make_task(spec, cfg)
    result = Trainer(task, cfg, tmp_path, progress=False).train()
    out = verify_run(result.model, task.latents(), cfg.params, resolution=256, out_dir=tmp_path)
    assert out["latents_passing"] >= 8, out["latents_passing"]


def test_flow_gradient_is_the_pde_time_derivative():
    """residual_gradient=flow: value mean(R^2), gradient -2 mean(R_u du/dtheta + R_v dv/dtheta)."""
    m = (2, 1)
    for mode in ["flow", "full"]:
        task = GrayScottTask(_cfg(derivatives="spectral", residual_gradient=mode), torch.device("cpu"), torch.float64)
        fu, fv = _Analytic(0.7, 0.1, m), _Analytic(0.2, 0.05, m)
        model = GrayScottField(fu, fv)
        g = torch.Generator().manual_seed(0)
        t = task.loss_terms(model, 0, {"residual"}, g)
        t["residual"].backward()
        # recompute R on the same grid without graph
        g = torch.Generator().manual_seed(0)
        off = torch.rand(2, generator=g, dtype=torch.float64)
        with torch.no_grad():
            W, G, Lap = task.fields_and_derivatives(model, task.Z, off)
        p = task.params.gs
        u, v = W[:, 0], W[:, 1]
        Ru = p.D_u * Lap[:, 0] - u * v * v + p.alpha * (1 - u)
        Rv = p.D_v * Lap[:, 1] + u * v * v - (p.alpha + p.beta) * v
        assert t["residual"].item() == pytest.approx(((Ru**2).mean() + (Rv**2).mean()).item(), rel=1e-12)
        if mode == "flow":  # the dummy parameters shift u (resp. v) by a constant: dW/dtheta = 1
            assert fu.dummy.grad.item() == pytest.approx(-2 * Ru.mean().item(), rel=1e-10)
            assert fv.dummy.grad.item() == pytest.approx(-2 * Rv.mean().item(), rel=1e-10)
        else:  # d/dc of mean(R^2) for u -> u + c: 2 mean(R_u (-v^2 - alpha) + R_v v^2)
            expect = 2 * (Ru * (-v * v - p.alpha) + Rv * v * v).mean()
            assert fu.dummy.grad.item() == pytest.approx(expect.item(), rel=1e-10)


def test_interpolation_latents_run_between_the_first_two_codes():
    from ginn.tasks.gray_scott.figures import interpolation_latents

    Z = torch.tensor([[-1.0, 0.0], [1.0, 2.0], [5.0, 5.0]], dtype=torch.float64)
    I = interpolation_latents(Z, 5)
    assert torch.allclose(I[0], Z[0]) and torch.allclose(I[-1], Z[1])
    assert torch.allclose(I[2], torch.tensor([0.0, 1.0], dtype=torch.float64))


def test_fourier_model_and_bad_model_kind():
    cfg = build_config({"problem": "gray-scott", "model": {"kind": "fourier", "hidden": [16, 8], "sigma": 3.0, "n_features": 8},
                        "latents": {"n_shapes": 2, "dim": 1}, "params": {"kind": "gray-scott", "grid": 16}})
    task = GrayScottTask(cfg, torch.device("cpu"), torch.float32)
    model = task.build_model()
    x = torch.rand(5, 2)
    z = torch.zeros(5, 1)
    # periodic: shifting x by whole periods changes nothing
    assert torch.allclose(model(x, z), model(x + torch.tensor([1.0, -2.0]), z), atol=1e-5)
    t = _terms(task, model)
    assert all(torch.isfinite(v) for v in t.values())
    bad = build_config({"problem": "gray-scott", "model": {"kind": "resmlp"}})
    with pytest.raises(ConfigError, match="model.kind"):
        GrayScottTask(bad, torch.device("cpu"), torch.float32).build_model()


def test_step_target_is_reused_and_shifted_for_step_reuse_iterations():
    """``residual_gradient = step`` with ``step_reuse = 3``: the target computed at iteration 0 is
    reused (moved by an exact Fourier shift to the new grid offset) at iterations 1 and 2, and
    recomputed from the current state at iteration 3; with ``step_reuse = 1`` it is always fresh."""
    from ginn.extract.grid import periodic_points as grid_points
    from ginn.tasks.gray_scott import pseudo_time_step
    from ginn.tasks.gray_scott.finite_diff import fourier_shift

    cfg = _cfg(residual_gradient="step", step_reuse=3, step_count=5, grid=16)
    task = GrayScottTask(cfg, torch.device("cpu"), torch.float64)
    gs = task.params.gs
    Z = torch.zeros(2, 2, dtype=torch.float64)

    def state(offset, amp):  # a band-limited pattern on the translated grid, (S, 2, n, n)
        X = grid_points(16, offset, dtype=torch.float64)
        f = torch.sin(2 * math.pi * (2 * X[..., 0] + X[..., 1]))
        return torch.stack([1.0 - amp * f, amp * (1 + f)])[None].expand(2, -1, -1, -1).clone()

    o0, o1, o3 = (torch.tensor(o, dtype=torch.float64) for o in ([0.2, 0.5], [0.7, 0.1], [0.4, 0.9]))
    T0 = task._step_target(state(o0, 0.2), Z, o0, 0)
    assert torch.allclose(T0, pseudo_time_step(state(o0, 0.2), gs, 1.0, 5), atol=1e-14)
    # iteration 1: another state (amp 0.3) and offset, but the stored target, shifted
    T1 = task._step_target(state(o1, 0.3), Z, o1, 1)
    assert torch.allclose(T1, fourier_shift(T0, o1 - o0), atol=1e-12)
    assert not torch.allclose(T1, pseudo_time_step(state(o1, 0.3), gs, 1.0, 5), atol=1e-3)  # not recomputed
    T3 = task._step_target(state(o3, 0.3), Z, o3, 3)
    assert torch.allclose(T3, pseudo_time_step(state(o3, 0.3), gs, 1.0, 5), atol=1e-14)

    fresh = GrayScottTask(_cfg(residual_gradient="step", step_reuse=1, step_count=5, grid=16), torch.device("cpu"), torch.float64)
    fresh._step_target(state(o0, 0.2), Z, o0, 0)
    assert torch.allclose(fresh._step_target(state(o1, 0.3), Z, o1, 1), pseudo_time_step(state(o1, 0.3), gs, 1.0, 5), atol=1e-14)


def test_step_sobolev_adds_the_diffusion_weighted_misfit():
    """``step_sobolev = c``: the logged misfit is ``mean |W - T|^2 + c mean |D lap (W - T)|^2``;
    for ``W - T = eps sin(2 pi m . x)`` in v only (u exact) that is
    ``eps^2 / 4 (1 + c D_v^2 (2 pi |m|)^4)`` (half of the entries are v's, mean sin^2 = 1/2)."""
    eps, m, c = 0.01, (3, 2), 100.0
    task = GrayScottTask(_cfg(derivatives="spectral", residual_gradient="step", step_sobolev=c), torch.device("cpu"), torch.float64)
    model = GrayScottField(_Analytic(0.8, 0.1, m), _Analytic(0.2, 0.05, m))
    n = task.params.grid

    def target(W, Z, offset, step):
        X = grid_points(n, offset, dtype=W.dtype)
        d = eps * torch.sin(2 * math.pi * (m[0] * X[..., 0] + m[1] * X[..., 1]))
        T = W.detach().clone()
        T[:, 1] -= d
        return T

    from ginn.extract.grid import periodic_points as grid_points

    task._step_target = target
    out = _terms(task, model)
    k2 = (2 * math.pi) ** 2 * (m[0] ** 2 + m[1] ** 2)
    expected = eps**2 / 4 * (1 + c * task.params.gs.D_v**2 * k2**2)
    assert out["_step_misfit"].item() == pytest.approx(expected, rel=1e-10)


def test_fine_grid_takes_over_from_fine_grid_from():
    """``fine_grid = 16, fine_grid_from = 2`` on a ``grid = 8`` run: iterations 0 and 1 train on 8²,
    from iteration 2 on 16². Checked through the loss: for ``v = 0.2 + 0.05 sin(2 pi (5 x + y))``
    (5 cycles: aliased on 8², exact on 16²) the logged mean(R^2) equals the residual recomputed on the
    grid of that iteration, and the two grids give different values."""
    from ginn.tasks.gray_scott.solver import residuals

    task = GrayScottTask(_cfg(derivatives="spectral", grid=8, fine_grid=16, fine_grid_from=2, D_v=1e-3),
                        torch.device("cpu"), torch.float64)
    assert [task.grid_at(s) for s in (0, 1, 2, 50)] == [8, 8, 16, 16]
    model = GrayScottField(_Analytic(0.8, 0.1, (5, 1)), _Analytic(0.2, 0.05, (5, 1)))

    def expected(n, off):  # the solver's own (NumPy, spectral) residual on the n-point grid
        W = sample_grid(model, task.Z, n, off).detach().numpy()
        Ru, Rv = residuals(W[:, 0], W[:, 1], task.params.gs)
        return float((Ru**2).mean() + (Rv**2).mean())

    got = {}
    for step in (1, 2):
        g = torch.Generator().manual_seed(0)
        got[step] = task.loss_terms(model, step, {"residual"}, g)["_residual"].item()
    off = torch.rand(2, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    assert got[1] == pytest.approx(expected(8, off), rel=1e-12)
    assert got[2] == pytest.approx(expected(16, off), rel=1e-12)
    assert abs(got[1] - got[2]) > 0.3 * got[2]  # with D_v = 1e-3 the diffusion term dominates R


def test_flow_steps_switches_step_to_the_full_residual_gradient():
    """``residual_gradient = step, flow_steps = 2``: iteration 1 optimises the step regression (its
    gradient differs from that of mean(R^2)), from iteration 2 on the residual term's gradient is
    exactly the paper's gradient of mean(R^2) (the quick preset's final polish)."""
    def grads(task, step):
        model = GrayScottField(_Analytic(0.8, 0.1, (3, 1)), _Analytic(0.2, 0.05, (3, 1)))
        g = torch.Generator().manual_seed(step)
        out = task.loss_terms(model, step, {"residual"}, g)
        return torch.stack(torch.autograd.grad(out["residual"], list(model.parameters()))), out

    kw = dict(derivatives="spectral", grid=16, D_v=1e-3, step_count=5)
    switched = GrayScottTask(_cfg(residual_gradient="step", flow_steps=2, **kw), torch.device("cpu"), torch.float64)
    full = GrayScottTask(_cfg(residual_gradient="full", **kw), torch.device("cpu"), torch.float64)
    g1, out1 = grads(switched, 1)
    g2, out2 = grads(switched, 2)
    f1, _ = grads(full, 1)
    f2, _ = grads(full, 2)
    assert "_step_misfit" in out1 and "_step_misfit" not in out2
    assert torch.allclose(g2, f2, rtol=1e-12, atol=0) and f2.abs().min() > 0
    assert not torch.allclose(g1, f1, rtol=1e-2)


def test_resume_mid_target_is_bitwise_identical(tmp_path):
    """``residual_gradient = step, step_reuse = 4``: a run stopped at iteration 6 (in the middle of a
    target's 4 iterations) and resumed from its checkpoint ends with exactly the weights of the
    uninterrupted run: the stored target travels in the checkpoint."""
    from ginn.train.trainer import Trainer

    def run(iterations, out, resume=False):
        c = build_config({
            "problem": "gray-scott", "seed": 1,
            "model": {"kind": "siren", "hidden": [8, 4], "w0_first": 5.0},
            "latents": {"n_shapes": 2, "dim": 1},
            "params": {"kind": "gray-scott", "grid": 8, "derivatives": "spectral", "residual_gradient": "step", "step_reuse": 4,
                       "step_count": 3, "D_v": 1e-3},
            "training": {"iterations": iterations, "lr": 1e-3, "checkpoint_every": 100, "log_every": 100},
        })
        tr = Trainer(GrayScottTask(c, torch.device("cpu"), torch.float32), c, out, progress=False)
        if resume:
            assert tr.resume() and tr.step == 6
        return torch.cat([q.detach().flatten() for q in tr.train().model.parameters()])

    full = run(10, tmp_path / "a")
    run(6, tmp_path / "b")
    assert torch.equal(full, run(10, tmp_path / "b", resume=True))
