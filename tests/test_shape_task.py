"""ShapeTask sampling: every shape of a generative batch gets samples of every interface."""

import pytest
import torch

from ginn.problems import load_spec
from ginn.train.registry import make_task, resolve_config


def test_every_shape_sees_every_interface():
    spec = load_spec("obstacle")
    cfg = resolve_config(spec, "demo", {"sampling": {"n_interface": 64}})
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
    cfg = resolve_config(spec, "single", {"losses": {"containment_power": 1}})
    task = make_task(spec, cfg)
    model = task.build_model()
    active = {"design_region", "obstacle"}
    pts = task.sample(1, active, torch.Generator().manual_seed(3))  # what loss_terms draws with this seed
    out = task.loss_terms(model, 0, active, torch.Generator().manual_seed(3))
    with torch.no_grad():
        f_out, f_obs = model(pts["outside"][0], None), model(pts["obstacle"][0], None)
    for name, f in (("design_region", f_out), ("obstacle", f_obs)):
        expected = f.clamp(max=0).abs().mean().item()
        assert expected > 0  # the untrained field violates both somewhere
        assert out[name].item() == pytest.approx(expected, rel=1e-5)
