"""Settings derived from a problem's geometry: the documented formulas, recorded in config.yaml,
never reaching the built-in specs, and the public suite's specs valid."""

import math
from pathlib import Path

import pytest
import torch
import yaml

from ginn import runs
from ginn.config import flattened
from ginn.problems import load_spec, validate_spec
from ginn.problems.derived import derived_defaults, length_scale

SUITE = sorted((Path(__file__).resolve().parents[1] / "benchmarks" / "suite").glob("*.yaml"))


def _spec(half: float, dim: int = 2, **extra):
    lo, hi = [-half] * dim, [half] * dim
    return validate_spec({"name": "t", "geometry": {"dim": dim, "domain": {"lo": lo, "hi": hi},
                                                    "interfaces": [{"type": "segment", "a": [0.0] * dim,
                                                                    "b": [half / 2] + [0.0] * (dim - 1)}]}, **extra})


@pytest.mark.parametrize("half", [0.5, 1.0, 4.0])
def test_weights_scale_with_the_size_of_the_domain(half):
    """A problem scaled by s gets the weights that keep each term's contribution unchanged."""
    cfg = _spec(half).config()
    p = _spec(half).build()
    assert length_scale(p) == half
    # the frame absorbs the scale: sqrt(s / h) with h = 5e-3 * unit_scale = 5e-3 s
    assert cfg.model.frame == "domain" and cfg.model.w0_first == pytest.approx(math.sqrt(200.0))
    assert cfg.losses.interface.weight == pytest.approx(3000.0 / half**2)
    assert cfg.losses.design_region.weight == pytest.approx(300.0 / half)
    assert cfg.losses.connectedness.weight == pytest.approx(8.0 / half)
    assert cfg.losses.diversity.weight == pytest.approx(0.015 / half)
    assert cfg.connectedness.margin == pytest.approx(0.02 * half)
    assert (cfg.losses.containment_power, cfg.losses.containment_slope) == (1, 1.0)
    # scale-free terms and the schedule do not depend on it
    assert (cfg.losses.normal.weight, cfg.losses.eikonal.weight, cfg.training.iterations) == (10.0, 0.1, 2000)


def test_a_stated_budget_keeps_the_schedule_in_thirds():
    spec = _spec(1.0)
    assert spec.config().training.lr_decay_every == 666  # 2000 // 3
    t = spec.config(None, {"training": {"iterations": 8000}}).training
    assert (t.iterations, t.lr_decay_every) == (8000, 2666)
    t = spec.config(None, {"training": {"iterations": 8000, "lr_decay_every": 100}}).training
    assert (t.iterations, t.lr_decay_every) == (8000, 100)  # a stated schedule wins
    t = spec.config(None, {"training": {"iterations": 8000}}, {"training": {"iterations": 300}}).training
    assert (t.iterations, t.lr_decay_every) == (300, 100)  # the last stated budget


def test_a_structural_problem_joins_its_pieces_from_the_end_of_the_continuation():
    """With a ``physics`` block the connectedness term starts when the compliance's step width and
    penalty are final (half the budget, stated or derived, unless the start is stated); without
    one from the first step."""
    from ginn.constraints.compliance import CONTINUATION

    mbb = runs.resolve("mbb", None, {})[1]
    assert mbb.losses.connectedness.start == CONTINUATION * mbb.training.iterations == 1000
    assert runs.resolve("cantilever-3d", None, {})[1].losses.connectedness.start == 1800
    assert runs.resolve("mbb", None, {}, sets=["training.iterations=300"])[1].losses.connectedness.start == 150
    stated = runs.resolve("mbb", None, {}, sets=["training.iterations=300", "losses.connectedness.start=7"])[1]
    assert stated.losses.connectedness.start == 7
    assert _spec(1.0).config().losses.connectedness.start == 0
    assert runs.resolve("obstacle", None, {})[1].losses.connectedness.start == 0


