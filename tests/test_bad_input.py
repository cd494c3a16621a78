"""Every bad input and failing disk ends in one line ``ginn: error: ...`` that names the bad field,
file or path, and exit status 2, never a traceback."""

import contextlib
import os
import random
import shutil
import subprocess
from pathlib import Path

import pytest
import torch

from ginn import runs
from ginn.cli import main
from ginn.train.checkpoint import load_checkpoint

TINY = ["--set", "latents.n_shapes=2", "--set", "model.hidden=[16,16]", "--set", "sampling.n_domain=128",
        "--set", "sampling.n_outside=64", "--set", "sampling.n_interface=32", "--set", "sampling.n_boundary=32",
        "--set", "training.threads=1"]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """A finished tiny obstacle run (6 iterations)."""
    out = tmp_path_factory.mktemp("bad") / "run"
    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 6}},
                             sets=[s for s in TINY if s != "--set"])
    runs.train(spec, cfg, out, progress=False, results=False)
    return out


def _copy(run: Path, where: Path) -> Path:
    shutil.copytree(run, where)
    return where


def _run(args, capsys, monkeypatch, cwd) -> tuple[int, str]:
    monkeypatch.chdir(cwd)
    try:
        code = main([str(a) for a in args])
    except SystemExit as e:
        code = e.code
    return code, capsys.readouterr().err


