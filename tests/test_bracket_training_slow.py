"""A reduced bracket trained for a few hundred iterations, with and without the connectedness loss.

Slow (about 10-20 minutes on a shared 2-core CPU): ``pytest -m slow tests/test_bracket_training_slow.py``.

Checks:
* all six interfaces are fitted: on each interface component (4 bolt holes, 2 clevis pin holes),
  the mean of ``f^2`` (the interface loss restricted to that component) is below ``5e-3`` and
  below 1/50 of the same number for the untrained SIREN (about 0.3, RMS |f| about 0.55): the
  interface values are at most ~1/7 (RMS) of the untrained field's magnitude away from zero.
  Measured after 300 iterations on this machine: 3e-5 .. 1.3e-3 (the pin holes, the largest
  interfaces, are the slowest); an interface that is not attached keeps values of the order of
  the field's magnitude and fails.
* the connectedness loss reduces the number of connected components of the shape inside the
  envelope, ``b0(Omega ∩ E)`` (same seed, same everything else), and does not raise ``b0``.
* the `cpu` preset as a user runs it meets the single-shape acceptance bounds (about 10 more minutes),
  and the `cpu-gen` preset its per-shape bounds on each of its four shapes (about 30 more minutes).
"""

import pytest
import torch

from ginn.eval.shapes import evaluate_shapes
from ginn.geometry import sample_interfaces_with_components
from ginn.problems import load_spec
from ginn.tasks import make_task
from ginn.train.trainer import Trainer

pytestmark = pytest.mark.slow

# The cpu preset with a smaller model, fewer points and iterations, and Table 2's envelope, normal
# and eikonal weights (the configuration the bounds below were measured with). The first-layer
# frequency, interface weight, term starts and containment form are pinned to the values of that
# measurement, so that later changes of the cpu preset do not move this test.
REDUCED = {
    "model": {"hidden": [96, 96, 96], "w0_first": 8.0},
    "losses": {"interface": {"weight": 1.0}, "design_region": {"weight": 0.1, "start": 0}, "normal": {"weight": 1e-6},
               "eikonal": {"weight": 1e-9}, "connectedness": {"start": 0}, "containment_slope": 0.0,
               "containment_power": 2},
    "sampling": {"n_domain": 1024, "n_outside": 512, "n_interface": 512, "n_band": 512, "n_boundary": 128},
    "connectedness": {"every": 5, "grid": 10},
    "training": {"iterations": 300, "lr_decay_every": 150, "checkpoint_every": 1000, "threads": 1},
}


def _train(tmp_path, name, conn_weight):
    spec = load_spec("bracket")
    cfg = spec.config("cpu", REDUCED, {"losses": {"connectedness": {"weight": conn_weight}}})
    task = make_task(spec, cfg)
    res = Trainer(task, cfg, tmp_path / name, progress=False).train()
    assert res.status == "completed" and res.step == 300
    return task, res.model


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bracket")
    return {"with": _train(tmp, "with", 1e-2), "without": _train(tmp, "without", 0.0)}


def _interface_fit(model, problem):
    """Mean of ``f^2`` on each interface component, ``(n_components,)``."""
    g = torch.Generator().manual_seed(1)
    x, _, comp = sample_interfaces_with_components(problem.interfaces, 12000, g)
    with torch.no_grad():
        f = model(x, None)
    return torch.stack([f[comp == k].pow(2).mean() for k in range(int(comp.max()) + 1)])


@pytest.mark.parametrize("which", ["with", "without"])
def test_all_six_interfaces_are_fitted(runs, which):
    task, model = runs[which]
    torch.manual_seed(task.cfg.seed)
    untrained = _interface_fit(task.build_model(), task.problem)
    per = _interface_fit(model, task.problem)
    assert per.shape == (6,)
    print(which, "per-interface mean f^2:", per.tolist(), "untrained:", untrained.tolist())
    assert (per < 5e-3).all(), per
    assert (per < untrained / 50).all(), (per, untrained)


def test_connectedness_reduces_b0(runs):
    """The loss joins the components of the shape inside E (``connectedness.restrict_to_design_region``,
    the default): b0(Omega ∩ E) drops, and b0 of the whole shape does not rise. Measured: b0(Omega
    ∩ E) 1 with, 12 without; b0 2 and 2 (a speck outside E in the run with the loss)."""
    m = {}
    for which, (task, model) in runs.items():
        m[which] = evaluate_shapes(model, None, task.problem, resolution=64).to_json()["shapes"][0]
        print(which, {k: m[which][k] for k in ("b0", "b0_in_design_region", "connected_interfaces_share", "interface_cd1")})
    assert m["with"]["b0_in_design_region"] < m["without"]["b0_in_design_region"]
    assert m["with"]["b0"] <= m["without"]["b0"]
    assert m["with"]["connected_interfaces_share"] >= m["without"]["connected_interfaces_share"]


def _train_preset(name: str):
    """Train a bracket preset as `ginn train bracket --preset NAME` does (no run directory)."""
    spec = load_spec("bracket")
    cfg = spec.config(name, {})
    task = make_task(spec, cfg)
    return task, Trainer(task, cfg, None, progress=False).train().model


def test_cpu_preset_meets_the_acceptance_bounds():
    """The `cpu` preset as a user runs it (one shape, default threads) ends with the part inside
    the envelope in one piece, all six interfaces on it, CD1 <= 5e-3 and vol_out <= 1e-3 on the
    256-cell evaluation grid of `ginn eval` (docs/results.md, bracket: seed 0 CD1 4.6e-3, vol_out
    9.4e-4); about 10 minutes on 2 idle cores.
    """
    task, model = _train_preset("cpu")
    m = evaluate_shapes(model, None, task.problem, resolution=256).to_json()["shapes"][0]
    print({k: m[k] for k in ("b0", "b0_in_design_region", "connected_interfaces_share", "interface_cd1", "volume_outside")})
    assert m["b0_in_design_region"] == 1
    assert m["connected_interfaces_share"] == 1.0
    assert m["interface_cd1"] <= 5e-3
    assert m["volume_outside"] <= 1e-3


def test_cpu_gen_preset_meets_the_acceptance_bounds():
    """The generative `cpu-gen` preset as a user runs it (four shapes, default threads) meets the
    same bounds on every shape, with diversity_mean > 0 (docs/results.md, bracket: CD1 4.1e-3 to
    4.5e-3, vol_out 4.2e-4 to 4.5e-4, diversity_mean 0.015); 36 minutes on 2 idle cores."""
    task, model = _train_preset("cpu-gen")
    Z = task.latents()
    assert Z.shape == (4, 1)
    out = evaluate_shapes(model, Z, task.problem, resolution=256)
    for m in out["shapes"]:
        print({k: m[k] for k in ("b0", "b0_in_design_region", "connected_interfaces_share", "interface_cd1", "volume_outside")})
    print("diversity_mean", out["diversity_mean"])
    for m in out["shapes"]:
        assert m["b0_in_design_region"] == 1
        assert m["connected_interfaces_share"] == 1.0
        assert m["interface_cd1"] <= 5e-3
        assert m["volume_outside"] <= 1e-3
    assert out["diversity_mean"] > 0
