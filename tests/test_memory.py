"""The size check before a run allocates: the parameter count against the built networks, the
step estimate's arithmetic, and refusals of sizes that cannot fit."""

import pytest

from ginn import runs
from ginn.errors import ConfigError
from ginn.train.memory import ACTIVATION_COPIES, PARAMETER_COPIES, check_memory, parameter_count, step_bytes


@pytest.mark.parametrize("problem, preset", [("obstacle", None), ("obstacle", "softplus"), ("bracket", "cpu"),
                                             ("wheel", None), ("plateau", "cpu")])
def test_parameter_count_is_that_of_the_built_network_up_to_the_first_layer(problem, preset):
    spec, cfg = runs.resolve(problem, preset)
    from ginn.tasks import make_task

    model = make_task(spec, cfg).build_model()
    real = sum(p.numel() for p in model.parameters())
    first = (cfg.model.width if cfg.model.kind == "resmlp" else cfg.model.hidden[0])
    # the estimate takes 8 inputs besides the code: it differs from the network by the first layer's rows only
    assert abs(parameter_count(cfg) - real) <= 8 * first


def test_step_bytes_counts_parameters_and_activations():
    _, cfg = runs.resolve("obstacle", None, {"model": {"hidden": [10, 20]}, "latents": {"n_shapes": 3, "dim": 1},
                                            "sampling": {"n_domain": 100, "n_outside": 0, "n_obstacle": 0,
                                                         "n_interface": 50, "n_band": 0, "n_boundary": 0}})
    params = (8 + 1 + 1) * 10 + 11 * 20 + 21 * 1
    assert parameter_count(cfg) == params
    assert step_bytes(cfg) == 4 * (params * PARAMETER_COPIES + 3 * 150 * 30 * ACTIVATION_COPIES)


def test_sizes_that_cannot_fit_are_refused_with_the_estimate(monkeypatch):
    from ginn.train import memory

    _, cfg = runs.resolve("obstacle", None, {"latents": {"n_shapes": 16}})
    monkeypatch.setattr(memory, "free_bytes", lambda device: step_bytes(cfg) - 1)
    with pytest.raises(ConfigError, match=r"needs at least .* GiB .* 16 shapes per step .* free on cpu"):
        check_memory(cfg)
    monkeypatch.setattr(memory, "free_bytes", lambda device: step_bytes(cfg))
    check_memory(cfg)  # exactly enough passes
    monkeypatch.setattr(memory, "free_bytes", lambda device: None)
    check_memory(cfg)  # unknown free memory: no refusal
