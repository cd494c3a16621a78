"""A run from start to finish: train, resume, load, evaluate, export and plot a run directory.

The one workflow behind the CLI (``ginn train``, ``resume``, ``eval``, ``export``, ``plot``), the
Python front door (:func:`fit`, :func:`evaluate`) and every sweep trial::

    spec, cfg = resolve("obstacle", "demo", {"training": {"iterations": 200}})   # spec -> config
    outcome = train(spec, cfg)                          # task -> run directory -> trainer -> results
    run = load_run(outcome.run_dir)                     # the trained model back from the checkpoint
    metrics = evaluate(outcome.run_dir)                 # what `ginn eval` writes to metrics.json

Kind-specific work (what to evaluate, export, draw or show) is the task's
(:class:`ginn.train.task.Results`); nothing here switches on the problem kind.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import torch
from torch import Tensor, nn

from .config import RunConfig, build_config, deep_merge, parse_set, with_overrides
from .errors import ConfigError, GinnError
from .problems import ProblemSpec, load_spec
from .problems.record import INPUTS, record_spec
from .tasks import make_task
from .tasks.shape.results import VERDICTS_FILE
from .train.checkpoint import load_checkpoint, load_weights
from .train.distributed import DistContext, on_main
from .train.lock import RunLock
from .train.memory import check_memory
from .train.rundir import (
    RUN_RECORDS,
    Status,
    io_error,
    new_run_dir,
    read_config_dict,
    read_status,
    set_aside,
    write_run_files,
    write_status,
)
from .train.task import Task
from .train.trainer import Trainer

__all__ = [
    "Run", "Outcome", "is_spec_file", "resolve", "train", "resume", "fit", "load_run",
    "evaluate", "export", "plot", "check_device", "device_here",
]

Say = Callable[[str], None]


def _silent(msg: str) -> None:
    pass


def is_spec_file(problem: str | Path) -> bool:
    """Whether ``problem`` names a spec file (``.yaml``/``.yml``) rather than a built-in problem."""
    return Path(str(problem)).suffix in (".yaml", ".yml")


def resolve(problem: str | Path, preset: str | None = None, *overrides: dict,
            sets: list[str] | None = None) -> tuple[ProblemSpec, RunConfig]:
    """The spec of ``problem`` (a built-in name or a spec file) and its run configuration: the spec's
    defaults, the preset, each override dict, then ``sets`` (``["key=value", ...]``).

    ``problem`` in the config is the built-in name, or the spec file's absolute path, so that the
    run directory can rebuild the problem.
    """
    spec = load_spec(problem)
    head = {"problem": str(Path(problem).resolve()) if is_spec_file(problem) else spec.name}
    return spec, spec.config(preset, head, *overrides, parse_set(sets or []))


@dataclass
class Outcome:
    """How a training (or resumed training) ended.

    Attributes:
        status: ``completed``, ``interrupted`` (SIGINT/SIGTERM; a checkpoint was written) or the
            status of a hook that stopped the run (e.g. ``pruned``).
        step, seconds: where it stopped and the training time.
        run_dir: the run directory.
        task, model: the trained task and model.
        results: the result files written at the end (empty without results or when not completed).
        reason: why a hook stopped the run.
    """

    status: str
    step: int
    seconds: float
    run_dir: Path
    task: Task
    model: nn.Module
    results: list[Path] = field(default_factory=list)
    reason: str = ""


def device_here(device: str) -> str:
    """``device`` where this machine has it, else ``cpu``: a run trained on a GPU opens for reading
    on a machine without one."""
    return "cpu" if device.startswith("cuda") and not torch.cuda.is_available() else device


def check_device(device: str, where: str = "device") -> None:
    """Raise a one-line :class:`ConfigError` naming ``where`` unless this machine has ``device``."""
    if not device.startswith("cuda"):
        return
    if not torch.cuda.is_available():
        raise ConfigError(f"{where} {device}: CUDA is not available on this machine")
    index = int(device.partition(":")[2] or 0)
    if index >= torch.cuda.device_count():
        raise ConfigError(f"{where} {device}: this machine has {torch.cuda.device_count()} CUDA device(s)")


def _finish(trainer: Trainer, task: Task, run_dir: Path, results: bool, say: Say) -> Outcome:
    """Train to the end (the trainer keeps ``status.json`` true) and write the result files."""
    try:
        return _finish_run(trainer, task, run_dir, results, say)
    finally:
        trainer.close()


def _finish_run(trainer: Trainer, task: Task, run_dir: Path, results: bool, say: Say) -> Outcome:
    res = trainer.train()
    out = Outcome(res.status, res.step, res.seconds, run_dir, task, trainer.model, reason=res.reason)
    if not trainer.is_main or res.status != "completed":  # ranks > 0 write nothing; interrupted or stopped
        return out
    say(f"trained {res.step} iterations in {res.seconds:.1f} s" + (f" ({res.reason})" if res.reason else ""))
    for cb in trainer.callbacks:
        for line in cb.report():
            say(line)
    if results:
        try:
            out.results = task.results.finalize(trainer.model, run_dir)
        except OSError as e:
            write_status(run_dir, "failed", res.step, res.seconds, f"writing the results: {e.strerror}")
            raise io_error(e, e.filename or run_dir) from None
        trainer.log_figures(out.results)
        write_status(run_dir, "completed", res.step, res.seconds)
        if out.results:
            say("results:")
            for p in out.results:
                say(f"  {p}")
    say(f"run directory: {run_dir}")
    return out


def train(
    spec: ProblemSpec,
    cfg: RunConfig,
    out: str | Path | None = None,
    *,
    progress: bool = True,
    results: bool | None = None,
    hooks: list[Callable] | None = None,
    dist: DistContext | None = None,
    say: Say = _silent,
    prepare: Callable[[Path], None] | None = None,
) -> Outcome:
    """Train ``spec`` under ``cfg`` into a new run directory.

    Arguments:
        spec, cfg: the problem and its resolved configuration (:func:`resolve`).
        out: the run directory (must be new or empty; default ``runs/<problem>-<timestamp>``).
        progress: show a progress bar.
        results: write the task's result files (shapes, figures) at the end (None:
            ``cfg.output.results``; False is recorded in the config, so a resume honours it).
        hooks: ``hook(trainer, step, losses)`` after every step; a hook may raise
            :class:`ginn.train.callbacks.StopRun` to end the run with its status.
        dist: the torchrun context (None: one process); only rank 0 writes.
        say: where progress messages go (the CLI prints them).
        prepare: called with the run directory after its files are written, before training.
    """
    if results is not None and results != cfg.output.results:
        cfg = with_overrides(cfg, {"output": {"results": results}})
    if dist is None:
        check_device(cfg.device)
    check_memory(dist.localize(cfg) if dist is not None else cfg)
    task = make_task(spec, dist.localize(cfg) if dist is not None else cfg)
    locks: list[RunLock] = []  # rank 0 writes, and holds the run's lock from its creation to the end

    def create() -> Path:
        run_dir, lock = new_run_dir(spec.name, out)
        locks.append(lock)
        return run_dir

    run_dir = on_main(dist, create)
    try:
        main = dist is None or dist.is_main
        if main:
            rec = record_spec(spec)
            write_run_files(run_dir, cfg, rec.source, notes=spec.derived_notes(cfg), spec_text=rec.text,
                            inputs={f"{INPUTS}/{name}": src for name, src in rec.inputs.items()})
            if prepare is not None:
                prepare(run_dir)
        where = cfg.device if dist is None else f"{dist.world} x {dist.device} ({dist.backend})"
        (say if main else _silent)(
            f"training {spec.name}" + (f" (preset {cfg.preset})" if cfg.preset else "") + f" on {where}; run directory {run_dir}")
        trainer = Trainer(task, task.cfg, run_dir, progress=progress, hooks=hooks, dist=dist)
        return _finish(trainer, task, run_dir, cfg.output.results, say if main else _silent)
    finally:
        for lock in locks:
            lock.release()


def _run_config(run_dir: Path, spec: ProblemSpec | None = None) -> tuple[ProblemSpec, RunConfig]:
    """The spec and config of a run directory (a config without ``params.kind`` takes the spec's)."""
    raw = read_config_dict(run_dir)
    if spec is None:
        spec = _recorded_spec(Path(run_dir), str(raw.get("problem", "")))
    params = raw.get("params")
    if not isinstance(params, dict) or "kind" not in params:
        raw = deep_merge(raw, {"params": {"kind": spec.kind}})
    try:
        return spec, spec.check_kind(build_config(raw))
    except ConfigError as e:
        raise ConfigError(f"{Path(run_dir) / 'config.yaml'}: {e}") from None


def _recorded_spec(run_dir: Path, original: str) -> ProblemSpec:
    """The spec a run trained, from the run's own copy ``problem.yaml`` (and the files of
    ``inputs/`` it names) only: a run never reads its problem from outside its directory."""
    copy = run_dir / "problem.yaml"
    if not copy.is_file():
        raise GinnError(f"{copy}: missing; a run rebuilds its problem ({original or 'unknown'}) from its own copy only")
    return load_spec(copy)


def resume(
    run_dir: str | Path,
    iterations: int | None = None,
    *,
    progress: bool = True,
    results: bool | None = None,
    dist: DistContext | None = None,
    say: Say = _silent,
    device: str | None = None,
) -> Outcome:
    """Continue a run from its last checkpoint (up to ``iterations`` in total if given; on
    ``device`` if given, else on the device it was trained on).

    The run's lock is taken before anything is read (one line naming the holder if another process
    writes the run). A completed run is continued only to a larger ``iterations``; a run that never
    reached a checkpoint restarts from its saved config, its earlier ``metrics.jsonl`` and
    ``status.json`` moved aside to ``restarts/<n>/`` (and says so). ``results`` None: as the run
    was started (``output.results`` of its config).

    Raises:
        GinnError: another process writes the run (or, seen from another machine, its heartbeat is
            fresh); the run is complete and ``iterations`` is not beyond it; ``iterations`` is not
            beyond its current step; a completed run has lost its checkpoint.
    """
    run_dir = Path(run_dir)
    read_config_dict(run_dir)  # one line if it is not a run directory
    lock = RunLock(run_dir)

    def claim() -> Status:
        lock.acquire()
        state = read_status(run_dir)
        alive, why = state.judge()
        if alive and state.host != socket.gethostname():  # on this machine the lock is the truth
            raise GinnError(f"{run_dir}: the run is still {state.describe()}; stop it before resuming")
        if state.status == "completed" and (iterations is None or iterations <= state.step):
            raise GinnError(f"{run_dir}: the run is complete at iteration {state.step}; "
                            f"`ginn resume {run_dir} --iterations N` with N > {state.step} trains it further")
        return state

    try:
        state = on_main(dist, claim)  # decided once, on rank 0 (the others would see its new status)
        return _resume_locked(run_dir, state, iterations, progress, results, dist, say, device)
    finally:
        lock.release()


def _resume_locked(run_dir: Path, state: Status, iterations: int | None, progress: bool, results: bool | None,
                   dist: DistContext | None, say: Say, device: str | None) -> Outcome:
    main = dist is None or dist.is_main
    if state.status == "running" and main:
        say(f"{run_dir} was {state.describe().split(';')[0]}")
    spec, cfg = _run_config(run_dir)
    if iterations is not None:
        cfg = with_overrides(cfg, {"training": {"iterations": iterations}})
    if device is not None:
        cfg = with_overrides(cfg, {"device": device})
    elif dist is None and device_here(cfg.device) != cfg.device:
        raise ConfigError(f"{run_dir}: the run trains on {cfg.device}, which this machine does not have; "
                          f"`ginn resume {run_dir} --device cpu` continues it on the CPU")
    if dist is None:
        check_device(cfg.device, "--device")
    cfg = dist.localize(cfg) if dist is not None else cfg
    check_memory(cfg)
    task = make_task(spec, cfg)
    trainer = Trainer(task, cfg, run_dir, progress=progress, dist=dist)
    main_say = say if trainer.is_main else _silent
    if trainer.resume():
        if iterations is not None and iterations <= trainer.step:
            raise GinnError(f"--iterations {iterations}: the run is already at iteration {trainer.step}; "
                            "give a larger total")
        main_say(f"resuming {run_dir} at iteration {trainer.step} of {cfg.training.iterations}")
    elif state.status == "completed":
        raise GinnError(f"{run_dir}: the run completed {state.step} iterations but {trainer.checkpoint_path} is missing; "
                        "there is nothing to continue from (its files are left as they are)")
    else:
        if trainer.is_main:
            kept = set_aside(run_dir, ("metrics.jsonl", "status.json"))
            main_say(f"{run_dir} has no checkpoint yet: restarting it from its config.yaml"
                     + (f" (its earlier records moved to {kept})" if kept else ""))
    return _finish(trainer, task, run_dir, cfg.output.results if results is None else results, main_say)


@dataclass
class Run:
    """A loaded run: its config, problem spec, task and trained model (from the last checkpoint)."""

    path: Path
    config: RunConfig
    spec: ProblemSpec
    task: Task
    model: nn.Module
    step: int

    @property
    def latents(self) -> Tensor | None:
        """The trained latent codes ``(S, k)``, or None for a single shape."""
        return self.task.latents()


def load_run(run_dir: str | Path, device: str | None = None) -> Run:
    """Rebuild the task and model of a run directory and load the last checkpoint's weights, on
    ``device`` (default: the run's own where this machine has it, else the CPU)."""
    run_dir = Path(run_dir)
    spec, cfg = _run_config(run_dir)
    if device is not None:
        check_device(device, "--device")
    device = device or device_here(cfg.device)
    if device != cfg.device:
        cfg = with_overrides(cfg, {"device": device})
    task = make_task(spec, cfg)
    model = task.build_model().to(device=cfg.device, dtype=cfg.torch_dtype)
    ck = load_checkpoint(run_dir / "checkpoints" / "last.pt", map_location=cfg.device)
    load_weights(model, ck, run_dir / "checkpoints" / "last.pt")
    task.load_state_dict(ck.get("task", {}))
    model.eval()
    return Run(run_dir, cfg, spec, task, model, int(ck["step"]))


def fit(
    problem: str | Path,
    preset: str | None = None,
    out: str | Path | None = None,
    overrides: dict | None = None,
    sets: list[str] | None = None,
    progress: bool = True,
    results: bool = True,
) -> Run:
    """Train a built-in problem (by name) or a spec file and write a run directory; what
    ``ginn train`` does, returning the trained run.

    Arguments:
        problem: built-in name (``ginn.list_problems()``) or path to a YAML spec.
        preset: named preset of the problem.
        out: run directory (default ``runs/<problem>-<timestamp>``).
        overrides: a partial config dict, e.g. ``{"training": {"iterations": 100}}``.
        sets: ``["key=value", ...]`` overrides as on the command line.
        progress: show a progress bar.
        results: write shapes and figures at the end.

    Returns:
        the :class:`Run` of the finished (or interrupted) run.
    """
    spec, cfg = resolve(problem, preset, overrides or {}, sets=sets)
    outcome = train(spec, cfg, out, progress=progress, results=results)
    return load_run(outcome.run_dir)


def _write_json(path: Path, data: dict) -> None:
    path.write_text(json.dumps(data, indent=2, default=float))


#: The most held-out codes ``ginn eval --heldout`` judges.
MAX_HELDOUT = 100_000


def evaluate(run_dir: str | Path, resolution: int | None = None, device: str | None = None,
             heldout: int | None = None) -> dict:
    """The metrics of a run (what ``ginn eval`` prints), also written to ``RUN/metrics.json``;
    ``heldout``: the held-out latent codes of a generative shape model (None: the default count)."""
    metrics, _ = evaluate_with_text(run_dir, resolution, device, heldout)
    return metrics


def evaluate_with_text(run_dir: str | Path, resolution: int | None = None, device: str | None = None,
                       heldout: int | None = None) -> tuple[dict, str]:
    """:func:`evaluate` and the task's readable text of the metrics."""
    run = load_run(run_dir, device=device)
    extra = {}
    if heldout is not None:
        if run.task.kind != "shape" or run.task.latents() is None:
            raise ConfigError("--heldout: judges the latent set of a generative shape run (latents.n_shapes > 1)")
        if heldout > MAX_HELDOUT:
            raise ConfigError(f"--heldout {heldout}: at most {MAX_HELDOUT} codes (each is a shape extracted on the "
                              "evaluation grid)")
        extra["heldout"] = heldout
    ev = run.task.results.evaluate(run.model, resolution=resolution, out_dir=run.path, **extra)
    metrics = ev.to_json()
    _write_json(run.path / "metrics.json", metrics)
    return metrics, ev.text() + f"\n(written to {run.path / 'metrics.json'})"


def export(run_dir: str | Path, latents: list[list[float]] | None = None, resolution: int | None = None,
           mesh_format: str | None = None, out: str | Path | None = None, device: str | None = None) -> list[Path]:
    """Meshes (3D) or contours (2D) of the trained latents, or of the given latent values, into
    ``out`` (default ``RUN/export``), evaluated on ``device`` (default: :func:`load_run`'s)."""
    run = load_run(run_dir, device=device)
    out_dir = Path(out) if out else run.path / "export"
    return run.task.results.export(run.model, latents or None, out_dir, resolution, mesh_format)


def verdict_lines(paths: list[Path]) -> list[str]:
    """The verdict of each exported shape (the ``verdicts.json`` among ``paths`` an export wrote):
    one line per shape and the grid they were judged on."""
    for p in paths:
        if Path(p).name == VERDICTS_FILE:
            data = json.loads(Path(p).read_text())
            return [row["text"] for row in data["shapes"]] + [
                f"(judged as ginn eval judges them: a grid of {data['resolution']} cells along the longest side)"]
    return []


def view(run_dir: str | Path, out: str | Path | None = None, steps: int = 64, device: str | None = None) -> Path:
    """The latent-space explorer of a completed run (``ginn view``): one self-contained HTML file
    (the task's :meth:`~ginn.train.task.Results.view`), ``RUN/figures/explorer.html`` unless
    ``out`` says otherwise; the pictures are drawn on ``device`` (default: :func:`load_run`'s)."""
    run_dir = Path(run_dir)
    st = read_status(run_dir)
    if st.status not in ("completed", "unknown"):
        raise ConfigError(f"{run_dir}: the run is {st.describe()}; ginn view shows completed runs "
                          f"(`ginn resume {run_dir}` finishes it)")
    if steps < 1:
        raise ConfigError(f"--steps must be at least 1, got {steps}")
    if out is not None and Path(out).resolve().parent == run_dir.resolve() and Path(out).name in RUN_RECORDS:
        raise ConfigError(f"--out {out}: is one of the run's own files; choose another name")
    run = load_run(run_dir, device=device)
    path = Path(out) if out is not None else run.path / "figures" / "explorer.html"
    return run.task.results.view(run.model, path, steps=steps, title=f"{run.spec.name}: {run.path.name}")


def plot(run_dir: str | Path, resolution: int | None = None, device: str | None = None) -> list[Path]:
    """The figures of a run (``ginn plot``), drawn on ``device`` (default: :func:`load_run`'s)."""
    run = load_run(run_dir, device=device)
    return run.task.results.plot(run.model, run.path, resolution)
