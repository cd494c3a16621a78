"""The ``ginn`` subcommands: parsed arguments in, :mod:`ginn.runs` (or :mod:`ginn.sweep`) called,
text and an exit status out. Argument parsing lives in :mod:`ginn.cli.parser`."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

from .. import runs, sweep
from ..errors import ConfigError, GinnError
from ..eval.shapes import format_comparison_table
from ..problems import list_problems, load_spec, spec_text
from ..train.distributed import init_distributed, shutdown
from ..train.rundir import read_config_dict, read_status

__all__ = ["COMMANDS"]


def _printer(quiet: bool) -> Callable[[str], None]:
    return (lambda msg: None) if quiet else (lambda msg: print(msg, flush=True))


def _exit_status(outcome: runs.Outcome, main: bool) -> int:
    """0 when completed; 130 when interrupted, saying how to continue (on rank 0)."""
    if outcome.status != "interrupted":
        return 0
    if main:
        print(f"interrupted at iteration {outcome.step}; checkpoint written. Continue with: ginn resume {outcome.run_dir}",
              flush=True)
    return 130


def cmd_train(args: argparse.Namespace) -> int:
    runs.check_device(args.device or "cpu", "--device")
    over: dict = {}
    if args.seed is not None:
        over["seed"] = args.seed
    if args.device is not None:
        over["device"] = args.device
    if args.iterations is not None:
        over["training"] = {"iterations": args.iterations}
    spec, cfg = runs.resolve(args.problem, args.preset, over, sets=args.sets)
    dist = init_distributed(cfg.device)  # None unless started by torchrun
    try:
        main = dist is None or dist.is_main
        outcome = runs.train(spec, cfg, args.out, progress=not args.quiet, results=False if args.no_results else None,
                             dist=dist, say=_printer(args.quiet or not main))
        return _exit_status(outcome, main)
    finally:
        shutdown(dist)


def cmd_resume(args: argparse.Namespace) -> int:
    raw = read_config_dict(Path(args.run_dir))
    dist = init_distributed(args.device or str(raw.get("device", "cpu")))  # None unless started by torchrun
    try:
        main = dist is None or dist.is_main
        outcome = runs.resume(args.run_dir, args.iterations, progress=not args.quiet, device=args.device,
                              results=False if args.no_results else None, dist=dist, say=_printer(args.quiet or not main))
        return _exit_status(outcome, main)
    finally:
        shutdown(dist)


def cmd_status(args: argparse.Namespace) -> int:
    for rd in args.run_dirs:
        read_config_dict(Path(rd))  # one line if it is not a run directory
        print(f"{rd}: {read_status(Path(rd)).describe()}")
    return 0


def _note_unfinished(run_dir: str | Path) -> None:
    """One line on stderr when a run being read has not completed (running, stopped, failed)."""
    st = read_status(Path(run_dir))
    if st.status not in ("completed", "unknown"):
        sys.stderr.write(f"ginn: note: {run_dir} is {st.describe()}\n")


def cmd_problems(args: argparse.Namespace) -> int:
    if args.action == "show":
        if not args.name:
            raise ConfigError("usage: ginn problems show NAME")
        load_spec(args.name)  # validates
        sys.stdout.write(spec_text(args.name))
        return 0
    for name in list_problems():
        spec = load_spec(name)
        presets = ", ".join(sorted(spec.presets or {})) or "-"
        desc = (spec.description or "").strip().splitlines()[0] if spec.description else ""
        print(f"{name:12s} {spec.kind:10s} presets: {presets:28s} {desc}")
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    runs.check_device(args.device or "cpu", "--device")
    results = []
    for rd in args.run_dirs:
        _note_unfinished(rd)
        metrics, text = runs.evaluate_with_text(Path(rd), resolution=args.resolution, device=args.device,
                                                heldout=args.heldout)
        results.append(metrics)
        if not args.table:
            print(text)
    if args.table:
        if not all("mean" in r for r in results):
            raise GinnError("--table compares shape runs only")
        print(format_comparison_table(results, [str(r) for r in args.run_dirs]))
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    _note_unfinished(args.run_dir)
    paths = runs.export(Path(args.run_dir), args.latent, args.resolution, args.format, args.out, device=args.device)
    for p in paths:
        print(p)
    for line in runs.verdict_lines(paths):
        print(line)
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    _note_unfinished(args.run_dir)
    for p in runs.plot(Path(args.run_dir), args.resolution, device=args.device):
        print(p)
    return 0


def cmd_view(args: argparse.Namespace) -> int:
    print(runs.view(Path(args.run_dir), args.out, args.steps, device=args.device))
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    sweep.require_optuna()
    if args.report:
        return _sweep_report(args)
    if not args.problem:
        raise ConfigError("usage: ginn sweep PROBLEM|SPEC.yaml --space SPACE.yaml --trials N (or ginn sweep --report)")
    if not args.space:
        raise ConfigError("ginn sweep: --space SPACE.yaml is required")
    space = sweep.load_space(args.space)
    over: dict = {}
    if args.device is not None:
        over["device"] = args.device
    if args.iterations is not None:
        over["training"] = {"iterations": args.iterations}
    if args.seed is not None:
        over["seed"] = args.seed
    spec, cfg = runs.resolve(args.problem, args.preset, over, sets=args.sets)
    setup = sweep.SweepSetup.create(spec, cfg, space, out=args.out, storage=args.storage, study=args.study,
                                    space_path=Path(args.space), quiet=args.quiet)
    log = _printer(args.quiet)
    log(f"sweep {setup.study_name}: {args.trials} trials in total, storage {setup.storage.split('://')[0]}, "
        f"trials in {setup.out / 'trials'}")
    counts = sweep.run_worker(setup, args.trials, log)
    log(f"this worker: {counts['complete']} completed, {counts['pruned']} pruned, {counts['fail']} failed")
    if not args.quiet:
        print(sweep.report(sweep.open_study(setup.storage, setup.study_name, create=False), setup.out / "objective.png"))
    return 0


def _sweep_report(args: argparse.Namespace) -> int:
    if args.storage:
        storage, study, out = args.storage, args.study, (Path(args.out) if args.out else None)
        if not study:
            names = sweep.study_names(storage)
            if len(names) != 1:
                raise ConfigError("--report with --storage: name the study with --study (studies: " + (", ".join(names) or "none") + ")")
            study = names[0]
    else:
        if not args.out:
            raise ConfigError("--report needs --out SWEEP_DIR or --storage URL --study NAME")
        out = Path(args.out)
        if not (out / "study.db").is_file():
            raise ConfigError(f"--out {out}: no study.db (not a sweep directory)")
        storage = sweep.default_storage(out)
        sweep_json = out / "sweep.json"
        study = args.study or (json.loads(sweep_json.read_text()).get("study") if sweep_json.is_file() else None)
        if not study:
            raise ConfigError(f"--out {out}: no sweep.json; name the study with --study")
    st = sweep.open_study(storage, study, create=False)
    png = out / "objective.png" if out is not None else Path(f"objective-{study}.png")
    sys.stdout.write(sweep.report(st, png) + "\n")
    return 0


#: subcommand name -> implementation
COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    "train": cmd_train,
    "resume": cmd_resume,
    "status": cmd_status,
    "problems": cmd_problems,
    "eval": cmd_eval,
    "export": cmd_export,
    "plot": cmd_plot,
    "view": cmd_view,
    "sweep": cmd_sweep,
}
