"""Resuming is exact: a run killed at any iteration and resumed from its last checkpoint ends with
the weights of the uninterrupted run, bit for bit on CPU, for every kind of task; metrics.jsonl is
cut back to the checkpoint; status.json tells a killed run from a running one."""

import json
import os
import random
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from ginn import runs
from ginn.cli import main
from ginn.config import build_config, config_to_dict
from ginn.tasks import make_task
from ginn.train.checkpoint import load_checkpoint
from ginn.train.rundir import read_status, truncate_metrics
from ginn.train.trainer import Trainer

# the demo's four shapes with fewer domain samples: one shape stays in two pieces, so the
# connectedness loss penalises a saddle at every step, with warm updates between rebuilds
# the runs below compare an uninterrupted run in this process with processes of their own: with
# the eager kernels, which every process computes alike (the compiled ones are checked process
# against process, test_compiled_kernels_resume_bitwise); the feasibility checks only where a
# case says so (they cost a grid evaluation of every shape each)
OBSTACLE = ["sampling.n_domain=512", "sampling.n_outside=256", "connectedness.every=3", "training.threads=1",
            "training.log_every=1", "training.compile=false", "training.feasibility_checks=0"]


@pytest.fixture(autouse=True)
def _threads():
    n = torch.get_num_threads()
    yield
    torch.set_num_threads(n)


def _weights(model) -> dict:
    return {k: v.detach().clone() for k, v in model.state_dict().items()}


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


class _Kill(Exception):
    """Stands in for a kill: the trainer stops without a checkpoint at this iteration."""


def _run_with_kills(spec, cfg, out: Path, kills: list[int]):
    """Train into ``out``, 'killed' after each iteration in ``kills`` and resumed from the last
    checkpoint each time; returns the final model's weights."""
    for k in kills:
        task = make_task(spec, cfg)

        def hook(trainer, step, values, k=k):
            if step + 1 == k:
                raise _Kill

        tr = Trainer(task, cfg, out, progress=False, hooks=[hook])
        tr.resume()
        with pytest.raises(_Kill):
            tr.train()
    tr = Trainer(make_task(spec, cfg), cfg, out, progress=False)
    assert tr.resume()
    return _weights(tr.train().model)


CASES = {
    "surface network, diversity": ("obstacle", "demo", OBSTACLE),
    "persistent homology": ("obstacle", "demo", [*OBSTACLE, "connectedness.method=persistent-homology",
                                                 "connectedness.grid=32"]),
    "augmented Lagrangian": ("obstacle", "demo", [*OBSTACLE, "balancing.method=augmented-lagrangian",
                                                  "balancing.update_every=4", "balancing.mu_growth=2"]),
    "adaptive multipliers": ("obstacle", "demo", [*OBSTACLE, "balancing.method=adaptive"]),
    "check-driven multipliers, stop when feasible": ("obstacle", "demo", [
        *OBSTACLE, "balancing.method=feasibility", "training.stop_when_feasible=true", "latents.n_shapes=2",
        "training.feasibility_checks=4"]),
    "structural (compliance, volume offset)": ("mbb", None, ["training.threads=1", "model.hidden=[16,16]",
                                                             "structural.cells=30"]),
    "structural, a least diversity (its running estimate and calibration)": ("cantilever", None, [
        "training.threads=1", "model.hidden=[16,16]", "structural.cells=30", "latents.n_shapes=3",
        "training.feasibility_checks=4"]),
    "structural, CG warm starts": ("mbb", None, ["training.threads=1", "model.hidden=[16,16]", "structural.cells=30",
                                                 "structural.method=cg"]),
    "gated curvature objective, reference verdict": ("plateau", None, [
        "training.threads=1", "model.hidden=[16,16]", "losses.mean_curvature.start=3", "sampling.n_domain=256",
        "sampling.n_boundary=64", "sampling.n_interface=64", "training.feasibility_checks=3"]),
    "mirror": ("mirror", None, ["training.threads=1", "params.n_samples=64"]),
    "gray-scott": ("gray-scott", "quick", ["training.threads=1", "model.hidden=[16,8]", "latents.n_shapes=2",
                                           "params.grid=16", "params.fine_grid=0", "params.step_reuse=4",
                                           "params.flow_steps=0", "training.lr_restart_at=0"]),
}


