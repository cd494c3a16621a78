"""The command line on a CUDA device: train (with feasibility checks over held-out codes), resume,
eval and export run there as on the CPU, and the judge gives one run the same verdicts on both
devices. Skipped without a CUDA device (tests/conftest.py)."""

import json
from pathlib import Path

import pytest
import yaml

from ginn.cli import main

pytestmark = [pytest.mark.cuda, pytest.mark.long]

DEVICE = "cuda"
MOUNT_3D = Path(__file__).resolve().parents[1] / "benchmarks" / "suite" / "mount-3d.yaml"

SMALL_2D = [
    "--set", "sampling.n_domain=512", "--set", "sampling.n_outside=256", "--set", "sampling.n_obstacle=64",
    "--set", "sampling.n_interface=128", "--set", "sampling.n_boundary=64", "--set", "latents.n_shapes=2",
    "--set", "model.hidden=[32,32]", "--set", "output.resolution=64", "--set", "training.feasibility_checks=2",
    "--quiet",
]


def _run(args, capsys):
    code = main(args)
    out = capsys.readouterr()
    return code, out.out, out.err


def _eval(run, device, capsys):
    code, out, err = _run(["eval", str(run), "--device", device, "--resolution", "64", "--heldout", "8"], capsys)
    assert code == 0, err
    return json.loads((run / "metrics.json").read_text())


def test_generative_2d_round_trip_on_cuda(tmp_path, capsys, few_heldout_checks):
    run = tmp_path / "run"
    code, _, err = _run(["train", "obstacle", "--preset", "demo", "--iterations", "20", "--device", DEVICE, "--out", str(run), *SMALL_2D], capsys)
    assert code == 0, err
    assert json.loads((run / "status.json").read_text())["status"] == "completed"
    lines = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    checks = [c for c in lines if c.get("event") == "feasibility"]
    assert [c["step"] for c in checks] == [10, 20] and all(c["heldout"]["shapes"] == 2 for c in checks)
    code, _, err = _run(["resume", str(run), "--iterations", "24", "--device", DEVICE, "--no-results", "--quiet"], capsys)
    assert code == 0, err
    assert json.loads((run / "status.json").read_text())["step"] == 24
    on_gpu = _eval(run, DEVICE, capsys)
    on_cpu = _eval(run, "cpu", capsys)
    # one judge: the same constraints violated at the same codes, with values equal to the rounding
    # of a float32 grid evaluation (volume: a few of the 64^2 cells)
    for key in ("feasible", "shapes"):
        assert on_gpu["feasibility"][key] == on_cpu["feasibility"][key]
        assert on_gpu["feasibility"]["heldout"][key] == on_cpu["feasibility"]["heldout"][key]
    pairs = zip(on_gpu["feasibility"]["violations"] + on_gpu["feasibility"]["heldout"]["violations"],
                on_cpu["feasibility"]["violations"] + on_cpu["feasibility"]["heldout"]["violations"])
    for gpu, cpu in pairs:
        assert set(gpu) == set(cpu)
        for name in gpu:
            assert gpu[name]["value"] == pytest.approx(cpu[name]["value"], rel=1e-3, abs=2e-3), name
    code, out, err = _run(["export", str(run), "--latent", "0.25", "--device", DEVICE, "--resolution", "64", "--out", str(tmp_path / "ex")], capsys)
    assert code == 0, err
    assert json.loads((tmp_path / "ex" / "verdicts.json").read_text())["shapes"][0]["latent"] == [0.25]
    code, out, err = _run(["plot", str(run), "--device", DEVICE, "--resolution", "48"], capsys)
    assert code == 0 and "superposition.png" in out, err
    code, out, err = _run(["view", str(run), "--device", DEVICE, "--steps", "4", "--out", str(tmp_path / "x.html")], capsys)
    assert code == 0 and (tmp_path / "x.html").stat().st_size > 0, err


def test_generative_3d_trains_and_evaluates_on_cuda(tmp_path, capsys, few_heldout_checks):
    run = tmp_path / "run3"
    small_3d = [
        "--set", "latents.n_shapes=2", "--set", "model.hidden=[32,32]", "--set", "output.resolution=48",
        "--set", "training.feasibility_checks=1", "--quiet",
    ]
    code, _, err = _run(["train", str(MOUNT_3D), "--iterations", "6", "--device", DEVICE, "--out", str(run), *small_3d], capsys)
    assert code == 0, err
    code, _, err = _run(["eval", str(run), "--device", DEVICE, "--resolution", "48", "--heldout", "2"], capsys)
    assert code == 0, err
    m = json.loads((run / "metrics.json").read_text())
    assert len(m["shapes"]) == 2 and m["feasibility"]["heldout"]["shapes"] == 2


@pytest.mark.parametrize("args", [
    ["gray-scott", "--preset", "quick", "--set", "latents.draw=uniform"],
    ["mirror", "--preset", "demo"],
    ["plateau", "--preset", "demo"],
    ["bracket", "--preset", "demo", "--set", "latents.n_shapes=2"],
    [str(Path(__file__).resolve().parents[1] / "benchmarks" / "volume" / "obstacle-35.yaml")],
], ids=["gray-scott", "mirror", "plateau", "bracket", "volume-bound"])
def test_every_task_kind_steps_on_cuda(args, tmp_path, capsys, few_heldout_checks):
    run = tmp_path / "run"
    code, _, err = _run(["train", *args, "--iterations", "2", "--device", DEVICE, "--out", str(run), "--no-results", "--quiet"], capsys)
    assert code == 0, err
    status = json.loads((run / "status.json").read_text())
    assert status["status"] == "completed" and status["step"] == 2


MANUFACTURING = {
    "area": {"max": 8.0}, "min_thickness": 0.05, "min_gap": 0.05, "min_radius": 0.05,
    "overhang": {"angle": 45, "up": [0, 1], "plate": -0.4},
    "faces": [{"region": {"type": "rectangle", "lo": [-0.85, 0.3], "hi": [-0.55, 0.45]}, "normal": [0, 1]}],
}


def test_manufacturing_tolerances_train_and_are_judged_on_cuda(tmp_path, capsys, few_heldout_checks):
    """Every manufacturing term steps on CUDA and ginn eval measures every one of them there."""
    spec = yaml.safe_load((Path(__file__).resolve().parents[1] / "benchmarks" / "volume" / "obstacle-35.yaml").read_text())
    spec["tolerances"] = MANUFACTURING
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(spec))
    run = tmp_path / "run"
    code, _, err = _run(["train", str(path), "--iterations", "4", "--device", DEVICE, "--out", str(run), "--no-results",
                         "--quiet", "--set", "training.feasibility_checks=1"], capsys)
    assert code == 0, err
    m = _eval(run, DEVICE, capsys)
    for key in ("boundary_area", "thickness_removed", "gap_filled", "overhang_share", "sharp_share", "face_deviation"):
        assert all(key in s for s in m["shapes"]), key
