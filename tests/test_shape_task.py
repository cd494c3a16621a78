"""ShapeTask sampling: every shape of a generative batch gets samples of every interface."""

import pytest
import torch

from ginn.problems import load_spec
from ginn.tasks import make_task


class _FnField(torch.nn.Module):
    """A field given by a function of the points (no latent)."""

    def __init__(self, fn):
        super().__init__()
        self.fn = fn

    def forward(self, x, z=None):
        return self.fn(x)


def _depth_outside_obstacle_region(x):
    """Distance of ``x (n, 2)`` into the complement of E of the obstacle problem: the frame around
    the rectangle [-0.9, 0.9] x [-0.4, 0.4] and the disk of radius 0.1 at the origin."""
    d_frame = torch.sqrt((x[:, 0].abs() - 0.9).clamp_min(0) ** 2 + (x[:, 1].abs() - 0.4).clamp_min(0) ** 2)
    return torch.maximum(d_frame, 0.1 - x.norm(dim=-1))


def test_every_shape_sees_every_interface():
    spec = load_spec("obstacle")
    cfg = spec.config("demo", {"sampling": {"n_interface": 64}})
    task = make_task(spec, cfg)
    gen = torch.Generator().manual_seed(0)
    pts = task.sample(4, {"interface", "normal"}, gen)
    x, n = pts["interface"], pts["normals"]
    assert x.shape == (4, 64, 2)
    for s in range(4):
        left, right = (x[s, :, 0] < 0), (x[s, :, 0] > 0)
        assert left.sum() > 10 and right.sum() > 10  # both segments x = -0.9 and x = +0.9
        # normals travel with their points: outward (-1, 0) on the left, (+1, 0) on the right
        assert torch.all(n[s, left, 0] == -1) and torch.all(n[s, right, 0] == 1)
        assert torch.allclose(x[s, :, 0].abs(), torch.full((64,), 0.9))


def test_containment_power_reaches_the_losses():
    """``losses.containment_power = 1``: the design-region and obstacle terms of a training step
    are the mean of |min(0, f)| over their samples (checked against the field's own values)."""
    spec = load_spec("obstacle")
    cfg = spec.config("single", {"losses": {"containment_power": 1}})
    task = make_task(spec, cfg)
    torch.manual_seed(0)
    model = task.build_model()
    with torch.no_grad():  # shift the untrained field so that both constraints are violated somewhere
        model.core[-1].bias.fill_(-0.3)
    active = {"design_region", "obstacle"}
    pts = task.sample(1, active, torch.Generator().manual_seed(3))  # what loss_terms draws with this seed
    out = task.loss_terms(model, 0, active, torch.Generator().manual_seed(3))
    with torch.no_grad():
        f_out, f_obs = model(pts["outside"][0], None), model(pts["obstacle"][0], None)
    for name, f in (("design_region", f_out), ("obstacle", f_obs)):
        expected = f.clamp(max=0).abs().mean().item()
        assert expected > 0  # the untrained field violates both somewhere
        assert out[name].item() == pytest.approx(expected, rel=1e-5)


def test_containment_slope_is_exact_for_sdfs_and_catches_flat_fields():
    """``losses.containment_slope = 1``: an exact SDF of a shape inside E (a disk of radius 0.2
    centred at (0.5, 0)) costs nothing, while the nearly flat field ``f = 1e-3`` (which the
    paper's loss accepts: f > 0 outside E) is penalised by the mean of (d_E(x) - 1e-3)^2 over the
    samples outside E; inside the obstacle the floor is the depth into it."""
    spec = load_spec("obstacle")
    cfg = spec.config("single", {"losses": {"containment_slope": 1.0}})
    task = make_task(spec, cfg)
    active = {"design_region", "obstacle"}

    c = torch.tensor([0.5, 0.0])
    sdf = _FnField(lambda x: (x - c).norm(dim=-1) - 0.2)
    out = task.loss_terms(sdf, 0, active, torch.Generator().manual_seed(5))
    assert out["design_region"].item() == 0.0 and out["obstacle"].item() == 0.0

    flat = _FnField(lambda x: 0.0 * x[:, 0] + 1e-3)
    out = task.loss_terms(flat, 0, active, torch.Generator().manual_seed(5))
    pts = task.sample(1, active, torch.Generator().manual_seed(5))
    xo = pts["outside"][0]
    d_out = _depth_outside_obstacle_region(xo)
    expected = (1e-3 - d_out).clamp(max=0).pow(2).mean().item()
    assert expected > 1e-4 and out["design_region"].item() == pytest.approx(expected, rel=1e-5)
    d_obs = (0.1 - pts["obstacle"][0].norm(dim=-1)).clamp_min(0)  # depth into the disk
    assert out["obstacle"].item() == pytest.approx((1e-3 - d_obs).clamp(max=0).pow(2).mean().item(), rel=1e-5)


