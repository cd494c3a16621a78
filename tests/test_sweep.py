"""`ginn sweep`: search spaces, objective, pruning, shared budgets of concurrent workers, report."""

import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

optuna = pytest.importorskip("optuna")

from ginn.cli import main  # noqa: E402
from ginn.errors import ConfigError  # noqa: E402
from ginn.sweep import (  # noqa: E402
    MISSING_PENALTY,
    SweepSetup,
    load_space,
    objective_value,
    open_study,
    parse_space,
    run_worker,
)
from ginn.sweep.study import _pruning_hook  # noqa: E402

TINY = ["--set", "latents.n_shapes=2", "--set", "model.hidden=[8,8]", "--set", "sampling.n_domain=64",
        "--set", "sampling.n_outside=32", "--set", "sampling.n_obstacle=16", "--set", "sampling.n_interface=16",
        "--set", "sampling.n_boundary=16", "--set", "losses.connectedness.weight=0", "--set", "training.threads=1"]
SPACE = """
losses.eikonal.weight: {type: float, low: 1.0e-6, high: 1.0e-3, log: true}
model.w0_first: {type: float, low: 0.5, high: 3.0}
training.lr: {type: float, low: 1.0e-4, high: 1.0e-2, log: true}
eval_resolution: 16
"""


def _space(tmp_path, text=SPACE) -> Path:
    p = tmp_path / "space.yaml"
    p.write_text(text)
    return p


# --- search space and objective ----------------------------------------------------------------------


def test_space_parses_flat_and_params_forms():
    s = parse_space({"losses.eikonal.weight": {"type": "float", "low": 1e-6, "high": 1e-3, "log": True},
                     "params": {"model.kind": {"type": "categorical", "choices": ["siren", "resmlp"]}},
                     "objective": {"interface_cd1": 2}, "report_every": 5, "sampler": "random"})
    assert set(s.params) == {"losses.eikonal.weight", "model.kind"}
    assert s.params["losses.eikonal.weight"] == {"type": "float", "low": 1e-6, "high": 1e-3, "log": True}
    assert s.objective == {"interface_cd1": 2.0} and s.report_every == 5 and s.sampler == "random"


@pytest.mark.parametrize("text, msg", [
    ("a.b: {type: float, low: 1}", "needs 'low' and 'high'"),
    ("a.b: {type: gaussian, low: 0, high: 1}", "unknown type"),
    ("a.b: {type: float, low: 0, high: 1, log: true}", "log scale needs low > 0"),
    ("a.b: {type: float, low: 2, high: 1}", "low <= high"),
    ("a.b: {type: categorical, choices: []}", "non-empty list"),
    ("a.b: {type: int, low: 0.5, high: 3}", "int bounds must be integers"),
    ("a.b: {type: float, low: 0, high: 1, mean: 3}", "unknown field 'mean'"),
    ("a.b: 3", "expected a mapping with 'type'"),
    ("objective: {b0: 1}", "no parameters"),
    ("a.b: {type: float, low: 0, high: 1}\nsampler: grid", "sampler must be one of"),
    ("a.b: {type: float, low: 0, high: 1}\nreport_every: 0", "positive integer"),
    ("a.b: [1, 2", "not valid YAML"),
])
def test_bad_space_files_are_one_line_config_errors(tmp_path, text, msg):
    with pytest.raises(ConfigError, match=msg) as e:
        load_space(_space(tmp_path, text))
    assert "\n" not in str(e.value)