@pytest.mark.long
@pytest.mark.parametrize("case", list(CASES))
def test_resume_is_exact_for_every_task_kind(case, tmp_path, few_heldout_checks):
    problem, preset, sets = CASES[case]
    spec, cfg = runs.resolve(problem, preset, {"training": {"iterations": 16, "checkpoint_every": 5}}, sets=sets)
    if problem == "obstacle":  # the codes drawn at each step are part of what resumes exactly
        assert cfg.latents.draw == "lattice" and cfg.latents.n_shapes > 1
    base = Trainer(make_task(spec, cfg), cfg, None, progress=False).train()
    resumed = _run_with_kills(spec, cfg, tmp_path / "run", kills=[7, 13])
    assert _same(_weights(base.model), resumed), case


def _poll_step(metrics: Path) -> int:
    try:
        lines = metrics.read_text().splitlines()
    except OSError:
        return -1
    for line in reversed(lines):
        try:
            return int(json.loads(line)["step"])
        except (ValueError, KeyError, TypeError):
            continue
    return -1


def _cli(*args: str, out: Path, sets: list[str]) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "ginn", "train", *args, "--out", str(out), "--quiet", "--no-results"]
    for s in sets:
        cmd += ["--set", s]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow
def test_sigkill_at_random_iterations_resumes_bitwise(tmp_path, capsys):
    """``kill -9`` at five random iterations of real ``ginn train`` processes (checkpoints every
    0.2 s of training, so at arbitrary steps; one kill may come before the first checkpoint, which
    restarts the run), then ``ginn resume``: the final weights equal the uninterrupted run's, and a
    killed run reads as ``not running`` (about a minute; the default suite kills one run once,
    test_compiled_kernels_resume_bitwise)."""
    sets = [*OBSTACLE, "training.iterations=40", "training.checkpoint_every=1000", "training.checkpoint_seconds=0.2"]
    spec, cfg = runs.resolve("obstacle", "demo", {"output": {"results": False}}, sets=sets)
    base = Trainer(make_task(spec, cfg), cfg, None, progress=False).train()
    rng = random.Random(0)
    for i, target in enumerate(sorted(rng.sample(range(4, 36), 5))):
        out = tmp_path / f"kill{i}"
        proc = _cli("obstacle", "--preset", "demo", out=out, sets=sets)
        deadline = time.time() + 120
        while _poll_step(out / "metrics.jsonl") < target and proc.poll() is None and time.time() < deadline:
            time.sleep(0.02)
        assert proc.poll() is None, f"the run ended before iteration {target}: {proc.stderr.read()}"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        assert read_status(out).status in ("running", "unknown")
        assert main(["status", str(out)]) == 0
        said = capsys.readouterr().out
        assert "not running" in said or "unknown" in said, said
        outcome = runs.resume(out, progress=False)
        assert outcome.status == "completed" and outcome.step == 40
        assert _same(_weights(base.model), _weights(outcome.model)), f"kill near iteration {target}"
        steps = [r["step"] for r in map(json.loads, (out / "metrics.jsonl").read_text().splitlines()) if "event" not in r]
        assert steps == list(range(40)), steps  # no iteration logged twice, none missing
        assert not (out / "shapes").exists()  # --no-results is remembered by the resume


