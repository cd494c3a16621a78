"""ShapeTask sampling: every shape of a generative batch gets samples of every interface."""

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