def test_the_longest_side_sets_the_scale_and_3d_gets_its_budget():
    spec = validate_spec({"name": "t", "geometry": {"dim": 3, "domain": {"lo": [0, 0, 0], "hi": [1, 6, 2]}}})
    d, why = derived_defaults(spec.build())
    assert d["model"]["hidden"] == [128, 128, 128] and d["model"]["frame"] == "domain"
    assert d["training"]["iterations"] == 3600 and d["training"]["lr_decay_every"] == 1200
    assert "s = 3" in why["model.frame"] and "s = 3" in why["losses.interface.weight"]
    assert d["balancing"] == {"method": "feasibility"} and "balancing.method" in why


def test_the_spec_overrides_and_config_yaml_says_what_was_derived(tmp_path):
    spec = _spec(1.0, defaults={"model": {"w0_first": 2.0}, "latents": {"n_shapes": 1}})
    cfg = spec.config(None, {"training": {"iterations": 2}})
    assert cfg.model.w0_first == 2.0 and cfg.losses.interface.weight == 3000.0
    notes = spec.derived_notes(cfg)
    assert not any(n.startswith("model.w0_first") for n in notes)  # stated by the spec
    assert not any(n.startswith("training.iterations") for n in notes)  # overridden
    assert "losses.interface.weight = 3000.0  (3000 / s^2, s = 1)" in notes
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(spec.model_dump(mode="json", exclude_none=True)))
    spec2, cfg2 = runs.resolve(tmp_path / "t.yaml", None, {"training": {"iterations": 2}})
    out = runs.train(spec2, cfg2, tmp_path / "run", progress=False, results=False)
    text = (out.run_dir / "config.yaml").read_text()
    assert text.startswith("# derived from the problem's geometry")
    assert "#   losses.interface.weight = 3000.0  (3000 / s^2, s = 1)" in text
    assert yaml.safe_load(text)["losses"]["interface"]["weight"] == 3000.0  # comments only: the YAML is intact
    assert runs.load_run(out.run_dir).config == out.task.cfg