def test_metrics_cut_back_to_the_checkpoint_and_partial_line_dropped(tmp_path, few_heldout_checks):
    """A crash after the last checkpoint leaves log lines past it and a half-written last line;
    ``ginn resume`` drops both (with a warning) and logs every iteration exactly once."""
    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 12, "checkpoint_every": 5}},
                             sets=[*OBSTACLE, "latents.n_shapes=2", "training.feasibility_checks=4"])
    out = tmp_path / "run"

    def kill(trainer, step, values):
        if step == 7:
            raise _Kill

    with pytest.raises(_Kill):
        runs.train(spec, cfg, out, progress=False, results=False, hooks=[kill])
    assert runs.resume(out, progress=False).step == 12
    assert load_checkpoint(out / "checkpoints" / "last.pt")["step"] == 12
    m = out / "metrics.jsonl"
    with open(m, "a") as fh:  # as if iterations 12 and 13 had run after the checkpoint, then a crash
        fh.write('{"step": 12, "total": 1.0}\n{"step": 13, "tot')
    with pytest.warns(UserWarning, match="partial last line"):
        outcome = runs.resume(out, iterations=15, progress=False, results=False)
    assert outcome.step == 15
    records = [json.loads(line) for line in m.read_text().splitlines()]
    assert [r["step"] for r in records if "event" not in r] == list(range(15))
    checks = [r["step"] for r in records if r.get("event") == "feasibility"]
    assert checks == sorted(set(checks)) and checks[-1] == 15  # each check once, the last at the end
    # iteration records from index 10 on go, events from 11 completed iterations on
    assert truncate_metrics(m, 10) == sum(r["step"] >= 10 + ("event" in r) for r in records)
    assert [r["step"] for r in map(json.loads, m.read_text().splitlines()) if "event" not in r] == list(range(10))


def test_status_is_truthful_through_failure_and_completion(tmp_path):
    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 6}}, sets=OBSTACLE)
    out = runs.train(spec, cfg, tmp_path / "ok", progress=False, results=False)
    st = read_status(out.run_dir)
    assert (st.status, st.step, st.pid) == ("completed", 6, None)
    assert st.describe().startswith("completed at iteration 6")
    # a run whose loss never becomes finite fails, and says why
    bad = build_config(config_to_dict(cfg), {"training": {"lr": 1e30, "max_rollbacks": 0, "max_bad_steps": 1,
                                                          "iterations": 50}})
    with pytest.raises(Exception):
        runs.train(spec, bad, tmp_path / "bad", progress=False, results=False)
    st = read_status(tmp_path / "bad")
    assert st.status == "failed" and "diverged" in st.reason


def test_resume_without_a_checkpoint_restarts_from_the_config(tmp_path, capsys):
    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 9, "checkpoint_every": 100}}, sets=OBSTACLE)
    base = Trainer(make_task(spec, cfg), cfg, None, progress=False).train()
    out = tmp_path / "run"
    task = make_task(spec, cfg)

    def hook(trainer, step, values):
        if step == 4:
            raise _Kill

    from ginn.train.rundir import new_run_dir, write_run_files

    _, lock = new_run_dir("obstacle", out)
    write_run_files(out, cfg, Path(spec.source))
    with pytest.raises(_Kill):
        Trainer(task, cfg, out, progress=False, hooks=[hook]).train()
    lock.release()
    assert not (out / "checkpoints" / "last.pt").exists()
    before = (out / "metrics.jsonl").read_text()
    said = []
    outcome = runs.resume(out, progress=False, results=False, say=said.append)
    assert any("no checkpoint yet" in s and "restarts/1" in s for s in said), said
    assert _same(_weights(base.model), _weights(outcome.model))
    assert (out / "restarts" / "1" / "metrics.jsonl").read_text() == before  # the first attempt's records kept
    assert [json.loads(s)["step"] for s in (out / "metrics.jsonl").read_text().splitlines()][-1] == 8


