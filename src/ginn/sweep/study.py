"""Running a sweep: the Optuna study, its storage and lock, the trials of one worker, the report.

See :mod:`ginn.sweep` for the behaviour. Optuna (the optional ``sweep`` extra) is imported inside
the functions that use it, so that ``ginn`` runs without it.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..config import RunConfig, build_config, config_to_dict, nested
from ..errors import ConfigError, GinnError
from ..problems import ProblemSpec
from ..runs import evaluate, train
from ..train.callbacks import StopRun
from ..train.rundir import slug
from .objective import objective_value
from .space import SearchSpace, check_space_keys, suggest

__all__ = ["SweepSetup", "default_storage", "budget_lock", "make_storage", "open_study", "study_names",
           "run_trial", "run_worker", "report", "require_optuna"]


def require_optuna() -> None:
    """Raise a one-line :class:`ConfigError` when Optuna (the ``sweep`` extra) is missing."""
    try:
        import optuna  # noqa: F401
    except ImportError:
        raise ConfigError("ginn sweep needs Optuna: pip install 'ginn[sweep]'") from None


def default_storage(out: Path) -> str:
    return f"sqlite:///{(out / 'study.db').resolve()}"


def _sqlite_target(storage: str) -> str:
    """The database file of an ``sqlite:///`` URL, checked before its lock file is made beside it:
    its folder exists, and the file is new or an SQLite database (else one line, no lock left)."""
    db = Path(storage[len("sqlite:///"):])
    if not db.parent.is_dir():
        raise ConfigError(f"--storage {storage}: the folder {db.parent} does not exist")
    if db.is_dir():
        raise ConfigError(f"--storage {storage}: {db} is a directory, not an SQLite database file")
    if db.is_file() and db.stat().st_size > 0:
        with open(db, "rb") as fh:
            if fh.read(16) != b"SQLite format 3\x00":
                raise ConfigError(f"--storage {storage}: {db} is not an SQLite database")
    return str(db)


@contextlib.contextmanager
def budget_lock(storage: str, study: str):
    """A lock shared by every worker of one study (see the module docstring).

    SQLite: ``flock`` on ``<db>.lock`` (one machine, the only safe place for SQLite anyway);
    PostgreSQL: ``pg_advisory_lock``; MySQL: ``GET_LOCK``; other URLs: no lock (the total may then
    exceed ``--trials`` by up to the number of workers minus one).
    """
    if storage.startswith("sqlite:///"):
        path = Path(_sqlite_target(storage) + ".lock")
        with open(path, "a") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(fh, fcntl.LOCK_UN)
        return
    if storage.startswith(("postgresql", "mysql")):
        import sqlalchemy as sa

        eng = sa.create_engine(storage, poolclass=sa.pool.NullPool)
        key = zlib.crc32(f"ginn-sweep:{study}".encode()) & 0x7FFFFFFF
        pg = storage.startswith("postgresql")
        with eng.connect() as conn:
            if pg:
                conn.execute(sa.text("SELECT pg_advisory_lock(:k)"), {"k": key})
            else:
                conn.execute(sa.text("SELECT GET_LOCK(:k, -1)"), {"k": str(key)})
            try:
                yield
            finally:
                conn.execute(sa.text("SELECT pg_advisory_unlock(:k)" if pg else "SELECT RELEASE_LOCK(:k)"),
                             {"k": key if pg else str(key)})
                conn.commit()
        eng.dispose()
        return
    yield


def make_storage(url: str):
    """An Optuna RDB storage; SQLite with a generous busy timeout for concurrent workers."""
    import optuna

    kw: dict[str, Any] = {}
    if url.startswith("sqlite"):
        kw["engine_kwargs"] = {"connect_args": {"timeout": 120}}
    try:
        return optuna.storages.RDBStorage(url, **kw)
    except ImportError as e:  # a missing database driver (e.g. psycopg2)
        raise ConfigError(f"--storage {url.split('://')[0]}://...: database driver missing ({e}); "
                          "install it, e.g. pip install psycopg2-binary") from None
    except Exception as e:  # noqa: BLE001 - sqlalchemy/optuna raise many kinds; one line for the user
        raise GinnError(f"--storage: cannot open the study storage: {str(e).splitlines()[0][:200]}") from None


def study_names(storage: str) -> list[str]:
    """The names of the studies in ``storage``."""
    import optuna

    return list(optuna.get_all_study_names(make_storage(storage)))


@dataclass
class SweepSetup:
    """Everything a worker needs to run trials."""

    spec: ProblemSpec
    base: dict  # resolved config (dict) before the trial's values
    space: SearchSpace
    out: Path
    study_name: str
    storage: str
    quiet: bool

    @classmethod
    def create(cls, spec: ProblemSpec, cfg: RunConfig, space: SearchSpace, out: str | Path | None = None,
               storage: str | None = None, study: str | None = None, space_path: Path | None = None,
               quiet: bool = False) -> SweepSetup:
        """Check the space against ``cfg``, create the sweep directory (default ``runs/sweep-<problem>``)
        and record ``sweep.json``; the storage defaults to ``OUT/study.db`` (SQLite) and the study
        name to ``sweep-<problem>``."""
        base = config_to_dict(cfg)
        check_space_keys(space, base)
        safe = slug(spec.name)
        out_dir = Path(out) if out else Path("runs") / f"sweep-{safe}"
        out_dir.mkdir(parents=True, exist_ok=True)
        url = storage or default_storage(out_dir)
        name = study or f"sweep-{safe}"
        record = {"study": name, "storage": url if not storage else "(given)", "problem": cfg.problem,
                  "space": str(space_path.resolve()) if space_path else None}
        (out_dir / "sweep.json").write_text(json.dumps(record, indent=2))
        return cls(spec, base, space, out_dir, name, url, quiet)


def _make_sampler(space: SearchSpace):
    import optuna

    if space.sampler == "random":
        return optuna.samplers.RandomSampler(seed=space.seed)
    return optuna.samplers.TPESampler(seed=space.seed)


def _make_pruner(space: SearchSpace, iterations: int):
    import optuna

    if space.pruner == "none":
        return optuna.pruners.NopPruner()
    return optuna.pruners.MedianPruner(n_startup_trials=5, n_warmup_steps=max(0, iterations // 4))


def open_study(storage: str, name: str, space: SearchSpace | None = None, iterations: int = 0, create: bool = True):
    """Create or load the study ``name`` in ``storage``."""
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    st = make_storage(storage)
    if not create:
        try:
            return optuna.load_study(study_name=name, storage=st)
        except KeyError:
            names = ", ".join(optuna.get_all_study_names(st)) or "none"
            raise ConfigError(f"--study {name!r}: no such study in the storage (studies: {names})") from None
    return optuna.create_study(storage=st, study_name=name, sampler=_make_sampler(space),
                               pruner=_make_pruner(space, iterations), direction=space.direction,
                               load_if_exists=True)


def _pruning_hook(trial, space: SearchSpace | None, every: int, terms: list[str] | None = None):
    """Report the intermediate value every ``every`` iterations: the sum of the loss terms ``terms``
    (None: ``space.intermediate``, or else the constraint terms interface, design_region, obstacle
    that the trainer's task has, or else the total); stop the run when the pruner says so, with an
    error that is both the trainer's :class:`StopRun` and Optuna's ``TrialPruned``."""
    import optuna

    class Pruned(StopRun, optuna.TrialPruned):
        pass

    def hook(trainer, step: int, values: dict) -> None:
        done = step + 1
        if done % every:
            return
        names = terms
        if names is None:
            names = list(space.intermediate) if space is not None and space.intermediate else [
                k for k in ("interface", "design_region", "obstacle") if k in trainer.terms] or ["total"]
        v = sum(values.get(k, 0.0) for k in names)
        if math.isfinite(v):
            trial.report(v, done)
        if trial.should_prune():
            raise Pruned("pruned", f"pruned at iteration {done} (intermediate value {v:.4g})")

    return hook


def run_trial(trial, setup: SweepSetup) -> float:
    """Train and evaluate one trial in its own run directory; returns the objective value."""
    import optuna

    values = suggest(trial, setup.space)
    cfg = build_config(setup.base, nested(values))
    run_dir = setup.out / "trials" / f"{setup.study_name}-{trial.number:04d}"
    trial.set_user_attr("run_dir", str(run_dir.resolve()))

    def record(path: Path) -> None:
        (path / "trial.json").write_text(json.dumps({"study": setup.study_name, "number": trial.number, "params": values}, indent=2))

    every = setup.space.report_every or max(1, cfg.training.iterations // 10)
    outcome = train(setup.spec, cfg, run_dir, progress=False, results=False, prepare=record,
                    hooks=[_pruning_hook(trial, setup.space, every)])
    if outcome.status == "pruned":
        raise optuna.TrialPruned(outcome.reason)
    if outcome.status != "completed":  # SIGINT/SIGTERM: the worker stops
        raise KeyboardInterrupt
    metrics = evaluate(run_dir, resolution=setup.space.eval_resolution, device=cfg.device)
    unit = float(getattr(getattr(outcome.task, "problem", None), "unit_scale", 1.0) or 1.0)
    value, used = objective_value(metrics, setup.space.objective, unit)
    trial.set_user_attr("metrics", {k: v for k, v in used.items()})
    (run_dir / "objective.json").write_text(json.dumps({"objective": value, "metrics": used, "weights": setup.space.objective}, indent=2))
    return value


def run_worker(setup: SweepSetup, n_trials: int, log=print) -> dict[str, int]:
    """Run trials of the shared study until it holds ``n_trials`` trials. Returns counts by state."""
    import optuna
    from optuna.trial import TrialState

    iters = int(setup.base.get("training", {}).get("iterations", 0))
    with budget_lock(setup.storage, setup.study_name):
        study = open_study(setup.storage, setup.study_name, setup.space, iters)
    mine = {"complete": 0, "pruned": 0, "fail": 0}
    while True:
        with budget_lock(setup.storage, setup.study_name):
            if len(study.get_trials(deepcopy=False)) >= n_trials:
                break
            trial = study.ask()
        try:
            value = run_trial(trial, setup)
        except optuna.TrialPruned as e:
            study.tell(trial, state=TrialState.PRUNED)
            mine["pruned"] += 1
            log(f"trial {trial.number}: {e}")
            continue
        except KeyboardInterrupt:
            study.tell(trial, state=TrialState.FAIL)
            raise
        except Exception as e:  # noqa: BLE001 - a failed trial must not stop the sweep
            trial.set_user_attr("error", f"{type(e).__name__}: {str(e).splitlines()[0][:300] if str(e) else ''}")
            study.tell(trial, state=TrialState.FAIL)
            mine["fail"] += 1
            log(f"trial {trial.number}: failed ({type(e).__name__}: {str(e)[:200]})")
            continue
        study.tell(trial, value)
        mine["complete"] += 1
        log(f"trial {trial.number}: objective {value:.6g}  {trial.params}")
    return mine


def report(study, out_png: Path | None, top: int = 10) -> str:
    """A text table of the best trials (and a PNG of the objective over trials at ``out_png``)."""
    from optuna.trial import TrialState

    trials = study.get_trials(deepcopy=False)
    done = [t for t in trials if t.state == TrialState.COMPLETE and t.value is not None]
    maximize = study.direction.name == "MAXIMIZE"
    done.sort(key=lambda t: t.value, reverse=maximize)
    counts = {s.name.lower(): sum(t.state == s for t in trials) for s in TrialState}
    lines = [f"study {study.study_name}: {len(trials)} trials (" + ", ".join(f"{k} {v}" for k, v in counts.items() if v) + ")"]
    if done:
        lines.append(f"best {min(top, len(done))} ({'max' if maximize else 'min'}imised objective):")
        lines.append(f"{'trial':>6}  {'objective':>12}  params  [run directory]")
        for t in done[:top]:
            params = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in t.params.items())
            lines.append(f"{t.number:>6}  {t.value:>12.6g}  {params}  [{t.user_attrs.get('run_dir', '-')}]")
    else:
        lines.append("no completed trials yet")
    if out_png is not None and done:
        _plot(trials, out_png, maximize)
        lines.append(f"plot: {out_png}")
    return "\n".join(lines)


def _plot(trials, path: Path, maximize: bool) -> None:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure
    from optuna.trial import TrialState

    done = sorted((t for t in trials if t.state == TrialState.COMPLETE and t.value is not None), key=lambda t: t.number)
    pruned = [t for t in trials if t.state == TrialState.PRUNED]
    fig = Figure(figsize=(6.4, 4.0), dpi=120)
    ax = fig.add_subplot()
    xs, ys = [t.number for t in done], [t.value for t in done]
    ax.scatter(xs, ys, s=14, label="completed")
    best, cur = [], None
    for y in ys:
        cur = y if cur is None else (max(cur, y) if maximize else min(cur, y))
        best.append(cur)
    ax.step(xs, best, where="post", color="C1", label="best so far")
    if pruned:
        ax.scatter([t.number for t in pruned], [min(ys)] * len(pruned), marker="x", s=14, color="0.6", label="pruned")
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("trial")
    ax.set_ylabel("objective")
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