CASES = {
    "view: no run": (lambda r, t: ["view", t / "missing"], "missing"),
    "view: unfinished run": (lambda r, t: _running(_copy(r, t / "r")), "ginn view shows completed runs"),
    "view: --steps 0": (lambda r, t: ["view", r, "--steps", "0"], "--steps"),
    "view: --steps x": (lambda r, t: ["view", r, "--steps", "x"], "--steps"),
    "--out is a file": (lambda r, t: (t / "f").write_text("x") and ["train", "obstacle", "--out", t / "f", *TINY],
                        "not a directory"),
    "no interfaces": (lambda r, t: (t / "empty.yaml").write_text(
        "name: empty\ngeometry: {dim: 2, domain: {lo: [0, 0], hi: [1, 1]}}\n") and ["train", t / "empty.yaml"],
        "geometry.interfaces': a shape problem needs at least one interface"),
    "no active loss": (lambda r, t: (t / "off.yaml").write_text(
        "name: noloss\ngeometry: {dim: 2, domain: {lo: [0, 0], hi: [1, 1]}, interfaces: [{type: segment, a: [0, 0], b: [1, 0]}]}\n"
        "defaults: {losses: {" + ", ".join(f"{k}: {{weight: 0}}" for k in (
            "interface", "design_region", "obstacle", "normal", "eikonal", "connectedness", "diversity")) + "}}\n")
        and ["train", t / "off.yaml"], "no active loss term"),
    "export --resolution -3": (lambda r, t: ["export", r, "--resolution", "-3"], "--resolution"),
    "eval --resolution 0": (lambda r, t: ["eval", r, "--resolution", "0"], "--resolution"),
    "eval --resolution 1e8": (lambda r, t: ["eval", r, "--resolution", "100000000"], "resolution 100000000"),
    "--set inf": (lambda r, t: ["train", "obstacle", "--set", "model.w0_first=.inf"], "model.w0_first"),
    "--set nan": (lambda r, t: ["train", "obstacle", "--set", "training.lr=.nan"], "training.lr"),
    "--device cuda:x": (lambda r, t: ["train", "obstacle", "--device", "cuda:x"], "--device"),
    "spec is a directory": (lambda r, t: ["train", t], "is a directory"),
    "duplicate spec key": (lambda r, t: (t / "dup.yaml").write_text(
        "name: a\nname: b\ngeometry: {dim: 2, domain: {lo: [0, 0], hi: [1, 1]}}\n") and ["train", t / "dup.yaml"],
        "duplicate key 'name'"),
    "name read as a boolean": (lambda r, t: (t / "b.yaml").write_text(
        "name: off\ngeometry: {dim: 2, domain: {lo: [0, 0], hi: [1, 1]}}\n") and ["train", t / "b.yaml"],
        "spec field 'name': must be text; YAML read it as False: put the name in quotes"),
    "domain bounds of 1e200": (lambda r, t: (t / "big.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [-1e200, -1e200], hi: [1e200, 1e200]}, "
        "interfaces: [{type: circle, center: [0, 0], radius: 1e199}]}\n") and ["train", t / "big.yaml"],
        "spec field 'geometry.domain.lo[0]': must be >= -1000000000000000"),
    "radius of 1e16": (lambda r, t: (t / "big.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [-1, -1], hi: [1, 1]}, "
        "interfaces: [{type: circle, center: [0, 0], radius: 1e16}]}\n") and ["train", t / "big.yaml"],
        "radius': must be <= 1000000000000000"),
    "a billion shapes": (lambda r, t: ["train", "obstacle", "--set", "latents.n_shapes=1000000000"],
                         "1000000000 shapes per step (latents.n_shapes)"),
    "a hidden width of 1e11": (lambda r, t: ["train", "obstacle", "--set", "model.hidden=[100000000000]"],
                               "model widths [100000000000]"),
    "view --steps 99999999999": (lambda r, t: ["view", r, "--steps", "99999999999"], "--steps: must be <= 4096"),
    "spec name of 300 characters": (lambda r, t: (t / "n.yaml").write_text(
        "name: " + "a" * 300 + "\ngeometry: {dim: 2, domain: {lo: [-1, -1], hi: [1, 1]}, "
        "interfaces: [{type: circle, center: [0, 0], radius: 0.5}]}\n") and ["train", t / "n.yaml"],
        "spec field 'name': string should have at most 200 characters"),
    "--out name of 300 characters": (lambda r, t: ["train", "obstacle", "--out", t / ("a" * 300), *TINY],
                                     "cannot create the run directory: a name in the path is longer than the file system allows"),
    "sweep storage not an SQLite file": (lambda r, t: (t / "s.yaml").write_text("training.lr: {type: float, low: 1.0e-4, high: 1.0e-2}\n")
                                         and (t / "notes.txt").write_text("hello")
                                         and ["sweep", "obstacle", "--space", t / "s.yaml", "--trials", "1",
                                              "--storage", f"sqlite:///{t / 'notes.txt'}"], "notes.txt is not an SQLite database"),
    "sweep storage is a directory": (lambda r, t: (t / "s.yaml").write_text("training.lr: {type: float, low: 1.0e-4, high: 1.0e-2}\n")
                                     and ["sweep", "obstacle", "--space", t / "s.yaml", "--trials", "1",
                                          "--storage", f"sqlite:///{t}"], "is a directory, not an SQLite database file"),
    "tolerance read as a boolean": (lambda r, t: (t / "y.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [-1, -1], hi: [1, 1]}, interfaces: [{type: circle, center: [0, 0], "
        "radius: 0.5}]}\ntolerances: {interface: yes}\n") and ["train", t / "y.yaml"],
        "spec field 'tolerances.interface': must be a number; YAML read it as True"),
    "negative tolerance": (lambda r, t: (t / "tol.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [0, 0], hi: [1, 1]}}\ntolerances: {interface: -1}\n")
        and ["train", t / "tol.yaml"], "tolerances.interface"),
    "negative hole count": (lambda r, t: (t / "h.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [0, 0], hi: [1, 1]}}\ntopology: {holes: -1}\n")
        and ["train", t / "h.yaml"], "spec field 'topology.holes': must be >= 0"),
    "fractional hole count": (lambda r, t: (t / "h.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [0, 0], hi: [1, 1]}}\ntopology: {holes: 1.5}\n")
        and ["train", t / "h.yaml"], "spec field 'topology.holes'"),
    "fewer holes than the interfaces force": (lambda r, t: (t / "h.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [-1, -1], hi: [1, 1]}, design_region: {type: difference, children: "
        "[{type: rectangle, lo: [-0.9, -0.9], hi: [0.9, 0.9]}, {type: disk, center: [-0.5, 0], radius: 0.1}, "
        "{type: disk, center: [0.5, 0], radius: 0.1}]}, interfaces: [{type: circle, center: [-0.5, 0], radius: 0.1}, "
        "{type: circle, center: [0.5, 0], radius: 0.1}]}\ntopology: {holes: 1}\n")
        and ["train", t / "h.yaml"], "spec field 'topology.holes': 1 is fewer than the 2 holes"),
    "fewer tunnels than the interfaces force": (lambda r, t: (t / "h.yaml").write_text(
        "name: a\ngeometry: {dim: 3, domain: {lo: [-1, -1, -1], hi: [1, 1, 1]}, design_region: {type: difference, "
        "children: [{type: box, lo: [-0.8, -0.8, -0.3], hi: [0.8, 0.8, 0.3]}, {type: cylinder, center: [0, 0, 0], "
        "axis: [0, 0, 1], radius: 0.1, length: 2.5}]}, interfaces: [{type: cylinder_wall, center: [0, 0, 0], "
        "axis: [0, 0, 1], radius: 0.1, length: 0.6}]}\ntopology: {tunnels: 0}\n")
        and ["train", t / "h.yaml"], "spec field 'topology.tunnels': 0 is fewer than the 1 tunnel every shape has"),
    "tunnels in 2D": (lambda r, t: (t / "h.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [0, 0], hi: [1, 1]}}\ntopology: {tunnels: 1}\n")
        and ["train", t / "h.yaml"], "spec field 'topology.tunnels': a 3D target"),
    "two components": (lambda r, t: (t / "h.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [0, 0], hi: [1, 1]}}\ntopology: {components: 2}\n")
        and ["train", t / "h.yaml"], "spec field 'topology.components': only 1 is supported"),
    "rotation n < 2": (lambda r, t: (t / "s.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [-1, -1], hi: [1, 1]}, interfaces: [{type: circle, center: [0, 0], radius: 0.5}]}\nsymmetry: {rotation: {center: [0, 0], n: 1}}\n")
        and ["train", t / "s.yaml"], "spec field 'symmetry.rotation.n': must be >= 2"),
    "rotation n not an integer": (lambda r, t: (t / "s.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [-1, -1], hi: [1, 1]}, interfaces: [{type: circle, center: [0, 0], radius: 0.5}]}\nsymmetry: {rotation: {center: [0, 0], n: 2.5}}\n")
        and ["train", t / "s.yaml"], "spec field 'symmetry.rotation.n'"),
    "rotation axis of zero length": (lambda r, t: (t / "s.yaml").write_text(
        "name: a\ngeometry: {dim: 3, domain: {lo: [-1, -1, -1], hi: [1, 1, 1]}, interfaces: [{type: segment, a: [0, 0, -0.5], b: [0, 0, 0.5]}]}\nsymmetry: {rotation: {center: [0, 0, 0], n: 3, axis: [0, 0, 0]}}\n")
        and ["train", t / "s.yaml"], "spec field 'symmetry.rotation.axis': must be a non-zero vector"),
    "mirror normal of zero length": (lambda r, t: (t / "s.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [-1, -1], hi: [1, 1]}, interfaces: [{type: circle, center: [0, 0], radius: 0.5}]}\nsymmetry: {mirrors: [{point: [0, 0], normal: [0, 0]}]}\n")
        and ["train", t / "s.yaml"], "spec field 'symmetry.mirrors[0].normal': must be a non-zero vector"),
    "geometry not symmetric": (lambda r, t: (t / "s.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [-1, -1], hi: [1, 1]}, interfaces: [{type: circle, center: [0, 0], radius: 0.5}]}\nsymmetry: {mirrors: [{point: [0.2, 0], normal: [1, 0]}]}\n")
        and ["train", t / "s.yaml"], "spec field 'symmetry': the interfaces are not symmetric under mirror 0"),
    "export --latent nan": (lambda r, t: ["export", r, "--latent", "nan"], "--latent"),
    "export --latent beyond float32": (lambda r, t: ["export", r, "--latent", "1e308", "--out", t / "x"],
                                       "--latent: latent values must be finite in the model's float32"),
    "params.kind of another kind": (lambda r, t: ["train", "obstacle", "--set", "params.kind=mirror"],
                                    "config field 'params.kind': 'mirror' is not the kind of problem obstacle"),
    "view --out onto the run's config": (lambda r, t: ["view", r, "--out", r / "config.yaml"], "one of the run's own files"),
    "2D export --format stl": (lambda r, t: ["export", r, "--format", "stl"], "--format stl"),
    "--iterations 0": (lambda r, t: ["train", "obstacle", "--iterations", "0"], "--iterations"),
    "device through --set": (lambda r, t: ["train", "obstacle", "--set", "device=tpu", "--out", str(t / "o")],
                             "config field 'device'"),
    "resume a completed run below its step": (lambda r, t: ["resume", _copy(r, t / "r"), "--iterations", "3"],
                                              "complete at iteration 6"),
    "0-byte checkpoint": (lambda r, t: _empty_ckpt(_copy(r, t / "r")), "empty (0 bytes)"),
    "checkpoint of another layout": (lambda r, t: _saved_ckpt(_copy(r, t / "r"), {}, "resume"), "no model weights"),
    "checkpoint with a string step": (lambda r, t: _saved_ckpt(_copy(r, t / "r"), "step", "export"), "its step is '6'"),
    "checkpoint of another model size": (lambda r, t: _saved_ckpt(_copy(r, t / "r"), "shapes", "eval"),
                                         "does not fit the model of the run's config.yaml"),
    "config.yaml edited to another model": (lambda r, t: _edit_config(_copy(r, t / "r"), "hidden", [32, 32]) and ["resume", t / "r", "--iterations", "9"],
                                            "does not fit the model"),
    "negative seed": (lambda r, t: ["train", "obstacle", "--seed", "-1"], "config field 'seed': must be >= 0"),
    "YAML nested 400 deep": (lambda r, t: (t / "d.yaml").write_text("name: " + "[" * 400 + "]" * 400 + "\n")
                             and ["train", t / "d.yaml"], "nested more than 64 levels deep"),
    "random-bytes checkpoint": (lambda r, t: _random_ckpt(_copy(r, t / "r")), "not a torch checkpoint"),
    "corrupt config.yaml": (lambda r, t: _corrupt_config(_copy(r, t / "r")), "config.yaml: YAML syntax error"),
    "invalid config.yaml": (lambda r, t: _invalid_config(_copy(r, t / "r")), "config.yaml: config field 'training.lr'"),
    "missing run": (lambda r, t: ["status", t / "nope"], "not a ginn run directory"),
    "retired setting in --set": (lambda r, t: ["train", "obstacle", "--set", "losses.containment_margin=0.05"],
                                 "config field 'losses.containment_margin' was retired: the containment floor starts"),
    "retired setting in a spec": (lambda r, t: (t / "old.yaml").write_text(
        "name: a\ngeometry: {dim: 2, domain: {lo: [0, 0], hi: [1, 1]}, interfaces: [{type: segment, a: [0, 0], b: [1, 0]}]}\n"
        "defaults: {diversity: {interface_clearance: 0.05}}\n") and ["train", t / "old.yaml"],
        "spec field 'defaults.diversity.interface_clearance' was retired: the diversity measures the whole boundary"),
}


