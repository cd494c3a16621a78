"""The latent set of a generative model: the codes drawn at each step cover Z, the held-out codes,
the feasible share of Z and the smoothness of z -> shape on a field whose answer is known."""

import math

import numpy as np
import pytest
import torch

from ginn.config import LatentConfig, build_config
from ginn.eval.latent_space import LatentJudge, axis_paths, survey_latents
from ginn.models.latents import heldout_latents, lattice_generator, lattice_latents, lattice_span, step_latents, unit_lattice
from ginn.problems import validate_spec


@pytest.mark.parametrize("n, k", [(4, 1), (16, 1), (16, 2), (64, 2), (33, 3)])
def test_every_draw_is_stratified_along_each_axis(n, k):
    """Each coordinate of every draw holds one code in each of the n equal strata of the span."""
    cfg = LatentConfig(n_shapes=n, dim=k, low=-1.0, high=2.0)
    lo, hi = lattice_span(cfg)
    g = torch.Generator().manual_seed(3)
    for _ in range(20):
        Z = lattice_latents(cfg, g, dtype=torch.float64)
        assert Z.shape == (n, k)
        cell = torch.floor((Z - lo) / (hi - lo) * n).long()
        for a in range(k):
            assert sorted(cell[:, a].tolist()) == list(range(n))


def test_draws_cover_the_span_uniformly_and_the_span_holds_z_with_half_a_cell_each_side():
    cfg = LatentConfig(n_shapes=4, dim=1, low=-1.0, high=1.0)
    lo, hi = lattice_span(cfg)
    assert (lo, hi) == pytest.approx((-1 - 1 / 3, 1 + 1 / 3))  # half the reported spacing 2/3
    g = torch.Generator().manual_seed(0)
    z = torch.cat([lattice_latents(cfg, g, dtype=torch.float64)[:, 0] for _ in range(4000)]).numpy()
    u = np.sort((z - lo) / (hi - lo))
    ks = np.max(np.abs(u - (np.arange(1, len(u) + 1) - 0.5) / len(u)))
    assert ks < 0.02  # the empirical distribution is uniform on the span (16000 codes)
    # the lattice shifted by half a cell is the reported set
    half = lo + (hi - lo) * unit_lattice(4, 1, torch.tensor([0.5 / 4]))[:, 0]
    assert half.tolist() == pytest.approx([-1.0, -1 / 3, 1 / 3, 1.0])


def test_lattice_spreads_codes_in_two_dimensions():
    """The generator maximises the smallest distance on the torus: no two codes of 16 closer than a
    Latin hypercube on a diagonal would put them (1/16 * sqrt 2)."""
    assert lattice_generator(16, 1) == (1,)
    g = lattice_generator(16, 2)
    assert math.gcd(g[1], 16) == 1 and g[1] not in (1, 15)
    P = unit_lattice(16, 2, torch.zeros(2))
    d = (P[:, None] - P[None]).abs()
    d = torch.minimum(d, 1 - d).norm(dim=-1) + torch.eye(16) * 9
    assert float(d.min()) > 1.5 / 16


def test_step_latents_by_draw():
    g = torch.Generator().manual_seed(0)
    rep = torch.linspace(-1, 1, 4)[:, None]
    assert step_latents(LatentConfig(n_shapes=4, draw="fixed"), g, rep) is rep
    assert step_latents(LatentConfig(n_shapes=1, draw="lattice"), g, None) is None
    u = step_latents(LatentConfig(n_shapes=4, draw="uniform"), g, rep)
    assert u.shape == (4, 1) and float(u.abs().max()) <= 1


def test_heldout_codes_are_the_stratum_centres_in_one_dimension():
    h = heldout_latents(LatentConfig(n_shapes=4), 8, dtype=torch.float64)[:, 0]
    assert h.tolist() == pytest.approx([-0.875, -0.625, -0.375, -0.125, 0.125, 0.375, 0.625, 0.875])
    h2 = heldout_latents(LatentConfig(n_shapes=4, dim=2, low=0.0, high=1.0), 16, dtype=torch.float64)
    assert float(h2.min()) > 0 and float(h2.max()) < 1


def test_old_latents_random_setting_reads_as_its_draw():
    assert build_config({"latents": {"random": True}}).latents.draw == "uniform"
    assert build_config({"latents": {"random": False}}).latents.draw == "fixed"


# --- the feasible share of Z on a field with a known answer -------------------------------------

