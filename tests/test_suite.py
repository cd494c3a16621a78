"""benchmarks/suite.py: every problem trains with derived settings and is judged by its tolerances."""

import importlib.util
import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from ginn.problems import get_spec

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def suite():
    spec = importlib.util.spec_from_file_location("suite", ROOT / "benchmarks" / "suite.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_suite_lists_its_problems_and_the_builtins(suite):
    names = list(suite.problems())
    assert len(names) >= 10 and {"obstacle", "bracket", "plateau", "wheel-2d", "clamp-3d"} <= set(names)


def test_builtins_enter_as_users_would_write_them(suite):
    from ginn.problems import load_spec

    spec = suite.as_user_spec(load_spec("obstacle"))
    assert spec.defaults == {"latents": {"n_shapes": 16, "dim": 1, "low": -1.0, "high": 1.0}} and spec.presets == {}
    cfg = spec.config()
    assert cfg.model.frame == "domain" and cfg.losses.interface.weight == 3000.0  # derived, not the paper's 1.0
    assert cfg == load_spec("obstacle").config()  # what `ginn train obstacle` trains
    plateau = suite.as_user_spec(load_spec("plateau"))
    assert plateau.defaults == {"latents": {"n_shapes": 1}} and plateau.config().losses.mean_curvature.weight == 0


def test_a_row_per_run_and_the_rate(suite, tmp_path, capsys):
    assert suite.main(["--only", "hook-2d", "--iterations", "2", "--resolution", "32", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[2].startswith("| hook-2d | 0 | ") and out[-1].startswith("every shape feasible in ")
    rows = json.loads((tmp_path / "suite.json").read_text())
    assert rows[0]["problem"] == "hook-2d" and rows[0]["iterations"] == 2 and rows[0]["shapes"] == 1
    assert rows[0]["cd1_bound"] == pytest.approx(0.005 * 0.7)  # unit_scale: half the longest side, 0.7


def test_unknown_problem_is_one_line_and_exit_2(suite, capsys):
    assert suite.main(["--only", "nope"]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_rows_from_several_processes_merge_by_problem_and_seed(suite, tmp_path):
    path = tmp_path / "suite.json"
    suite.record(path, {"problem": "a", "seed": 0, "feasible": 1})
    suite.record(path, {"problem": "b", "seed": 0, "feasible": 2})
    suite.record(path, {"problem": "a", "seed": 0, "feasible": 3})
    assert json.loads(path.read_text()) == [{"problem": "b", "seed": 0, "feasible": 2}, {"problem": "a", "seed": 0, "feasible": 3}]


def test_an_interrupted_run_stops_the_suite(suite, tmp_path, monkeypatch, capsys):
    """SIGINT / SIGTERM end the run in progress as 'interrupted' (checkpointed): the suite stops there
    instead of going on with the next problem."""
    calls = []

    def interrupted(spec, cfg, out, **kw):
        calls.append(spec.name)
        return SimpleNamespace(status="interrupted")

    monkeypatch.setattr(suite.runs, "train", interrupted)
    assert suite.main(["--only", "hook-2d", "plate-2d", "--out", str(tmp_path)]) == 130
    assert calls == ["hook-2d"] and "interrupted" in capsys.readouterr().err
    assert not (tmp_path / "suite.json").exists()


def test_a_topology_target_joins_the_spec_and_the_name(suite, capsys):
    from ginn.errors import SpecError
    from ginn.problems import load_spec
    from ginn.problems.spec import validate_spec

    spec = suite.with_topology(suite.as_user_spec(load_spec("obstacle")), {"holes": 2})
    assert spec.name == "obstacle-holes2" and spec.build().topology.targets == {1: 2}
    # the run directory records the spec as YAML, which must load again (a valid name)
    assert validate_spec(spec.model_dump(mode="json", exclude_none=True, by_alias=True)).name == "obstacle-holes2"
    shelf = load_spec(str(ROOT / "benchmarks" / "suite" / "shelf-3d.yaml"))
    assert suite.with_topology(shelf, {"tunnels": 1, "cavities": 0}).build().topology.targets == {1: 1, 2: 0}
    with pytest.raises(SpecError, match="holes"):
        suite.with_topology(shelf, {"holes": 1})
    assert suite.topology_line({"dim": 2, "holes": [2, 1, 2, 2, None]}) == "  holes per shape: 2: 3, 1: 1"
    assert suite.topology_line({"dim": 3, "genus": [1, 1, 0]}) == "  genus per shape: 1: 2, 0: 1"
    assert suite.main(["--only", "hook-2d", "--topology", "holes=-1"]) == 2
    assert "--topology" in capsys.readouterr().err


def test_the_objective_column(suite, monkeypatch):
    plateau = [{"cd2_to_reference": 0.004, "area_relative_error": -0.013}, {"cd2_to_reference": 0.2, "area_relative_error": 0.01}]
    o = suite.objective(plateau)
    assert o == {"cd2_to_reference": 0.2, "area_relative_error": -0.013}
    assert suite.objective_text(o) == "CD2 0.2, area -1.3 %"
    beams = [{"compliance": 150.1}, {"compliance": 180.0}, {"compliance": None}]
    assert suite.objective_text(suite.objective(beams)) == "compliance 150.1 to 180"
    assert suite.objective_text({"compliance": [150.1, 180.0], "simp": 150.0}) == "compliance 150.1 to 180 (1.00 to 1.20 x SIMP)"
    assert suite.objective_text({"compliance": [165.0, 165.0], "simp": 150.0}) == "compliance 165 (1.10 x SIMP)"
    seen = []
    monkeypatch.setattr(suite, "simp_reference", lambda p: seen.append(p.name) or SimpleNamespace(compliance=150.0))
    o = suite.objective(beams, get_spec("mbb").build())
    assert seen == ["mbb"] and suite.objective_text(o) == "compliance 150.1 to 180 (1.00 to 1.20 x SIMP)"
    assert "simp" not in suite.objective(beams, get_spec("obstacle").build())  # no physics: no reference
    assert suite.objective([{"interface_cd1": 1e-3}]) is None and suite.objective_text(None) == "–"


def test_make_adds_a_thickness_and_a_volume_bound(suite, tmp_path, capsys):
    from ginn.problems import load_spec
    from ginn.problems.spec import validate_spec

    hook = suite.with_make(load_spec(str(ROOT / "benchmarks" / "suite" / "hook-2d.yaml")))
    assert hook.name == "hook-2d-make"
    tol = hook.build().tolerances
    # half the domain's longest side is 0.7
    assert tol.min_thickness.size == pytest.approx(0.05 * 0.7) and tol.volume_fraction.max == 0.5
    assert validate_spec(hook.model_dump(mode="json", exclude_none=True, by_alias=True)).name == "hook-2d-make"
    # a bound the spec states is kept
    make = load_spec(str(ROOT / "benchmarks" / "feature" / "bracket-make.yaml"))
    kept = suite.with_make(make).build().tolerances
    assert kept.min_thickness.size == pytest.approx(0.02) and kept.volume_fraction.max == 0.3
    assert suite.make_line({"thickness_removed": [0.0, 0.0031], "volume_fraction": [0.21, 0.48]}) == \
        "  thickness removed 0 to 0.0031, volume fraction 0.21 to 0.48"
    assert suite.main(["--make", "--only", "plateau"]) == 2
    assert "surface" in capsys.readouterr().err
    assert suite.main(["--make", "--only", "hook-2d", "--iterations", "2", "--resolution", "32", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[2].startswith("| hook-2d-make | 0 | ") and out[3].startswith("  thickness removed ")
    row = json.loads((tmp_path / "suite.json").read_text())[0]
    assert (tmp_path / "hook-2d-make-s0").is_dir() and 0 <= row["volume_fraction"][0] <= row["volume_fraction"][1] <= 1
