"""Smoke test: every built-in problem trains for two iterations under every preset.

Point budgets (and the connectedness loss's seed grid) are shrunk and the feasibility checks left
out (the presets' models, losses and schedules are kept) so that the whole set runs in the default
suite; the checks have tests of their own, full-size runs are slow tests and documented results.
"""

import math

import pytest
import torch

from ginn.problems import list_problems, load_spec
from ginn.tasks import make_task
from ginn.train.trainer import Trainer

SMALL_SAMPLING = {"n_domain": 256, "n_outside": 128, "n_obstacle": 32, "n_interface": 64, "n_band": 0, "n_boundary": 32}


def cases():
    out = []
    for name in list_problems():
        spec = load_spec(name)
        for preset in [None, *sorted(spec.presets)]:
            out.append(pytest.param(name, preset, id=f"{name}-{preset or 'default'}"))
    return out


@pytest.mark.parametrize("name, preset", cases())
def test_preset_trains_two_iterations(name, preset, tmp_path):
    spec = load_spec(name)
    over = {"training": {"iterations": 2, "checkpoint_every": 1, "feasibility_checks": 0}}
    if spec.kind == "shape":
        over["sampling"] = SMALL_SAMPLING
        over["connectedness"] = {"grid": 8}  # the seed grid of the critical points
        over["structural"] = {"cells": 12}  # the element grid of a structural problem
    if spec.kind == "gray-scott":
        over["params"] = {"grid": 16}
    cfg = spec.config(preset, over)
    task = make_task(spec, cfg)
    tr = Trainer(task, cfg, tmp_path, progress=False)
    res = tr.train()
    assert res.step == 2 and res.status == "completed"
    assert all(torch.isfinite(p).all() for p in res.model.parameters())
    assert all(math.isfinite(v) for k, v in res.last_losses.items())
    assert (tmp_path / "checkpoints" / "last.pt").exists()