SPEC = {"name": "growing-bar", "geometry": {
    "dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
    "design_region": {"type": "rectangle", "lo": [-0.5, -0.2], "hi": [0.1, 0.2]},
    "interfaces": [{"type": "segment", "a": [-0.5, -0.1], "b": [-0.5, 0.1], "normal": [-1, 0]}]},
    "tolerances": {"volume_outside": 1.0e-6}}


def bar(x, z):
    """A bar [-0.5, -0.5 + w] x [-0.1, 0.1] (its SDF) with w = 0.45 + 0.35 z: inside E (which ends at
    x = 0.1) while w <= 0.6, i.e. z <= 3 / 7."""
    w = 0.45 + 0.35 * z[:, 0]
    c = torch.stack([-0.5 + 0.5 * w, torch.zeros_like(w)], -1)
    h = torch.stack([0.5 * w, torch.full_like(w, 0.1)], -1)
    q = (x - c).abs() - h
    return q.clamp_min(0).norm(dim=-1) + q.max(-1).values.clamp_max(0)


def test_feasible_share_of_z_matches_the_analytic_interval():
    problem = validate_spec(SPEC).build()
    judge = LatentJudge(problem, 256)
    codes = heldout_latents(LatentConfig(n_shapes=2), 64, dtype=torch.float64)
    survey = survey_latents(bar, codes, judge)
    s = survey.summary
    z_star = 3 / 7
    expected = int(((codes[:, 0] <= z_star)).sum())
    cell = 2 / 256 / 0.35  # a grid cell of bar length, in latent units
    near = int(((codes[:, 0] - z_star).abs() <= cell).sum())
    assert abs(s.feasible - expected) <= near and s.shapes == 64
    ok = [not v for v in s.violations]
    assert all(ok[i] for i in range(64) if float(codes[i, 0]) < z_star - cell)
    assert not any(ok[i] for i in range(64) if float(codes[i, 0]) > z_star + cell)
    z, ratio, bad = s.worst_latent()
    assert z == pytest.approx([float(codes[-1, 0])]) and "volume_outside" in bad and ratio > 1
    # the bar grows at 0.35 per unit latent: its boundary moves at most that much (chamfer <= shift)
    sm = survey.smoothness
    assert sm["path_codes"] == 64 and sm["topology_changes"] == 0
    assert 0.05 < sm["change_rate_mean"] <= sm["change_rate_max"] < 0.35 * 1.1


def test_axis_paths_cross_the_centre():
    P = axis_paths(-1.0, 1.0, 3, 5)
    assert len(P) == 3 and P[1][:, 1].tolist() == [-1.0, -0.5, 0.0, 0.5, 1.0]
    assert P[1][:, 0].tolist() == [0.0] * 5 and P[1][:, 2].tolist() == [0.0] * 5


def test_the_judge_of_any_code_gives_the_verdict_of_ginn_eval():
    """``ginn export --latent`` and ``ginn view`` judge a code with :class:`LatentJudge`: at the
    reported codes its metrics and verdicts are those of ``ginn eval`` (``evaluate_shapes``)."""
    from ginn.eval.shapes import evaluate_shapes

    problem = validate_spec(SPEC).build()
    Z = torch.tensor([[-0.5], [0.2], [0.5], [0.9]], dtype=torch.float64)
    ev = evaluate_shapes(bar, Z, problem, 256)
    judged = LatentJudge(problem, 256).latents(bar, Z)
    assert [sorted(v) for v in judged.violations] == [sorted(v) for v in ev.feasibility.violations]
    assert judged.feasible == 2 and [bool(v) for v in judged.violations] == [False, False, True, True]
    one = LatentJudge(problem, 256)
    for i, m in enumerate(ev.shapes):
        mine = one.shape(bar, Z[i])[0]
        for k in ("interface_cd1", "volume_outside_off_interfaces", "b0_in_design_region", "connected_interfaces_share"):
            assert mine.get(k) == pytest.approx(m.get(k), rel=1e-12, abs=1e-15), (i, k)


def test_explorer_spans_the_latent_box_in_two_dimensions():
    from ginn.viz.explorer import explorer_latents

    lat = explorer_latents(torch.rand(5, 3), 16, box=(-1.0, 1.0))
    assert lat.grid == (4, 4) and len(lat.codes) == 16
    assert lat.codes[0].tolist() == [-1.0, -1.0, 0.0] and lat.codes[-1].tolist() == [1.0, 1.0, 0.0]
    assert lat.codes[1].tolist() == pytest.approx([-1.0, -1 / 3, 0.0])