def test_the_lock_decides_whether_a_run_is_running(tmp_path):
    """On this machine a run is running while a process holds its lock: a live pid in a stale
    status.json (a reused pid) does not keep a run from resuming; a held lock does, named."""
    from ginn.errors import GinnError
    from ginn.train.lock import RunLock, lock_holder
    from ginn.train.rundir import write_status

    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 3}}, sets=OBSTACLE)
    out = runs.train(spec, cfg, tmp_path / "run", progress=False, results=False).run_dir
    assert lock_holder(out) is None
    write_status(out, "running", 2, 1.0)  # this very (live) process, but it holds no lock
    st = read_status(out)
    assert not st.alive() and "no process holds its lock" in st.describe()
    with RunLock(out):
        assert lock_holder(out) == os.getpid()
        assert read_status(out).alive() and "holds its lock" in read_status(out).describe()
        with pytest.raises(GinnError, match=rf"another process writes this run \(pid {os.getpid()} on "):
            runs.resume(out, iterations=5, progress=False)
    status = json.loads((out / "status.json").read_text())
    (out / "status.json").write_text(json.dumps({**status, "pid": 999_999_999}))  # a process long gone
    said = []
    assert runs.resume(out, iterations=5, progress=False, results=False, say=said.append).step == 5
    assert any(s.startswith(f"{out} was not running") for s in said), said


def _resume_in_fork(out: Path, barrier, codes, n: int) -> None:
    with open(out.parent / f"err{n}", "w") as sys.stderr:
        barrier.wait()
        try:
            code = main(["resume", str(out), "--quiet", "--no-results"])
        except BaseException as e:  # noqa: BLE001 - said to the test, which fails on it
            code = f"{type(e).__name__}: {e}"
        codes.put((n, code))


def test_two_resumes_started_together_one_is_refused(tmp_path):
    """Two `ginn resume` of one run started at the same moment: one continues it, the other is
    refused with one line naming the holder, and metrics.jsonl holds every iteration once."""
    import multiprocessing as mp

    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 40, "checkpoint_every": 2}}, sets=OBSTACLE)

    def stop(trainer, step, values):
        if step == 1:
            raise _Kill

    with pytest.raises(_Kill):
        runs.train(spec, cfg, tmp_path / "run", progress=False, results=False, hooks=[stop])
    ctx = mp.get_context("fork")
    barrier, codes = ctx.Barrier(2), ctx.Queue()
    procs = [ctx.Process(target=_resume_in_fork, args=(tmp_path / "run", barrier, codes, n)) for n in (0, 1)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(timeout=300)
    result = dict(codes.get(timeout=30) for _ in procs)
    said = {n: (tmp_path / f"err{n}").read_text() for n in result}
    assert sorted(result.values(), key=str) == [0, 2], (result, said)
    loser = min(result, key=lambda n: -result[n])
    err = (tmp_path / f"err{loser}").read_text().strip().splitlines()
    assert len(err) == 1 and "another process writes this run (pid " in err[0], err
    steps = [json.loads(s)["step"] for s in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()
             if "event" not in json.loads(s)]
    assert steps == list(range(40))
    assert read_status(tmp_path / "run").status == "completed"


def test_a_stale_heartbeat_is_not_running_where_the_lock_cannot_be_read():
    from ginn.train.rundir import Status

    now = time.time()
    here = dict(status="running", pid=os.getpid(), host=socket.gethostname(), heartbeat_every=10.0)
    assert Status(**here, heartbeat=now - 80).alive(now)  # within 3 x 10 + 60 s, pid alive
    alive, why = Status(**here, heartbeat=now - 100).judge(now)
    assert not alive and "stale after 90 s" in why and "another process" in why
    assert not Status(**{**here, "pid": 999_999_999}, heartbeat=now).alive(now)
    elsewhere = dict(here, host="elsewhere-" + socket.gethostname())
    assert Status(**elsewhere, heartbeat=now - 80).alive(now) and not Status(**elsewhere, heartbeat=now - 100).alive(now)


def test_a_completed_run_is_extended_not_retrained(tmp_path, capsys):
    """`ginn resume` of a completed run says so and how to extend it; without its checkpoint it is
    refused with the history left as it was."""
    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 3}}, sets=OBSTACLE)
    out = runs.train(spec, cfg, tmp_path / "run", progress=False, results=False).run_dir
    assert main(["resume", str(out)]) == 2
    err = capsys.readouterr().err
    assert "complete at iteration 3" in err and "--iterations N` with N > 3" in err and err.count("\n") == 1
    (out / "checkpoints" / "last.pt").unlink()
    history = (out / "metrics.jsonl").read_text()
    assert main(["resume", str(out), "--iterations", "5"]) == 2
    err = capsys.readouterr().err
    assert "missing" in err and "nothing to continue from" in err
    assert (out / "metrics.jsonl").read_text() == history and read_status(out).status == "completed"


