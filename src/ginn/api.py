"""The notebook front door: ``ginn.fit`` trains a problem, ``ginn.evaluate`` measures a run.

Both do exactly what ``ginn train`` and ``ginn eval`` do, and return Python objects::

    import ginn
    run = ginn.fit("obstacle", preset="demo", overrides={"training": {"iterations": 200}})
    metrics = ginn.evaluate(run.path)
    run.model(x, z)   # the trained field
"""

from __future__ import annotations

from pathlib import Path

from .train.config import parse_set


def fit(
    problem: str | Path,
    preset: str | None = None,
    out: str | Path | None = None,
    overrides: dict | None = None,
    sets: list[str] | None = None,
    progress: bool = True,
    results: bool = True,
):
    """Train a built-in problem (by name) or a spec file and write a run directory.

    Arguments:
        problem: built-in name (``ginn.list_problems()``) or path to a YAML spec.
        preset: named preset of the problem.
        out: run directory (default ``runs/<problem>-<timestamp>``).
        overrides: a partial config dict, e.g. ``{"training": {"iterations": 100}}``.
        sets: ``["key=value", ...]`` overrides as on the command line.
        progress: show a progress bar.
        results: write shapes and figures at the end.

    Returns:
        :class:`ginn.train.run.Run` of the finished (or interrupted) run.
    """
    from .problems import load_spec
    from .train.registry import make_task, resolve_config
    from .train.run import load_run, new_run_dir, write_run_files, write_status
    from .train.trainer import Trainer

    spec = load_spec(problem)
    is_file = Path(str(problem)).suffix in (".yaml", ".yml")
    base = {"problem": str(Path(problem).resolve()) if is_file else spec.name}
    cfg = resolve_config(spec, preset, base, overrides or {}, parse_set(sets or []))
    task = make_task(spec, cfg)
    run_dir = new_run_dir(spec.name, out)
    write_run_files(run_dir, cfg, Path(spec.source) if Path(spec.source).is_file() else None)
    trainer = Trainer(task, cfg, run_dir, progress=progress)
    res = trainer.train()
    write_status(run_dir, res.status, res.step, res.seconds)
    if results and res.status == "completed":
        task.finalize(trainer.model, run_dir)
    return load_run(run_dir)


def evaluate(run_dir: str | Path, resolution: int | None = None) -> dict:
    """The metrics of a run (as ``ginn eval``; also written to ``RUN/metrics.json``)."""
    from .evaluate_run import evaluate_run_dir

    res = evaluate_run_dir(Path(run_dir), resolution=resolution)
    res.pop("_text", None)
    return res