def _running(run: Path) -> list:
    from ginn.train.rundir import write_status

    write_status(run, "running", 3, 1.0)
    return ["view", run]


def _empty_ckpt(run: Path) -> list:
    (run / "checkpoints" / "last.pt").write_bytes(b"")
    return ["eval", run]


def _saved_ckpt(run: Path, damage, command: str) -> list:
    """The run's checkpoint loaded, damaged and saved again (safe to load; the wrong layout)."""
    import torch

    path = run / "checkpoints" / "last.pt"
    state = torch.load(path, weights_only=True)
    if damage == "step":
        state["step"] = str(state["step"])
    elif damage == "shapes":
        state["model"] = {k: torch.zeros(*(n + 1 for n in v.shape)) for k, v in state["model"].items()}
    else:
        state = damage
    torch.save(state, path)
    return [command, run] + (["--iterations", "9"] if command == "resume" else [])


def _edit_config(run: Path, key: str, value) -> Path:
    import yaml

    cfg = yaml.safe_load((run / "config.yaml").read_text())
    cfg["model"][key] = value
    (run / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    return run


def _random_ckpt(run: Path) -> list:
    # fixed bytes: some random streams start with a valid pickle opcode sequence (a STOP byte first)
    (run / "checkpoints" / "last.pt").write_bytes(random.Random(0).randbytes(4096))
    return ["resume", run, "--iterations", "9"]


def _corrupt_config(run: Path) -> list:
    (run / "config.yaml").write_text("training: [1, 2\n")
    return ["eval", run]


def _invalid_config(run: Path) -> list:
    text = (run / "config.yaml").read_text().replace("lr: 0.001", "lr: -1.0")
    (run / "config.yaml").write_text(text)
    return ["plot", run]


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_is_one_line_and_exit_2(case, run_dir, tmp_path, capsys, monkeypatch):
    make, needle = CASES[case]
    args = make(run_dir, tmp_path)
    code, err = _run(args, capsys, monkeypatch, tmp_path)
    lines = [line for line in err.splitlines() if not line.startswith("ginn: note:")]
    assert code == 2, (case, err)
    assert len(lines) == 1 and lines[0].startswith("ginn: error:"), (case, err)
    assert "Traceback" not in err
    assert needle in lines[0], (case, lines[0])
    assert not list(tmp_path.glob("*.lock")), case  # a refused sweep leaves no lock beside its storage


# --- read-only directories and a full disk ------------------------------------------------------------


@contextlib.contextmanager
def _mount(path: Path, options: str):
    """A tmpfs at ``path`` (root only); skips the test where mounting is not allowed."""
    path.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.strip() or 'mount failed'}): needs root in a container "
                    "that allows mounts")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], capture_output=True)


