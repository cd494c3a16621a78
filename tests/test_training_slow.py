"""Slow end-to-end trainings (``make test-slow``): real runs checked against measured bounds."""

import pytest
import torch

from ginn.problems import load_spec
from ginn.train.registry import make_task, resolve_config
from ginn.train.trainer import Trainer

pytestmark = pytest.mark.slow


def train(name, preset, over):
    spec = load_spec(name)
    cfg = resolve_config(spec, preset, over)
    task = make_task(spec, cfg)
    res = Trainer(task, cfg, None, progress=False).train()
    return task, res


def test_single_shape_obstacle_fits_the_interfaces():
    """Issue 4: the interface loss of the single-shape obstacle falls below 1e-3."""
    task, res = train("obstacle", "single", {"training": {"iterations": 400}, "losses": {"connectedness": {"weight": 0.0}}})
    g = torch.Generator().manual_seed(1)
    vals = task.loss_terms(res.model, 400, {"interface"}, g)
    assert vals["interface"].item() < 1e-3

