"""The bracket's presets (paper Table 2, JEB column) and the CPU sizing; fast checks only.

The long training test is in ``tests/test_bracket_training_slow.py``; the smoke test that trains
every preset for two iterations is ``tests/test_presets_smoke.py``.
"""

import pytest

from ginn.problems import load_spec

PAPER = {  # Table 2, JEB (3D) column
    "interface": 1.0,
    "design_region": 1e-1,
    "normal": 1e-6,
    "eikonal": 1e-9,
    "connectedness": 1e-2,
}


@pytest.fixture(scope="module")
def spec():
    return load_spec("bracket")


def test_presets_exist(spec):
    assert {"gpu", "gpu-single", "cpu", "cpu-gen", "single", "demo"} <= set(spec.presets)


def test_gpu_preset_is_table_2(spec):
    c = spec.config("gpu")
    assert c.model.kind == "siren" and c.model.hidden == [256] * 5
    assert c.model.w0_first == 8.0
    assert (c.latents.n_shapes, c.latents.dim, c.latents.low, c.latents.high) == (4, 1, -0.1, 0.1)
    assert c.training.iterations == 5000 and c.training.lr == 1e-3
    assert (c.training.lr_decay, c.training.lr_decay_every) == (0.5, 1000)
    for name, w in PAPER.items():
        assert getattr(c.losses, name).weight == w, name
    assert 1e-5 <= c.losses.diversity.weight <= 1e-3  # Table 2: 1e-5 to 1e-3
    assert 1e-8 <= c.losses.strain.weight <= 1e-7  # Table 2: smoothness 1e-8 to 1e-7


def test_gpu_preset_samples_a_band_and_keeps_strain_off_the_interfaces(spec):
    c = spec.config("gpu")
    p = spec.build()
    assert p.interface_band == 0.05 and c.sampling.n_band > 0
    assert c.sampling.strain_interface_clearance > 0
    assert c.connectedness.every == 1 and c.connectedness.grid == 16


def test_gpu_single_is_gpu_with_one_shape(spec):
    g, s = spec.config("gpu"), spec.config("gpu-single")
    assert s.latents.n_shapes == 1 and s.losses.diversity.weight == 0.0
    assert s.model == g.model and s.sampling == g.sampling and s.training == g.training
    for name in PAPER:
        assert getattr(s.losses, name) == getattr(g.losses, name)


def test_cpu_presets_are_smaller_than_gpu(spec):
    g = spec.config("gpu")
    n_params = lambda h: sum((a + 1) * b for a, b in zip([4, *h], [*h, 1]))  # noqa: E731
    for name, shapes in (("cpu", 1), ("cpu-gen", 4)):
        c = spec.config(name)
        assert c.latents.n_shapes == shapes
        assert n_params(c.model.hidden) < n_params(g.model.hidden) / 5
        assert c.sampling.n_domain < g.sampling.n_domain and c.sampling.n_band > 0
        assert c.connectedness.every > 1 and c.connectedness.grid < g.connectedness.grid
        assert c.losses.connectedness.weight > 0 and c.sampling.strain_interface_clearance > 0
    assert spec.config("cpu").losses.diversity.weight == 0.0
    assert spec.config("cpu-gen").losses.diversity.weight > 0


def test_ablations_from_set(spec):
    """Table 4's ablations are --set overrides of the presets."""
    from ginn.config import parse_set

    over = parse_set(["losses.connectedness.weight=0", "model.w0_first=6.5", "losses.strain.weight=0",
                      "losses.normal.weight=0", "losses.eikonal.weight=0", "losses.diversity.weight=0"])
    c = spec.config("gpu", over)
    assert c.model.w0_first == 6.5
    assert all(getattr(c.losses, k).weight == 0 for k in ("connectedness", "strain", "normal", "eikonal", "diversity"))
    assert c.losses.interface.weight == 1.0 and c.model.hidden == [256] * 5