def test_latent_scale_keeps_the_latent_box_as_many_periods_as_one_axis():
    """Unset ``model.latent_scale`` resolves to ``(r w)^(1/k - 1)``: 1 in one dimension; in k
    dimensions each axis spans ``(r w)^(1/k)`` radians of the first layer, so the box holds
    ``r w`` cells like the interval; a value the user sets stays, and the resolved value is what
    the run's config records (so a run keeps its scale when the rule changes)."""
    from ginn import runs

    _, one = runs.resolve("obstacle", None)
    assert one.model.latent_scale == 1.0
    for k in (2, 3):
        _, cfg = runs.resolve("obstacle", None, sets=[f"latents.dim={k}", "latents.low=-0.5", "latents.high=1.5"])
        w, r = cfg.model.w0_first, 2.0
        assert cfg.model.latent_scale == pytest.approx((r * w) ** (1.0 / k - 1.0), rel=1e-12)
        assert (r * w * cfg.model.latent_scale) ** k == pytest.approx(r * w, rel=1e-9)
        assert build_config(cfg.model_dump()).model.latent_scale == cfg.model.latent_scale
    _, mlp = runs.resolve("obstacle", None, sets=["latents.dim=2", "model.kind=mlp"])
    assert mlp.model.latent_scale == pytest.approx(2.0 ** -0.5)
    _, own = runs.resolve("obstacle", None, sets=["latents.dim=2", "model.latent_scale=0.5"])
    assert own.model.latent_scale == 0.5


# --- codes per step ----------------------------------------------------------------------------


def test_a_lattice_step_trains_at_least_the_floor_and_other_draws_their_shapes():
    from ginn.models.latents import step_codes
    assert step_codes(LatentConfig(n_shapes=4, draw="lattice"), 16) == 16
    assert step_codes(LatentConfig(n_shapes=32, draw="lattice"), 16) == 32
    assert step_codes(LatentConfig(n_shapes=4, draw="fixed"), 16) == 4
    assert step_codes(LatentConfig(n_shapes=4, draw="uniform"), 16) == 4
    assert step_codes(LatentConfig(n_shapes=1, draw="lattice"), 16) == 1
    Z = step_latents(LatentConfig(n_shapes=4, draw="lattice"), torch.Generator().manual_seed(0), None, n=16)
    assert Z.shape == (16, 1)


def test_sixteen_codes_shifted_by_half_a_cell_hold_the_four_reported_codes():
    """16 - 1 is a multiple of 4 - 1: the step's lattice at the half-cell shift contains the reported set."""
    cfg = LatentConfig(n_shapes=4, dim=1, low=-1.0, high=1.0)
    lo, hi = lattice_span(cfg, 16)
    half = (lo + (hi - lo) * unit_lattice(16, 1, torch.tensor([0.5 / 16]))[:, 0]).tolist()
    assert half == pytest.approx([-1 + 2 * i / 15 for i in range(16)])
    for z in (-1.0, -1 / 3, 1 / 3, 1.0):
        assert min(abs(z - h) for h in half) < 1e-12


def test_a_step_spreads_the_reported_shapes_samples_over_its_codes():
    """obstacle demo (4 shapes, lattice): 16 codes a step in 2D, each with a quarter of the samples,
    so the step evaluates as many points as 4 shapes did; with fixed codes nothing changes."""
    from ginn.problems import load_spec
    from ginn.tasks import make_task
    from ginn.tasks.shape.task import spread_sampling
    spec = load_spec("obstacle")
    cfg = spec.config("demo", {"sampling": {"n_interface": 64, "n_band": 0}})
    assert cfg.latents.n_shapes == 4 and cfg.latents.draw == "lattice"
    task = make_task(spec, cfg)
    assert task.step_codes == 16
    s, s0 = task.setting.cfg.sampling, cfg.sampling
    assert (s.n_interface, s.n_domain, s.n_boundary) == (16, s0.n_domain // 4, s0.n_boundary // 4)
    assert s.n_band == 0 and s.projection_steps == s0.projection_steps
    terms = task.loss_terms(task.build_model(), 0, {"interface", "normal", "eikonal"}, torch.Generator().manual_seed(0))
    assert set(terms) >= {"interface", "normal", "eikonal"}
    fixed = spec.config("demo", {"latents": {"draw": "fixed"}})
    assert make_task(spec, fixed).step_codes == 4 and spread_sampling(fixed, 4) is fixed
    odd = spread_sampling(spec.config("demo", {"sampling": {"n_interface": 3}}), 16)
    assert odd.sampling.n_interface == 1  # at least one sample per code
