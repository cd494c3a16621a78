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


def test_structural_solver_and_training_on_cuda(tmp_path, capsys):
    """The batched CG on the GPU agrees with the CPU's direct solve (2D) and CG (3D) and hands the same
    gradient; a structural problem trains and is judged there."""
    import numpy as np
    import torch

    from ginn.physics import ElasticitySolver, ElementGrid, compliance

    for shape in ((30, 10), (12, 6, 6)):
        d = len(shape)
        g = ElementGrid((0.0,) * d, (3.0, 1.0, 1.0)[:d], shape)
        x = g.nodes
        fixed = np.zeros((g.n_nodes, d), bool)
        fixed[np.isclose(x[:, 0], 0)] = True
        F = np.zeros((g.n_nodes, d))
        F[np.isclose(x[:, 0], 3.0), 1] = -1.0
        E = torch.tensor(np.random.default_rng(0).uniform(1e-3, 1.0, (4, g.n_elements)))
        cpu = ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(1, -1), method="direct" if d == 2 else "cg")
        gpu = ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(1, -1), method="cg")
        Ec, Eg = E.clone().requires_grad_(), E.to(DEVICE).requires_grad_()
        cc, _ = compliance(Ec, cpu)
        cg, _ = compliance(Eg, gpu)
        cc.sum().backward()
        cg.sum().backward()
        assert torch.allclose(cg.cpu(), cc, rtol=1e-7)
        assert torch.allclose(Eg.grad.cpu(), Ec.grad, rtol=1e-6, atol=1e-9 * float(Ec.grad.abs().max()))
        # the clamped edge held along its normal only, one corner fully: the nodes' own frames on the GPU
        normals = np.where(np.isclose(x[:, :1], 0), np.eye(d)[0], 0.0)
        fixed = np.zeros((g.n_nodes, d), bool)
        fixed[np.flatnonzero(np.isclose(x[:, 0], 0))[:2]] = True
        if d == 3:
            fixed[np.isclose(x[:, 0], 0) & np.isclose(x[:, 2], 0), 2] = True
        cpu = ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(1, -1), method="direct", normals=normals)
        gpu = ElasticitySolver(g, 0.3, fixed.reshape(-1), F.reshape(1, -1), method="cg", normals=normals)
        assert torch.allclose(compliance(E.to(DEVICE), gpu)[0].cpu(), compliance(E, cpu)[0], rtol=1e-7)
    run = tmp_path / "mbb"
    code, _, err = _run(["train", "mbb", "--iterations", "20", "--device", DEVICE, "--out", str(run), "--quiet",
                         "--set", "model.hidden=[32,32]", "--set", "training.feasibility_checks=2"], capsys)
    assert code == 0, err
    metrics = _eval(run, DEVICE, capsys)
    assert metrics["shapes"][0]["compliance"] > 0
