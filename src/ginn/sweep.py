"""Hyperparameter sweeps with Optuna: ``ginn sweep PROBLEM --space SPACE.yaml --trials N``.

Every trial is a normal run directory (``OUT/trials/<study>-<number>``: config.yaml, metrics.jsonl,
checkpoint, metrics.json from ``ginn eval``), trained with the generic trainer from the problem's
config plus ``--preset``/``--set`` plus the trial's sampled values. The objective is computed from
the ``ginn eval`` metrics (:func:`ginn.evaluate_run.evaluate_run_dir`); intermediate values for
pruning are reported every ``report_every`` iterations by a trainer hook.

The search space file (YAML) maps dotted config keys to distributions, plus a few options::

    losses.eikonal.weight: {type: float, low: 1.0e-6, high: 1.0e-3, log: true}
    model.w0_first:        {type: float, low: 0.5, high: 3.0}
    training.lr:           {type: float, low: 1.0e-4, high: 1.0e-2, log: true}
    model.kind:            {type: categorical, choices: [siren, resmlp]}
    sampling.n_boundary:   {type: int, low: 64, high: 512, step: 64}
    objective: {interface_cd1: 10.0, b0_error: 1.0}   # optional (default: DEFAULT_OBJECTIVE)
    direction: minimize            # optional
    sampler: tpe                   # tpe (default) | random
    pruner: median                 # median (default) | none
    report_every: 50               # iterations between intermediate values (default iterations / 10)
    intermediate: [interface, design_region, obstacle]   # unweighted loss terms summed for pruning
    eval_resolution: 128           # grid resolution of the evaluation (default: ginn eval's)
    seed: 0                        # sampler seed (default: none, so parallel workers differ)

Parameters may also be listed under a ``params:`` mapping.

Objective: ``sum_k w_k * m_k`` over the metrics ``m_k`` named in ``objective``, minimised. Names
are the metrics of ``ginn eval`` (means over shapes: ``b0``, ``interface_cd1``,
``connected_interfaces_share``, ..., and ``diversity_mean``; for other task kinds, any numeric
top-level field of metrics.json) and two derived ones: ``b0_error`` = mean over shapes of
``|b0 - 1|`` (one connected component wanted) and ``ci_missing`` = ``1 - connected_interfaces_share``.
Length metrics (``interface_cd1``, ``diversity_mean``) are divided by the problem's ``unit_scale``.
The default (:data:`DEFAULT_OBJECTIVE`) is ``b0_error + ci_missing + 10 interface_cd1 - diversity_mean``
(the diversity term only for generative models). A metric that is missing or not finite (e.g. an
empty shape) adds ``|w| * MISSING_PENALTY``.

Budget: ``--trials N`` is the study's total number of trials, shared by every worker: a worker
takes the storage's lock (a file lock next to an SQLite file, an advisory lock on PostgreSQL),
counts the trials and creates the next one only if fewer than N exist, so N trials run in total
however many workers there are. Storage: an SQLite file ``OUT/study.db`` by default; a
``postgresql://`` URL lets workers on many machines share one study.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import sys
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from .errors import ConfigError, GinnError

DEFAULT_OBJECTIVE: dict[str, float] = {"b0_error": 1.0, "ci_missing": 1.0, "interface_cd1": 10.0, "diversity_mean": -1.0}
MISSING_PENALTY = 100.0
_LENGTH_METRICS = {"interface_cd1", "diversity_mean"}
_OPTIONS = {"objective", "direction", "sampler", "pruner", "report_every", "intermediate", "eval_resolution", "seed", "params"}
_DIST_KEYS = {"float": {"type", "low", "high", "log", "step"}, "int": {"type", "low", "high", "log", "step"},
              "categorical": {"type", "choices"}}


# --- the search space ------------------------------------------------------------------------------


@dataclass(frozen=True)
class SearchSpace:
    """A parsed search space file.

    Attributes:
        params: dotted config key -> distribution dict (``type`` float/int/categorical, ...).
        objective: metric name -> weight (minimised sum).
        direction, sampler, pruner: Optuna settings.
        report_every: iterations between intermediate values (None: iterations / 10).
        intermediate: unweighted loss terms summed as the intermediate value (None: the
            constraint terms interface, design_region, obstacle that the task has).
        eval_resolution: evaluation grid resolution (None: ``ginn eval``'s default).
        seed: sampler seed or None.
    """

    params: dict[str, dict]
    objective: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_OBJECTIVE))
    direction: str = "minimize"
    sampler: str = "tpe"
    pruner: str = "median"
    report_every: int | None = None
    intermediate: tuple[str, ...] | None = None
    eval_resolution: int | None = None
    seed: int | None = None


def _check_dist(key: str, d: Any) -> dict:
    where = f"search space {key!r}"
    if not isinstance(d, dict) or "type" not in d:
        raise ConfigError(f"{where}: expected a mapping with 'type' (float, int or categorical)")
    kind = d["type"]
    if kind not in _DIST_KEYS:
        raise ConfigError(f"{where}: unknown type {kind!r} (float, int, categorical)")
    extra = set(d) - _DIST_KEYS[kind]
    if extra:
        raise ConfigError(f"{where}: unknown field {sorted(extra)[0]!r} for type {kind}")
    if kind == "categorical":
        ch = d.get("choices")
        if not isinstance(ch, list) or not ch:
            raise ConfigError(f"{where}: 'choices' must be a non-empty list")
        return {"type": kind, "choices": ch}
    if "low" not in d or "high" not in d:
        raise ConfigError(f"{where}: {kind} needs 'low' and 'high'")
    num = int if kind == "int" else float
    try:
        low, high = num(d["low"]), num(d["high"])
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: 'low' and 'high' must be numbers") from None
    if kind == "int" and (low != d["low"] or high != d["high"]):
        raise ConfigError(f"{where}: int bounds must be integers")
    if not (math.isfinite(low) and math.isfinite(high)) or low > high:
        raise ConfigError(f"{where}: need finite low <= high (got {d['low']}, {d['high']})")
    log = d.get("log", False)
    if not isinstance(log, bool):
        raise ConfigError(f"{where}: 'log' must be true or false")
    if log and low <= 0:
        raise ConfigError(f"{where}: log scale needs low > 0")
    out = {"type": kind, "low": low, "high": high, "log": log}
    if "step" in d:
        if log:
            raise ConfigError(f"{where}: 'step' and 'log' cannot be combined")
        try:
            step = num(d["step"])
        except (TypeError, ValueError):
            raise ConfigError(f"{where}: 'step' must be a number") from None
        if step <= 0:
            raise ConfigError(f"{where}: 'step' must be > 0")
        out["step"] = step
    return out


def parse_space(data: Any, source: str = "search space") -> SearchSpace:
    """Validate a search space mapping (see the module docstring). Raises :class:`ConfigError`."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping of config keys to distributions")
    raw = dict(data.get("params") or {})
    if not isinstance(raw, dict):
        raise ConfigError(f"{source}: 'params' must be a mapping")
    raw.update({k: v for k, v in data.items() if k not in _OPTIONS})
    params = {str(k): _check_dist(str(k), v) for k, v in raw.items()}
    if not params:
        raise ConfigError(f"{source}: no parameters to search")
    kw: dict[str, Any] = {}
    if "objective" in data:
        obj = data["objective"]
        if not isinstance(obj, dict) or not obj:
            raise ConfigError(f"{source}: 'objective' must map metric names to weights")
        try:
            kw["objective"] = {str(k): float(v) for k, v in obj.items()}
        except (TypeError, ValueError):
            raise ConfigError(f"{source}: objective weights must be numbers") from None
    for name, choices in (("direction", ("minimize", "maximize")), ("sampler", ("tpe", "random")), ("pruner", ("median", "none"))):
        if name in data:
            if data[name] not in choices:
                raise ConfigError(f"{source}: {name} must be one of {', '.join(choices)} (got {data[name]!r})")
            kw[name] = data[name]
    for name in ("report_every", "eval_resolution", "seed"):
        if name in data:
            v = data[name]
            if not isinstance(v, int) or isinstance(v, bool) or (v < 1 and name != "seed"):
                raise ConfigError(f"{source}: {name} must be a positive integer")
            kw[name] = v
    if "intermediate" in data:
        v = data["intermediate"]
        v = [v] if isinstance(v, str) else v
        if not isinstance(v, list) or not v or not all(isinstance(x, str) for x in v):
            raise ConfigError(f"{source}: 'intermediate' must be a loss term name or a list of them")
        kw["intermediate"] = tuple(v)
    return SearchSpace(params=params, **kw)


