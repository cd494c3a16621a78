"""The `ginn` command line: one-line errors with exit status 2, and a train -> eval -> export -> plot -> resume round trip."""

import json
import runpy
import sys

import pytest

from ginn.cli import main

TINY = [
    "--set", "sampling.n_domain=256", "--set", "sampling.n_outside=128", "--set", "sampling.n_obstacle=32",
    "--set", "sampling.n_interface=64", "--set", "sampling.n_boundary=32", "--set", "latents.n_shapes=2",
    "--set", "model.hidden=[16,16]", "--set", "output.resolution=48", "--quiet",
]


def run_cli(args, capsys):
    code = main(args)
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize(
    "args, needle",
    [
        (["train", "nope"], "unknown problem"),
        (["train", "obstacle", "--set", "losses.foo.weight=1"], "losses.foo"),
        (["train", "obstacle", "--set", "training.lr=-1"], "training.lr"),
        (["train", "obstacle", "--set", "noequals"], "key=value"),
        (["train", "obstacle", "--preset", "nosuch"], "preset"),
        (["train", "obstacle", "--iterations", "-3"], "iterations"),
        (["train", "obstacle", "--device", "tpu"], "device"),
        (["train", "obstacle", "--bogus"], "unrecognized"),
        (["train", "obstacle", "--iterations", "x"], "invalid int"),
        (["eval", "/nonexistent/run"], "not a ginn run directory"),
        (["resume", "/nonexistent/run"], "not a ginn run directory"),
        (["train", "missing_spec.yaml"], "not found"),
    ],
)
def test_bad_input_one_line_exit_2(args, needle, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as e:
        code = main(args)
        raise SystemExit(code)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("ginn: error:"), err
    assert needle in err


def test_problems_lists_builtins(capsys):
    code, out, _ = run_cli(["problems"], capsys)
    assert code == 0
    for name in ("obstacle", "bracket", "plateau", "mirror", "gray-scott"):
        assert name in out
    code, out, _ = run_cli(["problems", "show", "obstacle"], capsys)
    assert code == 0 and "design_region" in out


@pytest.mark.long
def test_train_eval_export_plot_resume_round_trip(tmp_path, capsys, few_heldout_checks):
    run = tmp_path / "run"
    code, out, _ = run_cli(["train", "obstacle", "--preset", "demo", "--iterations", "3", "--out", str(run), *TINY], capsys)
    assert code == 0
    for f in ("config.yaml", "problem.yaml", "env.json", "metrics.jsonl", "checkpoints/last.pt", "status.json"):
        assert (run / f).exists(), f
    assert json.loads((run / "status.json").read_text())["status"] == "completed"
    assert len(list((run / "shapes").glob("*.png"))) == 2 and (run / "figures" / "loss_curves.png").exists()
    code, out, _ = run_cli(["eval", str(run), "--resolution", "64", "--heldout", "8"], capsys)
    assert code == 0 and "held-out latents: " in out and " of 8 feasible" in out
    m = json.loads((run / "metrics.json").read_text())
    assert m["problem"] == "obstacle" and m["n_shapes"] == 2 and len(m["shapes"]) == 2
    held = m["feasibility"]["heldout"]
    assert held["shapes"] == 8 and len(held["latents"]) == 8 and len(held["violations"]) == 8
    assert m["latent_space"]["path_codes"] == 8 and m["latent_space"]["resolution"] == 64
    assert set(m["mean"]) >= {"b0", "volume_outside", "interface_cd1", "connected_interfaces_share", "surface_strain"}
    code, out, _ = run_cli(["eval", str(run), str(run), "--table", "--resolution", "48", "--heldout", "4"], capsys)
    assert code == 0 and out.count("|") > 10
    code, out, _ = run_cli(["export", str(run), "--latent", "0.5", "--resolution", "48", "--out", str(tmp_path / "ex")], capsys)
    assert code == 0 and list((tmp_path / "ex").glob("*z0.5*.svg"))
    verdicts = json.loads((tmp_path / "ex" / "verdicts.json").read_text())
    assert verdicts["shapes"][0]["latent"] == [0.5] and verdicts["shapes"][0]["text"] in out
    assert "judged as ginn eval judges them" in out
    code, out, err = run_cli(["export", str(run), "--latent", "0.5", "0.1"], capsys)
    assert code == 2 and "latent" in err
    code, out, _ = run_cli(["plot", str(run), "--resolution", "48"], capsys)
    assert code == 0 and "superposition.png" in out
    # resume continues to a larger iteration count from the checkpoint
    code, out, _ = run_cli(["resume", str(run), "--iterations", "5", "--no-results", "--quiet"], capsys)
    assert code == 0
    assert json.loads((run / "status.json").read_text())["step"] == 5


def test_module_entry_point_help(monkeypatch, capsys):
    """``python -m ginn --help`` runs ginn/__main__.py (here in this process, as ``-m`` would)."""
    monkeypatch.setattr(sys, "argv", ["ginn", "--help"])
    sys.modules.pop("ginn.__main__", None)
    with pytest.raises(SystemExit) as exit_:
        runpy.run_module("ginn", run_name="__main__", alter_sys=True)
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    for cmd in ("train", "resume", "problems", "eval", "export", "plot", "view", "sweep"):
        assert cmd in out