@contextlib.contextmanager
def _read_only_copy(run: Path, where: Path):
    """``run`` copied into a read-only directory: a read-only tmpfs as root, file modes otherwise."""
    if os.geteuid() != 0:
        dst = shutil.copytree(run, where / "run")
        for p in [dst, *dst.rglob("*")]:
            p.chmod(0o555 if p.is_dir() else 0o444)
        try:
            yield Path(dst)
        finally:
            for p in [dst, *Path(dst).rglob("*")]:
                p.chmod(0o755)
        return
    with _mount(where / "mnt", "size=64m") as mnt:
        dst = shutil.copytree(run, mnt / "run")
        r = subprocess.run(["mount", "-o", "remount,ro", str(mnt)], capture_output=True, text=True)
        if r.returncode != 0:
            pytest.skip(f"cannot remount read-only: {r.stderr.strip()}")
        yield Path(dst)


@pytest.mark.parametrize("command", [["eval"], ["plot"], ["export"], ["resume", "--iterations", "9"]])
def test_read_only_run_directory(command, run_dir, tmp_path, capsys, monkeypatch):
    with _read_only_copy(run_dir, tmp_path) as ro:
        args = [command[0], ro, *command[1:]]
        code, err = _run(args, capsys, monkeypatch, tmp_path)
    lines = [line for line in err.splitlines() if not line.startswith("ginn: note:")]
    assert code == 2 and len(lines) == 1, err
    assert str(ro) in lines[0] and ("read-only" in lines[0] or "permission denied" in lines[0]), lines[0]
    assert "Traceback" not in err