def test_builtin_specs_state_every_derived_setting():
    """The paper reproductions keep their settings: every derived path is stated by the `paper`
    preset (or plateau's defaults but its multipliers and learning-rate schedule; its MLP leaves
    the SIREN frequency unused), while the obstacle
    and bracket state nothing but their shapes and latent range without a preset."""
    for name, preset in (("obstacle", "paper"), ("bracket", "paper"), ("plateau", None)):
        spec = load_spec(name)
        cfg = spec.config(preset)
        notes = spec.derived_notes(cfg)
        allowed = {"model.kind", "model.w0_hidden"} | ({"model.w0_first"} if name == "plateau" else set())
        allowed |= {"losses.topology.weight", "topology.grid"}  # act only with topology targets; these state none
        # act only with a volume bound, a least feature size or a physics block; these state none
        allowed |= {"losses.compliance.weight", "losses.attachment.weight", "losses.volume.weight", "losses.area.weight", "losses.thickness.weight", "losses.gap.weight", "losses.overhang.weight",
                    "losses.thickness_edges.weight", "losses.gap_edges.weight", "losses.fillet.weight", "losses.faces.weight"}
        if name == "plateau":
            allowed.add("latents.draw")  # acts only with latent codes; Plateau trains one shape
            # the multipliers and the learning-rate schedule are derived as for every problem
            allowed |= {"balancing.method", "training.lr_decay", "training.lr_decay_every"}
        assert not spec.build().topology.targets and spec.build().tolerances.volume_fraction is None
        assert cfg.model.frame == "raw"
        assert cfg.balancing.method == ("feasibility" if name == "plateau" else "weighted")
        if name == "plateau":
            assert (cfg.training.lr_decay, cfg.training.lr_decay_every) == (0.5, cfg.training.iterations // 3)
            assert all(spec.config(p).balancing.method == "weighted" for p in ("cpu", "demo"))
        kept = {n.split(" = ")[0] for n in notes}
        # a derived value may coincide with the stated one; what matters is that none is taken from derived alone
        stated = set(flattened(spec.defaults)) | {p for layer in spec.preset_layers(preset) for p in flattened(layer)}
        assert kept - stated - allowed == set(), (name, sorted(kept - stated - allowed))
        if preset is not None:
            assert set(spec.defaults) == {"latents"}
            assert spec.config().model.frame == "domain"  # no preset: the derived settings
            assert spec.config().balancing.method == "feasibility"


@pytest.mark.parametrize("path", SUITE, ids=[p.stem for p in SUITE])
def test_suite_specs_are_valid_and_state_no_training_settings(path):
    spec = load_spec(path)
    p = spec.build()
    assert p.interfaces and spec.presets == {}
    assert set(spec.defaults) <= {"latents"} and set(spec.defaults.get("latents", {})) <= {"n_shapes"}
    n = spec.config().latents.n_shapes
    assert n == 1 or 4 <= n <= 16  # single shapes and generative sets of 4 to 16


def test_suite_covers_what_the_issue_lists():
    specs = [load_spec(p) for p in SUITE]
    kinds = {n["type"] for s in specs for n in s.model_dump()["geometry"]["interfaces"]}
    assert {"segment", "polyline", "circle", "annulus", "cylinder_wall", "mesh"} <= kinds
    assert {s.geometry.dim for s in specs} == {2, 3}
    assert {len(s.geometry.obstacles) for s in specs} >= {0, 1, 2, 3}
    assert len(specs) + 3 >= 10  # with the built-in obstacle, bracket and plateau


def _scaled_problem(k: float) -> dict:
    """A 2D problem drawn at scale ``k``: a rectangle E minus a disk obstacle, two segment interfaces."""
    return {"name": f"scaled{k:g}", "geometry": {
        "dim": 2, "domain": {"lo": [-1.0 * k, -0.5 * k], "hi": [1.0 * k, 0.5 * k]},
        "design_region": {"type": "rectangle", "lo": [-0.9 * k, -0.4 * k], "hi": [0.9 * k, 0.4 * k]},
        "interfaces": [{"type": "segment", "a": [-0.9 * k, -0.4 * k], "b": [-0.9 * k, 0.4 * k], "normal": [-1.0, 0.0]},
                       {"type": "segment", "a": [0.9 * k, -0.4 * k], "b": [0.9 * k, 0.4 * k], "normal": [1.0, 0.0]}],
        "obstacles": [{"type": "disk", "center": [0.0, 0.0], "radius": 0.1 * k}]},
        "defaults": {"latents": {"n_shapes": 2}, "losses": {"connectedness": {"weight": 0.0}}}}


@pytest.mark.long
def test_a_problem_and_its_scaled_copy_train_alike(few_heldout_checks):
    """With the derived settings a problem drawn 10 times larger trains the same network: the
    losses are equal and the inner weights follow the same path (up to rounding; in float64, as
    the surface samples outside E are a discrete choice that float32 rounding can flip)."""
    from ginn.tasks import make_task
    from ginn.train.trainer import Trainer

    out = {}
    for k in (1.0, 10.0):
        spec = validate_spec(_scaled_problem(k))
        cfg = spec.config(None, {"training": {"iterations": 5, "threads": 1, "dtype": "float64"}, "seed": 0})
        trainer = Trainer(make_task(spec, cfg), cfg, None, progress=False)
        res = trainer.train()
        out[k] = (res.last_losses, [p.detach().clone() for p in trainer.model.inner.parameters()])
    (l1, w1), (l10, w10) = out[1.0], out[10.0]
    # each term scales with its power of the size (f is a distance); the weighted sum does not
    for term, power in (("interface", 2), ("design_region", 1), ("obstacle", 1), ("eikonal", 0), ("normal", 0),
                        ("diversity", 1), ("total", 0)):
        assert l10[term] == pytest.approx(l1[term] * 10.0**power, rel=2e-3, abs=1e-6), term
    for a, b in zip(w1, w10):
        torch.testing.assert_close(a, b, rtol=1e-3, atol=1e-5)


@pytest.mark.parametrize("radius, tolerance, expected", [(0.02, 5e-3, 25.0), (0.05, 5e-3, math.sqrt(200.0)),
                                                       (0.3, 5e-3, math.sqrt(200.0)), (0.3, 0.04, 5.0),
                                                       (0.08, 0.04, 6.25)])
def test_first_layer_frequency_follows_the_smallest_interface_and_the_tolerance(radius, tolerance, expected):
    """omega_0^1 = max(5, s / (2 r), sqrt(s / h)) for a circle interface of radius r and the
    interface tolerance h (s = 1 = unit_scale here)."""
    from ginn.problems.derived import smallest_feature

    spec = validate_spec({"name": "t", "geometry": {
        "dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
        "interfaces": [{"type": "circle", "center": [0, 0], "radius": radius},
                       {"type": "segment", "a": [-0.9, -0.9], "b": [0.9, -0.9]}]},
        "tolerances": {"interface": tolerance}})
    assert smallest_feature(spec.build()) == pytest.approx(radius)
    assert spec.config().model.w0_first == pytest.approx(expected)
    assert (f"max(5, s / (2 a), sqrt(s / h)); at least s / (2 e) with physics, s = 1, a = {radius:.4g}, "
            f"h = {tolerance:.4g})") in " ".join(spec.derived_notes(spec.config()))  # no e without physics


@pytest.mark.parametrize("half, side, cells", [(0.05, 2.0, 90), (0.05, 1.0, 90), (0.01, 2.0, 200)])
def test_a_structural_problem_draws_members_as_thin_as_its_elements(half, side, cells):
    """With a ``physics`` block omega_0^1 is at least s / (2 e), ``e`` the element side of the
    structural grid (the longest side ``L`` over its cells: ``cells / 4``; 90 cells, or ``2 L / a``
    where that is more, so that the smallest interface, of half length ``a``, spans 4); the same
    geometry without physics keeps max(5, s / (2 a), sqrt(s / h))."""
    from ginn.problems.structural import structural_grid

    a = half * side
    geometry = {"dim": 2, "domain": {"lo": [0, 0], "hi": [side, side / 2]},
                "interfaces": [{"type": "segment", "a": [side, 0.1 * side], "b": [side, 0.1 * side + 2 * a]}]}
    physics = {"material": {"youngs_modulus": 1.0, "poisson_ratio": 0.3},
               "supports": [{"region": {"type": "rectangle", "lo": [-1, -1], "hi": [0, side]}}],
               "loads": [{"interface": 0, "force": [0.0, -1.0]}]}
    bare = validate_spec({"name": "t", "geometry": geometry})
    spec = validate_spec({"name": "t", "geometry": geometry, "physics": physics,
                          "tolerances": {"volume_fraction": {"max": 0.5}}})
    assert structural_grid(spec.build(), 0, a).shape[0] == cells
    s = side / 2
    # the interface tolerance is 5e-3 of the unit scale, which defaults to s
    assert bare.config().model.w0_first == pytest.approx(max(5.0, s / (2 * a), math.sqrt(200.0)))
    assert spec.config().model.w0_first == pytest.approx(cells / 4)
    assert f"e = {side / cells:.4g}" in " ".join(spec.derived_notes(spec.config()))


def test_every_derived_setting_is_a_rule_and_in_the_spec_reference():
    """One copy of each derived constant: the rules give the settings, the notes and the docs table."""
    from ginn.config import flattened
    from ginn.problems.derived import RULES

    paths = [r.path for r in RULES]
    assert len(paths) == len(set(paths))
    for dim in (2, 3):
        d, why = derived_defaults(_spec(1.0, dim=dim).build())
        assert set(flattened(d)) == set(why) <= set(paths)
    text = (Path(__file__).resolve().parents[1] / "docs" / "problem-spec.md").read_text()
    for r in RULES:
        assert f"| `{r.path}` | {r.formula} |" in text, r.path