@pytest.mark.slow
def test_one_run_killed_ten_times_ends_like_the_uninterrupted_one(tmp_path):
    """The same run killed with SIGKILL ten times at random iterations, each time continued by a
    `ginn resume` process, ends with the uninterrupted run's weights (about 2 minutes)."""
    sets = [*OBSTACLE, "training.iterations=120", "training.checkpoint_every=1000", "training.checkpoint_seconds=0.3"]
    spec, cfg = runs.resolve("obstacle", "demo", {"output": {"results": False}}, sets=sets)
    base = Trainer(make_task(spec, cfg), cfg, None, progress=False).train()
    out = tmp_path / "run"
    targets = sorted(random.Random(1).sample(range(5, 115), 10))
    proc = _cli("obstacle", "--preset", "demo", out=out, sets=sets)
    for target in targets:
        while _poll_step(out / "metrics.jsonl") < target and proc.poll() is None:
            time.sleep(0.02)
        assert proc.poll() is None, proc.stderr.read()
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        proc = subprocess.Popen([sys.executable, "-m", "ginn", "resume", str(out), "--quiet"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert proc.wait() == 0, proc.stderr.read()
    ck = load_checkpoint(out / "checkpoints" / "last.pt")
    assert ck["step"] == 120
    model = make_task(spec, cfg).build_model()
    model.load_state_dict(ck["model"])
    assert _same(_weights(base.model), _weights(model))


@pytest.mark.long
@pytest.mark.compile
def test_compiled_kernels_resume_bitwise(tmp_path, capsys):
    """With the compiled SIREN kernels (the default): a ``ginn train`` process killed with SIGKILL
    reads as not running, and continued here ends with the weights of the uninterrupted run here,
    so its first part computed in the other process as it would have here (the kernels' code
    depends only on their shapes, not on what a process ran before)."""
    sets = [o for o in OBSTACLE if not o.startswith("training.compile")]
    sets += ["training.iterations=20", "training.checkpoint_every=1000", "training.checkpoint_seconds=0.2"]
    whole, out = tmp_path / "whole", tmp_path / "killed"
    proc = _cli("obstacle", "--preset", "demo", out=out, sets=sets)
    while _poll_step(out / "metrics.jsonl") < 12 and proc.poll() is None:
        time.sleep(0.02)
    assert proc.poll() is None, proc.stderr.read()
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    # the uninterrupted run after the kill: trained while the other process runs, it could let
    # that process reach its last step before the poll saw step 12
    spec, cfg = runs.resolve("obstacle", "demo", sets=sets)
    runs.train(spec, cfg, whole, progress=False, results=False)
    assert read_status(out).status in ("running", "unknown") and main(["status", str(out)]) == 0
    said = capsys.readouterr().out
    assert "not running" in said or "unknown" in said, said
    assert runs.resume(out, progress=False).status == "completed"
    a, b = (load_checkpoint(d / "checkpoints" / "last.pt") for d in (whole, out))
    assert a["step"] == b["step"] == 20
    assert a["model"].keys() == b["model"].keys() and all(torch.equal(a["model"][k], b["model"][k]) for k in a["model"])
