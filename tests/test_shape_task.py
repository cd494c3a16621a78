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


def _off_obstacle_interfaces(x, tol):
    """``(n,)`` bool: the points of ``x (n, 2)`` farther than ``tol`` from the obstacle problem's
    interfaces, the segments x = +-0.9, |y| <= 0.4."""
    d = torch.sqrt((x[:, 0].abs() - 0.9) ** 2 + (x[:, 1].abs() - 0.4).clamp_min(0) ** 2)
    return d > tol


def test_every_shape_sees_every_interface():
    spec = load_spec("obstacle")
    cfg = spec.config("demo", {"sampling": {"n_interface": 64}, "latents": {"draw": "fixed"}})
    task = make_task(spec, cfg)
    gen = torch.Generator().manual_seed(0)
    batch = task.draw_batch(4, {"interface", "normal"}, gen)
    x, n = batch.x["interface"], batch.attrs["normals"]
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
    pts = task.draw_batch(1, active, torch.Generator().manual_seed(3)).x  # what loss_terms draws with this seed
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

    # (2e-3: above the surface projection's residual tolerance 1e-3, so no point counts as on its
    # zero level set, which it does not have)
    flat = _FnField(lambda x: 0.0 * x[:, 0] + 2e-3)
    out = task.loss_terms(flat, 0, active, torch.Generator().manual_seed(5))
    pts = task.draw_batch(1, active, torch.Generator().manual_seed(5)).x
    xo = pts["outside"][0]
    d_out = _depth_outside_obstacle_region(xo)
    # the samples within the interface tolerance of an interface are left out (they count 0)
    off = _off_obstacle_interfaces(xo, task.problem.interface_tolerance)
    assert 0 < int((~off).sum()) < xo.shape[0]
    expected = ((2e-3 - d_out).clamp(max=0).pow(2) * off).mean().item()
    assert expected > 1e-4 and out["design_region"].item() == pytest.approx(expected, rel=1e-5)
    d_obs = (0.1 - pts["obstacle"][0].norm(dim=-1)).clamp_min(0)  # depth into the disk
    assert out["obstacle"].item() == pytest.approx((2e-3 - d_obs).clamp(max=0).pow(2).mean().item(), rel=1e-5)


def test_surface_samples_outside_the_design_region_are_penalised_by_their_depth():
    """A disk of radius 0.3 centred at (0.8, 0) overhangs E = [-0.9, 0.9] x [-0.4, 0.4] by 0.2:
    besides the uniform samples of X \\ E, the design-region loss (power 1, slope 1) takes the
    surface samples beyond x = 0.9, each at its depth x - 0.9 (f = 0 there); samples within the
    interface tolerance of the interface x = 0.9 count for nothing."""
    spec = load_spec("obstacle")
    cfg = spec.config("single", {"losses": {"containment_slope": 1.0, "containment_power": 1}})
    task = make_task(spec, cfg)
    c = torch.tensor([0.8, 0.0])
    disk = _FnField(lambda x: (x - c).norm(dim=-1) - 0.3)
    gen = torch.Generator().manual_seed(3)
    out = task.loss_terms(disk, 0, {"design_region"}, gen)
    batch = task.draw_batch(1, {"design_region"}, torch.Generator().manual_seed(3))
    xo = batch.x["outside"][0]
    tol = task.problem.interface_tolerance
    fo = (disk(xo) - _depth_outside_obstacle_region(xo)) * _off_obstacle_interfaces(xo, tol)
    # the surface samples: recompute them as the task does
    batch.evaluate(disk)
    srf = batch.surface()
    xb = srf.x[0][srf.converged[0]]
    beyond = xb[xb[:, 0] > 0.9]
    assert beyond.shape[0] > 5 and ((beyond - c).norm(dim=-1) - 0.3).abs().max() < 1e-5
    depth = _depth_outside_obstacle_region(beyond)
    assert torch.allclose(depth, beyond[:, 0] - 0.9, atol=1e-6)
    off = _off_obstacle_interfaces(beyond, tol)
    assert 0 < int((~off).sum()) < beyond.shape[0]  # the disk crosses the interface x = 0.9
    depth = depth[off]
    penalties = torch.cat([(-fo).clamp_min(0), depth])
    assert out["design_region"].item() == pytest.approx(penalties.mean().item(), rel=1e-4)