def test_cli_bad_space_key_exits_2_with_one_line(tmp_path, capsys):
    sp = _space(tmp_path, "losses.eikonall.weight: {type: float, low: 0, high: 1}\n")
    rc = main(["sweep", "obstacle", "--space", str(sp), "--trials", "1", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert "losses.eikonall.weight" in err and "unknown key" in err
    assert main(["sweep", "obstacle", "--space", str(tmp_path / "missing.yaml")]) == 2
    assert main(["sweep", "--report"]) == 2


def test_objective_is_the_weighted_sum_with_penalties():
    res = {"n_shapes": 3, "shapes": [{"b0": 1}, {"b0": 3}, {"b0": 0}],
           "mean": {"interface_cd1": 0.02, "connected_interfaces_share": 0.75, "surface_strain": None},
           "diversity_mean": 0.3}
    w = {"b0_error": 1.0, "ci_missing": 2.0, "interface_cd1": 10.0, "diversity_mean": -1.0, "surface_strain": 0.5}
    v, used = objective_value(res, w, unit_scale=2.0)
    # |b0-1| mean = (0+2+1)/3 = 1; ci_missing = 0.25; lengths / unit_scale: 0.01, 0.15; strain missing
    assert used["b0_error"] == pytest.approx(1.0) and used["ci_missing"] == pytest.approx(0.25)
    assert v == pytest.approx(1.0 + 0.5 + 0.1 - 0.15 + 0.5 * MISSING_PENALTY)
    single = {"n_shapes": 1, "shapes": [{"b0": 1}], "mean": {"interface_cd1": 0.0}, "diversity_mean": None}
    assert objective_value(single, {"interface_cd1": 1.0, "diversity_mean": -1.0})[0] == 0.0  # diversity n/a


# --- pruning --------------------------------------------------------------------------------------


class _FakeTrial:
    def __init__(self, prune_at):
        self.reports, self.prune_at = [], prune_at

    def report(self, v, step):
        self.reports.append((step, v))

    def should_prune(self):
        return bool(self.reports) and self.reports[-1][0] >= self.prune_at


def test_pruning_hook_reports_every_k_and_honours_should_prune():
    t = _FakeTrial(prune_at=6)
    hook = _pruning_hook(t, None, 3, ["interface", "obstacle"])
    for step in range(5):  # iterations 1..5: reports at 3
        hook(None, step, {"interface": 1.0 + step, "obstacle": 0.5, "eikonal": 100.0})
    assert t.reports == [(3, 3.5)]
    with pytest.raises(optuna.TrialPruned):
        hook(None, 5, {"interface": 2.0, "obstacle": 0.0})
    assert t.reports[-1] == (6, 2.0)


def test_pruned_trial_is_recorded_with_its_run_directory(tmp_path, monkeypatch):
    import ginn.sweep.study as sw
    from ginn.config import config_to_dict, parse_set
    from ginn.problems import load_spec

    monkeypatch.setattr(sw, "_make_pruner", lambda space, iters: optuna.pruners.ThresholdPruner(upper=-1.0))
    spec = load_spec("obstacle")
    base = config_to_dict(spec.config(None, parse_set(TINY[1::2]), {"training": {"iterations": 4}}))
    space = parse_space({"training.lr": {"type": "float", "low": 1e-3, "high": 1e-2}, "report_every": 2})
    setup = SweepSetup(spec, base, space, tmp_path, "p", sw.default_storage(tmp_path), True)
    counts = run_worker(setup, 2, log=lambda m: None)
    assert counts == {"complete": 0, "pruned": 2, "fail": 0}
    trials = open_study(setup.storage, "p", create=False).get_trials()
    assert [t.state.name for t in trials] == ["PRUNED", "PRUNED"]
    for t in trials:
        rd = Path(t.user_attrs["run_dir"])
        st = json.loads((rd / "status.json").read_text())
        assert st["status"] == "pruned" and st["step"] == 2  # pruned at the first report (iteration 2)
        assert list(t.intermediate_values) == [2] and t.intermediate_values[2] > -1.0


# --- concurrent workers ---------------------------------------------------------------------------


def _workers(tmp_path, n_trials, n_workers, storage=None, outs=None):
    space = _space(tmp_path)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    procs = []
    for w in range(n_workers):
        out = outs[w] if outs else tmp_path / "sweep"
        cmd = [sys.executable, "-m", "ginn", "sweep", "obstacle", "--space", str(space), "--trials", str(n_trials),
               "--out", str(out), "--iterations", "1", "--study", "s", "--quiet", *TINY]
        if storage:
            cmd += ["--storage", storage]
        procs.append(subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    for p in procs:
        out, err = p.communicate(timeout=600)
        assert p.returncode == 0, err[-2000:]


def _check_study(storage, n_trials):
    trials = open_study(storage, "s", create=False).get_trials()
    assert len(trials) == n_trials  # none lost, none extra
    assert sorted(t.number for t in trials) == list(range(n_trials))  # none duplicated
    assert all(t.state.name == "COMPLETE" and t.value is not None for t in trials)
    dirs = [Path(t.user_attrs["run_dir"]) for t in trials]
    assert len(set(dirs)) == n_trials
    for d, t in zip(dirs, trials):
        assert json.loads((d / "status.json").read_text())["status"] == "completed"
        assert json.loads((d / "objective.json").read_text())["objective"] == pytest.approx(t.value)
        assert json.loads((d / "trial.json").read_text())["params"] == t.params
    return trials


def _forked_worker(args):
    import torch

    torch.set_num_threads(1)
    os._exit(main(args))


def test_two_forked_sqlite_workers_share_the_budget(tmp_path):
    """Fast variant: two forked processes (torch already imported) run `ginn sweep` on one study."""
    import multiprocessing as mp

    space = _space(tmp_path)
    args = ["sweep", "obstacle", "--space", str(space), "--trials", "3", "--out", str(tmp_path / "sweep"),
            "--iterations", "1", "--study", "s", "--quiet", *TINY]
    ctx = mp.get_context("fork")
    procs = [ctx.Process(target=_forked_worker, args=(args,)) for _ in range(2)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(300)
        assert p.exitcode == 0
    _check_study(f"sqlite:///{tmp_path / 'sweep' / 'study.db'}", 3)


@pytest.mark.slow
def test_two_sqlite_workers_share_the_budget_and_report(tmp_path, capsys):
    _workers(tmp_path, 4, 2)
    out = tmp_path / "sweep"
    trials = _check_study(f"sqlite:///{out / 'study.db'}", 4)
    assert len(list((out / "trials").iterdir())) == 4
    assert main(["sweep", "--report", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    best = min(trials, key=lambda t: t.value)
    assert "4 trials (complete 4)" in text and f"{best.value:.6g}" in text.splitlines()[3]
    assert (out / "objective.png").stat().st_size > 1000


# --- PostgreSQL (slow) ----------------------------------------------------------------------------


def _pg_bin(name):
    p = shutil.which(name)
    if p:
        return p
    for d in sorted(Path("/usr/lib/postgresql").glob("*/bin"), reverse=True):
        if (d / name).exists():
            return str(d / name)
    return None


def _ensure_postgres():
    if _pg_bin("initdb") is None and os.geteuid() == 0 and shutil.which("apt-get"):
        subprocess.run(["apt-get", "install", "-y", "-q", "postgresql"], capture_output=True, timeout=600,
                       env=dict(os.environ, DEBIAN_FRONTEND="noninteractive"))
    if _pg_bin("initdb") is None:
        pytest.skip("PostgreSQL server binaries (initdb, pg_ctl) not found and `apt-get install postgresql` not possible")
    pytest.importorskip("psycopg2", reason="psycopg2 (pip install psycopg2-binary) is needed for the PostgreSQL test")


@pytest.fixture
def postgres_url():
    _ensure_postgres()
    import psycopg2

    base = Path(tempfile.mkdtemp(prefix="ginn-pg-"))
    as_user: list[str] = []
    if os.geteuid() == 0:  # the server refuses to run as root
        import pwd

        try:
            pw = pwd.getpwnam("postgres")
        except KeyError:
            pytest.skip("running as root and there is no 'postgres' user to run the server")
        os.chown(base, pw.pw_uid, pw.pw_gid)
        as_user = ["runuser", "-u", "postgres", "--"]
    data = base / "data"
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    subprocess.run(as_user + [_pg_bin("initdb"), "-D", str(data), "-U", "ginn", "--auth=trust", "-E", "UTF8"],
                   check=True, capture_output=True, timeout=120)
    subprocess.run(as_user + [_pg_bin("pg_ctl"), "-D", str(data), "-w", "-l", str(base / "log"), "-o",
                              f"-p {port} -k {base} -c listen_addresses=127.0.0.1", "start"],
                   check=True, capture_output=True, timeout=120)
    try:
        conn = psycopg2.connect(host="127.0.0.1", port=port, user="ginn", dbname="postgres")
        conn.autocommit = True
        conn.cursor().execute("CREATE DATABASE sweep")
        conn.close()
        yield f"postgresql+psycopg2://ginn@127.0.0.1:{port}/sweep"
    finally:
        subprocess.run(as_user + [_pg_bin("pg_ctl"), "-D", str(data), "-m", "fast", "stop"], capture_output=True, timeout=120)
        shutil.rmtree(base, ignore_errors=True)


@pytest.mark.slow
def test_two_postgres_workers_share_the_budget(tmp_path, postgres_url):
    t0 = time.time()
    # two "machines": separate sweep directories, one study in the database
    _workers(tmp_path, 5, 2, storage=postgres_url, outs=[tmp_path / "a", tmp_path / "b"])
    _check_study(postgres_url, 5)
    n = len(list((tmp_path / "a" / "trials").iterdir())) + len(list((tmp_path / "b" / "trials").iterdir()))
    assert n == 5 and time.time() - t0 < 600