def test_train_into_a_read_only_directory(tmp_path, capsys, monkeypatch):
    (tmp_path / "empty").mkdir()
    with _read_only_copy(tmp_path / "empty", tmp_path) as ro:
        code, err = _run(["train", "obstacle", "--out", ro / "new", *TINY], capsys, monkeypatch, tmp_path)
    assert code == 2 and len(err.splitlines()) == 1, err
    assert str(ro / "new") in err and ("read-only" in err or "permission denied" in err), err


def test_full_disk_keeps_the_last_checkpoint(tmp_path, capsys, monkeypatch):
    """On a tmpfs with room for one checkpoint but not for the second (written beside the first
    before it replaces it), training stops with one line that says so, and the first checkpoint
    is intact."""
    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 1}},
                             sets=[s for s in TINY if s != "--set"] + ["model.hidden=[128,128]"])
    probe = runs.train(spec, cfg, tmp_path / "probe", progress=False, results=False).run_dir
    size = (probe / "checkpoints" / "last.pt").stat().st_size
    others = sum(p.stat().st_size for p in probe.iterdir() if p.is_file())
    room = int(1.6 * size) + others + 64 * 1024
    with _mount(tmp_path / "disk", f"size={room}") as disk:
        args = ["train", "obstacle", "--out", disk / "run", "--iterations", "30", "--quiet", "--no-results",
                "--set", "training.checkpoint_every=5", *TINY, "--set", "model.hidden=[128,128]"]
        code, err = _run(args, capsys, monkeypatch, tmp_path)
        assert code == 2 and len(err.splitlines()) == 1, err
        assert "no space left on device" in err and "last checkpoint" in err, err
        ck = load_checkpoint(disk / "run" / "checkpoints" / "last.pt")
        assert ck["step"] == 5
        assert not list((disk / "run" / "checkpoints").glob("*.tmp"))