def test_away_from_interfaces_measures_the_distance_to_them():
    """The strain term's clearance (``sampling.strain_interface_clearance``): distances to the
    obstacle's interfaces (x = +-0.9, |y| <= 0.4) are exact here."""
    spec = load_spec("obstacle")
    task = make_task(spec, spec.config("demo", {}))
    pts = torch.tensor([[-0.85, 0.0], [-0.75, 0.1], [0.89, 0.39], [0.0, 0.0], [0.9, 0.45]])
    # distances: 0.05, 0.15, 0.01, 0.9, 0.05 (to the end point (0.9, 0.4))
    strain = next(c for c in task.constraints if c.name == "strain")
    assert strain.away_from_interfaces(pts, 0.1).tolist() == [False, True, False, True, False]
    assert strain.away_from_interfaces(pts, 0.0).all()



def test_without_a_floor_the_design_region_loss_is_the_papers():
    """``losses.containment_slope = 0`` (the paper's presets): the mean of min(0, f)^2 over the
    uniform samples of X \\ E alone; surface samples, where f = 0, would only dilute it."""
    spec = load_spec("obstacle")
    task = make_task(spec, spec.config("single", {}))  # the paper's settings, one shape
    c = torch.tensor([0.8, 0.0])
    disk = _FnField(lambda x: (x - c).norm(dim=-1) - 0.3)
    out = task.loss_terms(disk, 0, {"design_region"}, torch.Generator().manual_seed(3))
    xo = task.draw_batch(1, {"design_region"}, torch.Generator().manual_seed(3)).x["outside"][0]
    expected = disk(xo).clamp(max=0).pow(2).mean().item()
    assert expected > 0 and out["design_region"].item() == pytest.approx(expected, rel=1e-6)


def test_interface_residual_is_the_distance_where_the_field_is_flat_and_faces_the_normal():
    """``losses.interface_distance`` on the obstacle (interfaces x = +-0.9, |y| <= 0.4, outward
    normals -+x): the field ``f = k (x - 0.9 - c)`` has its zero level at x = 0.9 + c, so each sample
    of x = 0.9 is ``c`` away and faces its normal +x, and each of x = -0.9 has ``f = -k (1.8 + c)``
    and faces against its normal -x. For a slope ``k < 1`` the first enter as their distance ``c``,
    the second as ``f``; for ``k > 1`` all enter as ``f``, the paper's term."""
    spec = load_spec("obstacle")
    c = 0.01
    for k in (0.25, 2.5):
        field = _FnField(lambda x, k=k: k * (x[:, 0] - 0.9 - c))
        paper = 0.5 * k * k * (c * c + (1.8 + c) ** 2)
        ours = 0.5 * ((max(k, 1.0) * c) ** 2 + (k * (1.8 + c)) ** 2)
        for distance, want in ((True, ours), (False, paper)):
            task = make_task(spec, spec.config("single", {"losses": {"interface_distance": distance}}))
            out = task.loss_terms(field, 0, {"interface"}, torch.Generator().manual_seed(2))
            assert out["interface"].item() == pytest.approx(want, rel=1e-3)


def test_interface_residual_values_and_gradient():
    """``f / min(|grad f|, 1)``: for ``f = a x + b`` at ``x = 1`` with ``|a| < 1`` the residual is
    ``(a + b) / a`` and its square's derivatives are those of that quotient; capped by ``reach``
    where the gradient vanishes; ``f`` where the field is steeper than a distance or faces more than
    the tolerance away from a prescribed normal, the distance where it faces it or has none."""
    from ginn.constraints.interface import interface_residual
    a = torch.tensor(0.5, requires_grad=True)
    b = torch.tensor(0.1, requires_grad=True)
    f = (a * 1.0 + b).reshape(1)
    r = interface_residual(f, (a * torch.tensor([1.0, 0.0])).reshape(1, 2), 2.0)
    r.pow(2).sum().backward()
    q = 0.6 / 0.5
    assert r.item() == pytest.approx(q)
    assert a.grad.item() == pytest.approx(2 * q * (1.0 / 0.5 - 0.6 / 0.25))
    assert b.grad.item() == pytest.approx(2 * q / 0.5)
    f = torch.tensor([0.02, -0.03, 0.5, 0.02, 0.02, 0.02])
    g = torch.tensor([[0.5, 0.0], [0.0, 3.0], [0.0, 0.0], [0.5, 0.0], [0.5, 0.0], [0.5, 0.0]])
    n = torch.tensor([[0.0, 0.0]] * 3 + [[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]])
    assert interface_residual(f, g, 2.0, n, 0.98).tolist() == pytest.approx([0.04, -0.03, 2.0, 0.04, 0.02, 0.02])