def load_space(path: str | Path) -> SearchSpace:
    """Read and validate a search space YAML file. Raises :class:`ConfigError` (one line)."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"--space {p}: no such file")
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as e:
        line = getattr(getattr(e, "problem_mark", None), "line", None)
        raise ConfigError(f"--space {p}: not valid YAML" + (f" (line {line + 1})" if line is not None else "")) from None
    return parse_space(data, f"--space {p}")


def nested(flat: dict[str, Any]) -> dict:
    """``{"a.b": 1}`` -> ``{"a": {"b": 1}}``."""
    out: dict = {}
    for key, val in flat.items():
        node = out
        parts = key.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = val
    return out


def check_space_keys(space: SearchSpace, base: dict) -> None:
    """Every parameter must be a valid config key at its bounds/choices (one-line ConfigError)."""
    from .train.config import build_config

    for key, d in space.params.items():
        values = d["choices"] if d["type"] == "categorical" else [d["low"], d["high"]]
        for v in values:
            try:
                build_config(base, nested({key: v}))
            except ConfigError as e:
                raise ConfigError(f"search space {key!r} = {v!r}: {e}") from None


def suggest(trial, space: SearchSpace) -> dict[str, Any]:
    """Sample every parameter of ``space`` for an Optuna ``trial``: dotted key -> value."""
    out: dict[str, Any] = {}
    for key, d in space.params.items():
        if d["type"] == "categorical":
            out[key] = trial.suggest_categorical(key, d["choices"])
        elif d["type"] == "int":
            out[key] = trial.suggest_int(key, d["low"], d["high"], step=d.get("step", 1), log=d["log"])
        else:
            out[key] = trial.suggest_float(key, d["low"], d["high"], step=d.get("step"), log=d["log"])
    return out


# --- the objective ---------------------------------------------------------------------------------


def metric_value(result: dict, name: str, unit_scale: float = 1.0) -> float | None:
    """One named metric of a ``ginn eval`` result (see the module docstring), or None if missing."""
    mean = result.get("mean") or {}
    if name == "b0_error":
        vals = [s.get("b0") for s in result.get("shapes", [])]
        if not vals or any(v is None for v in vals):
            return None
        return float(sum(abs(float(v) - 1.0) for v in vals) / len(vals))
    if name == "ci_missing":
        v = mean.get("connected_interfaces_share")
        return None if v is None else 1.0 - float(v)
    v = mean.get(name, result.get(name))
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    v = float(v)
    return v / unit_scale if name in _LENGTH_METRICS else v


def objective_value(result: dict, weights: dict[str, float], unit_scale: float = 1.0) -> tuple[float, dict[str, float | None]]:
    """``sum_k w_k m_k`` (missing or non-finite: ``|w_k| * MISSING_PENALTY``) and the metrics used.

    ``diversity_mean`` is skipped for a single-shape result (it does not apply).
    """
    total, used = 0.0, {}
    for name, w in weights.items():
        if name == "diversity_mean" and result.get("n_shapes", 2) < 2:
            continue
        v = metric_value(result, name, unit_scale)
        used[name] = v
        total += abs(w) * MISSING_PENALTY if v is None or not math.isfinite(v) else w * v
    return total, used


# --- storage, locking ------------------------------------------------------------------------------


def default_storage(out: Path) -> str:
    return f"sqlite:///{(out / 'study.db').resolve()}"


@contextlib.contextmanager
def budget_lock(storage: str, study: str):
    """A lock shared by every worker of one study (see the module docstring).

    SQLite: ``flock`` on ``<db>.lock`` (one machine, the only safe place for SQLite anyway);
    PostgreSQL: ``pg_advisory_lock``; MySQL: ``GET_LOCK``; other URLs: no lock (the total may then
    exceed ``--trials`` by up to the number of workers minus one).
    """
    if storage.startswith("sqlite:///"):
        path = Path(storage[len("sqlite:///"):] + ".lock")
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


# --- one worker ------------------------------------------------------------------------------------


@dataclass
class SweepSetup:
    """Everything a worker needs to run trials."""

    spec: Any
    spec_path: Path | None
    base: dict  # resolved config (dict) before the trial's values
    space: SearchSpace
    out: Path
    study_name: str
    storage: str
    device: str | None
    quiet: bool


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


def _pruning_hook(trial, space: SearchSpace, every: int, terms: list[str]):
    import optuna

    def hook(trainer, step: int, values: dict) -> None:
        done = step + 1
        if done % every:
            return
        v = sum(values.get(k, 0.0) for k in terms)
        if math.isfinite(v):
            trial.report(v, done)
        if trial.should_prune():
            raise optuna.TrialPruned(f"pruned at iteration {done} (intermediate value {v:.4g})")

    return hook


def run_trial(trial, setup: SweepSetup) -> float:
    """Train and evaluate one trial in its own run directory; returns the objective value."""
    import optuna

    from .evaluate_run import evaluate_run_dir
    from .train.config import build_config
    from .train.registry import make_task
    from .train.run import new_run_dir, write_run_files, write_status
    from .train.trainer import Trainer

    values = suggest(trial, setup.space)
    cfg = build_config(setup.base, nested(values))
    run_dir = new_run_dir(setup.spec.name, setup.out / "trials" / f"{setup.study_name}-{trial.number:04d}")
    trial.set_user_attr("run_dir", str(run_dir.resolve()))
    write_run_files(run_dir, cfg, setup.spec_path)
    (run_dir / "trial.json").write_text(json.dumps({"study": setup.study_name, "number": trial.number, "params": values}, indent=2))
    task = make_task(setup.spec, cfg)
    iters = cfg.training.iterations
    every = setup.space.report_every or max(1, iters // 10)
    terms = list(setup.space.intermediate) if setup.space.intermediate else [
        k for k in ("interface", "design_region", "obstacle") if k in task.terms()] or ["total"]
    trainer = Trainer(task, cfg, run_dir, progress=False, hooks=[_pruning_hook(trial, setup.space, every, terms)])
    write_status(run_dir, "running", 0, 0.0)
    try:
        res = trainer.train()
    except optuna.TrialPruned:
        trainer.save()
        write_status(run_dir, "pruned", trainer.step, trainer.elapsed)
        raise
    write_status(run_dir, res.status, res.step, res.seconds)
    if res.status != "completed":  # SIGINT/SIGTERM: the worker stops
        raise KeyboardInterrupt
    metrics = evaluate_run_dir(run_dir, resolution=setup.space.eval_resolution, device=cfg.device)
    metrics.pop("_text", None)
    unit = float(getattr(getattr(task, "problem", None), "unit_scale", 1.0) or 1.0)
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


# --- the report ------------------------------------------------------------------------------------


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


# --- the CLI entry ---------------------------------------------------------------------------------


def _sweep_json(out: Path) -> dict:
    p = out / "sweep.json"
    return json.loads(p.read_text()) if p.is_file() else {}


def run_sweep_cli(args) -> int:
    """``ginn sweep`` (see :mod:`ginn.sweep_cli` for the flags)."""
    try:
        import optuna  # noqa: F401
    except ImportError:
        raise ConfigError("ginn sweep needs Optuna: pip install 'ginn[sweep]'") from None
    if args.report:
        return _report_cli(args)
    if not args.problem:
        raise ConfigError("usage: ginn sweep PROBLEM|SPEC.yaml --space SPACE.yaml --trials N (or ginn sweep --report)")
    if not args.space:
        raise ConfigError("ginn sweep: --space SPACE.yaml is required")
    if args.trials is None or args.trials < 1:
        raise ConfigError("--trials must be >= 1")
    from .problems import load_spec
    from .train.config import config_to_dict, parse_set
    from .train.registry import resolve_config

    space = load_space(args.space)
    spec = load_spec(args.problem)
    over: dict = {"problem": str(Path(args.problem).resolve()) if Path(args.problem).suffix in (".yaml", ".yml") else spec.name}
    if args.device is not None:
        over["device"] = args.device
    if getattr(args, "iterations", None) is not None:
        over["training"] = {"iterations": args.iterations}
    if getattr(args, "seed", None) is not None:
        over["seed"] = args.seed
    base = config_to_dict(resolve_config(spec, args.preset, over, parse_set(args.sets)))
    check_space_keys(space, base)
    safe = "".join(c if c.isalnum() or c in "-_" else "-" for c in spec.name)
    out = Path(args.out) if args.out else Path("runs") / f"sweep-{safe}"
    out.mkdir(parents=True, exist_ok=True)
    storage = args.storage or default_storage(out)
    study = args.study or f"sweep-{safe}"
    (out / "sweep.json").write_text(json.dumps({"study": study, "storage": storage if not args.storage else "(given)",
                                                "problem": over["problem"], "space": str(Path(args.space).resolve())}, indent=2))
    spec_path = Path(spec.source) if Path(spec.source).is_file() else None
    setup = SweepSetup(spec, spec_path, base, space, out, study, storage, args.device, args.quiet)
    log = (lambda *a: None) if args.quiet else (lambda msg: print(msg, flush=True))
    log(f"sweep {study}: {args.trials} trials in total, storage {storage.split('://')[0]}, trials in {out / 'trials'}")
    counts = run_worker(setup, args.trials, log)
    log(f"this worker: {counts['complete']} completed, {counts['pruned']} pruned, {counts['fail']} failed")
    if not args.quiet:
        print(report(open_study(storage, study, create=False), out / "objective.png"))
    return 0


def _report_cli(args) -> int:
    if args.storage:
        storage = args.storage
        study = args.study
        out = Path(args.out) if args.out else None
        if not study:
            import optuna

            names = optuna.get_all_study_names(make_storage(storage))
            if len(names) != 1:
                raise ConfigError("--report with --storage: name the study with --study (studies: " + (", ".join(names) or "none") + ")")
            study = names[0]
    else:
        if not args.out:
            raise ConfigError("--report needs --out SWEEP_DIR or --storage URL --study NAME")
        out = Path(args.out)
        if not (out / "study.db").is_file():
            raise ConfigError(f"--out {out}: no study.db (not a sweep directory)")
        storage = default_storage(out)
        study = args.study or _sweep_json(out).get("study")
        if not study:
            raise ConfigError(f"--out {out}: no sweep.json; name the study with --study")
    st = open_study(storage, study, create=False)
    png = out / "objective.png" if out is not None else Path(f"objective-{study}.png")
    sys.stdout.write(report(st, png) + "\n")
    return 0
