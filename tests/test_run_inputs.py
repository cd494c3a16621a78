"""A run directory is self-contained: the files its problem reads (meshes) are copied into it, and
the run rebuilds its problem from its own copies only; editing, moving or deleting the original
spec and mesh changes nothing, and a missing copy is one line, never a silent fallback."""

import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
import yaml

from ginn import runs
from ginn.cli import main

SUITE = Path(__file__).resolve().parents[1] / "benchmarks" / "suite"
TINY = ["latents.n_shapes=2", "model.hidden=[8,8]", "sampling.n_domain=64", "sampling.n_outside=32",
        "sampling.n_interface=32", "sampling.n_band=32", "sampling.n_boundary=32", "training.threads=1",
        "training.feasibility_checks=0", "connectedness.grid=8"]


def test_a_run_keeps_its_meshes_and_reads_only_them(tmp_path, capsys):
    src = tmp_path / "spec"
    (src / "meshes").mkdir(parents=True)
    shutil.copy(SUITE / "mount-3d.yaml", src / "mount.yaml")
    shutil.copy(SUITE / "meshes" / "pad.stl", src / "meshes" / "pad.stl")
    spec, cfg = runs.resolve(src / "mount.yaml", None, {"training": {"iterations": 1}}, sets=TINY)
    run = runs.train(spec, cfg, tmp_path / "run", progress=False, results=False).run_dir
    recorded = yaml.safe_load((run / "problem.yaml").read_text())
    assert recorded["geometry"]["interfaces"][0]["path"] == "inputs/pad.stl"
    assert (run / "inputs" / "pad.stl").read_bytes() == (src / "meshes" / "pad.stl").read_bytes()
    before = runs.load_run(run).task.problem.interfaces[0]
    # the original mesh changed, then the whole original folder gone: the run is what it was
    trimesh.creation.box(extents=[0.3, 0.3, 0.1]).export(src / "meshes" / "pad.stl")
    shutil.rmtree(src)
    after = runs.load_run(run).task.problem.interfaces[0]
    np.testing.assert_array_equal(_points(before), _points(after))
    # its own copy missing: one line naming it
    (run / "inputs" / "pad.stl").unlink()
    assert main(["export", str(run)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "inputs/pad.stl" in err
    (run / "problem.yaml").unlink()
    assert main(["eval", str(run)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "problem.yaml: missing" in err


def _points(interface) -> np.ndarray:
    """Points drawn on the interface with a fixed generator: equal for equal meshes."""
    out = interface.sample(256, generator=torch.Generator().manual_seed(0))
    return (out[0] if isinstance(out, tuple) else out).numpy()


@pytest.fixture(autouse=True)
def _cwd(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