def test_diversity_interface_clearance_drops_points_near_interfaces():
    """``diversity.interface_clearance``: boundary points within the clearance of an interface
    leave the shape distance. Distances to the obstacle's interfaces (x = +-0.9, |y| <= 0.4) are
    exact here, and with a clearance larger than the domain no point is left, so the term vanishes."""
    spec = load_spec("obstacle")
    cfg = spec.config("demo", {})
    task = make_task(spec, cfg)
    pts = torch.tensor([[-0.85, 0.0], [-0.75, 0.1], [0.89, 0.39], [0.0, 0.0], [0.9, 0.45]])
    # distances: 0.05, 0.15, 0.01, 0.9, 0.05 (to the end point (0.9, 0.4))
    assert task._away_from_interfaces(pts, 0.1).tolist() == [False, True, False, True, False]
    assert task._away_from_interfaces(pts, 0.0).all()

    class Disks(torch.nn.Module):  # shape z: the disk of radius 0.3 centred at (0.3 z, 0), as an SDF
        def forward(self, x, z):
            return (x - torch.cat([0.3 * z, torch.zeros_like(z)], dim=-1)).norm(dim=-1) - 0.3

    model, active = Disks(), {"diversity"}

    def term(clearance):
        t = make_task(spec, spec.config("demo", {"diversity": {"interface_clearance": clearance}}))
        return t.loss_terms(model, 0, active, torch.Generator().manual_seed(1))["diversity"].item()

    full, near, none_left = term(0.0), term(0.25), term(10.0)
    assert full < -0.1  # four distinct disks
    assert near == full  # every disk stays at least 0.3 away from the interfaces
    # no sample left: every distance is its floor sqrt(1e-12), delta = (4 * (1e-6)^(1/2))^2
    assert none_left == pytest.approx(-1.6e-5, rel=1e-5)


def test_containment_margin_shifts_the_floor_outwards():
    """``losses.containment_margin = m``: the floor is ``slope * max(0, d_E - m)``; the flat field
    ``f = 1e-3`` then costs the mean of (max(0, d_E - m) - 1e-3)_+^2 outside E, and the field
    ``max(0, d_E - m)`` costs nothing (and something without the margin)."""
    spec = load_spec("obstacle")
    m = 0.03
    cfg = spec.config("single", {"losses": {"containment_slope": 1.0, "containment_margin": m}})
    task = make_task(spec, cfg)
    active = {"design_region"}

    d_out = _depth_outside_obstacle_region

    flat = _FnField(lambda x: 0.0 * x[:, 0] + 1e-3)
    out = task.loss_terms(flat, 0, active, torch.Generator().manual_seed(5))
    xo = task.sample(1, active, torch.Generator().manual_seed(5))["outside"][0]
    expected = (1e-3 - (d_out(xo) - m).clamp_min(0)).clamp(max=0).pow(2).mean().item()
    assert expected > 1e-4 and out["design_region"].item() == pytest.approx(expected, rel=1e-5)
    late = _FnField(lambda x: (d_out(x) - m).clamp_min(0))  # zero up to m beyond E, then slope 1
    assert task.loss_terms(late, 0, active, torch.Generator().manual_seed(5))["design_region"].item() < 1e-15
    plain = make_task(spec, spec.config("single", {"losses": {"containment_slope": 1.0}}))
    assert plain.loss_terms(late, 0, active, torch.Generator().manual_seed(5))["design_region"].item() > 1e-5


def test_band_containment_adds_the_band_points_outside_E():
    """``sampling.band_containment``: the design-region term is the mean penalty over the uniform
    samples outside E *and* the band samples (within ``interface_band`` of an interface) that lie
    outside E. The obstacle's interfaces x = +-0.9 lie on dE, so about half of the band is outside."""
    base = load_spec("obstacle")
    spec = base.model_copy(update={"geometry": base.geometry.model_copy(update={"interface_band": 0.05})})
    over = {"sampling": {"n_band": 256, "n_outside": 64}}
    task = make_task(spec, spec.config("single", {**over, "sampling": {**over["sampling"], "band_containment": True}}))
    plain = make_task(spec, spec.config("single", over))
    active = {"design_region"}
    # a film of half-width 0.02 around the interfaces: it leaves E only near them
    field = _FnField(lambda x: torch.sqrt((x[:, 0].abs() - 0.9) ** 2 + (x[:, 1].abs() - 0.4).clamp_min(0) ** 2) - 0.02)
    pts = task.sample(1, active, torch.Generator().manual_seed(7))
    xo, xb = pts["outside"][0], pts["band"][0]
    outside_band = xb[_depth_outside_obstacle_region(xb) > 0]
    assert 0.3 * 256 < outside_band.shape[0] < 0.7 * 256
    fo = torch.cat([field(xo), field(outside_band)])
    expected = fo.clamp(max=0).pow(2).mean().item()
    got = task.loss_terms(field, 0, active, torch.Generator().manual_seed(7))["design_region"].item()
    assert got == pytest.approx(expected, rel=1e-5)
    # without the option only the uniform samples count; the band samples sit where the violation
    # is, so the denser estimate is larger here
    only = plain.loss_terms(field, 0, active, torch.Generator().manual_seed(7))["design_region"].item()
    assert only == pytest.approx(field(xo).clamp(max=0).pow(2).mean().item(), rel=1e-5)
    assert got > only