def test_the_python_api_refuses_the_same_inputs(run_dir):
    from ginn.errors import GinnError

    with pytest.raises(GinnError, match="finite"):
        runs.export(run_dir, [[float("nan")]])
    with pytest.raises(GinnError, match="GiB"):
        runs.evaluate(run_dir, resolution=100_000_000)


def test_a_run_directory_is_claimed_by_one_process(tmp_path):
    from ginn.errors import ConfigError
    from ginn.train.lock import LOCK_NAME
    from ginn.train.rundir import new_run_dir

    out = tmp_path / "out"
    path, lock = new_run_dir("x", out)
    assert path == out and lock.held
    with pytest.raises(ConfigError, match=r"another process writes a run there \(pid \d+ on .*, since 20"):
        new_run_dir("x", out)
    lock.release()  # as when its process ends, however it ends: taken again
    path, lock = new_run_dir("x", out)
    lock.release()
    (out / "config.yaml").write_text("{}")
    with pytest.raises(ConfigError, match="not empty"):
        new_run_dir("x", out)
    assert [p.name for p in out.iterdir()].count(LOCK_NAME) == 1
    (a, la), (b, lb) = new_run_dir("x", root=tmp_path / "runs"), new_run_dir("x", root=tmp_path / "runs")
    assert a != b and a.is_dir() and b.is_dir() and la.held and lb.held


def test_config_yaml_holds_only_the_model_fields_of_its_kind(run_dir):
    import yaml

    model = yaml.safe_load((run_dir / "config.yaml").read_text())["model"]
    assert model["kind"] == "siren" and "w0_first" in model and "hidden" in model
    assert not {"width", "n_blocks", "sigma", "n_features", "activation"} & set(model)


@pytest.mark.skipif(torch.cuda.is_available(), reason="needs a machine without CUDA")
def test_a_gpu_run_opens_on_a_cpu_machine(run_dir, tmp_path, capsys):
    """A run recorded with ``device: cuda`` is read here on the CPU; resuming it needs the choice
    said (``--device cpu``), in one line."""
    import yaml

    r = _copy(run_dir, tmp_path / "r")
    cfg = yaml.safe_load((r / "config.yaml").read_text())
    (r / "config.yaml").write_text(yaml.safe_dump({**cfg, "device": "cuda"}, sort_keys=False))
    assert main(["eval", str(r), "--resolution", "32"]) == 0
    assert main(["export", str(r), "--resolution", "32", "--out", str(tmp_path / "ex")]) == 0
    assert main(["view", str(r), "--steps", "2", "--out", str(tmp_path / "e.html")]) == 0
    capsys.readouterr()
    assert main(["resume", str(r), "--iterations", "8"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "trains on cuda" in err and "--device cpu" in err
    assert main(["resume", str(r), "--iterations", "8", "--device", "cpu", "--quiet", "--no-results"]) == 0
    assert runs.load_run(r).step == 8
    assert main(["eval", str(r), "--device", "cuda"]) == 2 and "CUDA is not available" in capsys.readouterr().err


def test_bytes_that_are_not_utf8_in_metrics_jsonl_cost_one_line(tmp_path):
    from ginn.train.rundir import read_metrics, truncate_metrics

    log = tmp_path / "metrics.jsonl"
    log.write_bytes(b'{"step": 0, "total": 1.0}\n\xff\xfe\x00garbage\n{"step": 1, "total": 0.5}\n')
    with pytest.warns(UserWarning, match=r"metrics.jsonl:2: skipped"):
        assert [r["step"] for r in read_metrics(log)] == [0, 1]
    with pytest.warns(UserWarning, match="line 2"):
        assert truncate_metrics(log, 1) == 2  # the damaged line and iteration 1
    assert log.read_text() == '{"step": 0, "total": 1.0}\n'


@pytest.mark.long
def test_fuzz_pass_answers_every_bad_input_with_one_line(capsys):
    """benchmarks/fuzz.py on 90 generated cases (bad spec fields, bad flags, damaged run files):
    exit 2 and one line for each bad spec and flag, no traceback anywhere, and ``ginn status``
    still answering for every damaged run (the script's default is 240 cases)."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "fuzz.py"
    spec = importlib.util.spec_from_file_location("fuzz", path)
    fuzz = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fuzz)
    code = fuzz.main(["--n", "90", "--seed", "11"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "90 of 90 cases answered as they should (30 spec, 30 flag, 30 run)" in out