def test_level_distance_is_bounded_where_the_field_is_flat():
    """``f / |grad f|`` for a slope, capped at ``reach`` in size where the gradient vanishes."""
    from ginn.constraints.interface import level_distance
    f = torch.tensor([0.02, -0.03, 0.5, -0.5])
    g = torch.tensor([[0.5, 0.0], [0.0, 3.0], [0.0, 0.0], [1e-9, 0.0]])
    assert level_distance(f, g, 2.0).tolist() == pytest.approx([0.04, -0.01, 2.0, -2.0])


def test_the_wall_of_the_domain_outside_the_design_region_is_penalised_where_the_shape_runs_into_it():
    """E = [-0.5, 0.98] x [-1, 1] in X = [-1, 1]^2 leaves a sliver 0.02 wide along x = 1, thinner
    than the uniform samples of X \\ E are apart (sqrt(1.04 / 512) = 0.045). The slab -0.4 <= x <=
    1.05 runs through it into the wall: no zero crossing there for the surface samples, and few
    uniform samples. At the wall points in the sliver (the lattice of 128 cells on X's edges, at the
    cells' centres, within 0.045 outside E: 128 on x = 1, and x = 0.992 on each of y = +-1)
    f - depth = (x - 1.05) - (x - 0.98) = -0.07, and each joins the design-region term's mean."""
    from ginn.problems import validate_spec

    spec = validate_spec({"name": "sliver", "geometry": {
        "dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
        "design_region": {"type": "box", "lo": [-0.5, -1], "hi": [0.98, 1]},
        "interfaces": [{"type": "segment", "a": [0.0, 0.0], "b": [0.0, 0.1], "normal": [1, 0]}]}})
    task = make_task(spec, spec.config(None, {"latents": {"n_shapes": 1}}))
    c = next(c for c in task.constraints if c.name == "design_region")
    assert c.wall.shape[0] == 128 + 2 + 2 * 3  # and 3 on each of y = +-1 beside x = -0.5, where f > depth
    slab = _FnField(lambda x: torch.maximum(-0.4 - x[:, 0], x[:, 0] - 1.05))
    with_wall = task.loss_terms(slab, 0, {"design_region"}, torch.Generator().manual_seed(1))["design_region"].item()
    c.wall = c.wall[:0]
    without = task.loss_terms(slab, 0, {"design_region"}, torch.Generator().manual_seed(1))["design_region"].item()
    n = task.draw_batch(1, {"design_region"}, torch.Generator().manual_seed(1)).x["outside"].shape[1]
    k = 128 + 2
    assert with_wall == pytest.approx((without * n + 0.07 * k) / (n + k), rel=1e-4)
    # a shape away from the wall leaves the term as it was, to the bit (such problems train as
    # before), here a disk across E's left side, outside E where the uniform samples see it
    c.wall = next(c for c in make_task(spec, spec.config(None, {"latents": {"n_shapes": 1}})).constraints
                  if c.name == "design_region").wall
    disk = _FnField(lambda x: (x - torch.tensor([-0.6, 0.0])).norm(dim=-1) - 0.2)
    a = task.loss_terms(disk, 0, {"design_region"}, torch.Generator().manual_seed(1))["design_region"]
    c.wall = c.wall[:0]
    b = task.loss_terms(disk, 0, {"design_region"}, torch.Generator().manual_seed(1))["design_region"]
    assert a.item() > 0 and torch.equal(a, b)
