"""Implementations of the CLI subcommands (argument parsing lives in ginn.cli)."""

from __future__ import annotations

import sys
from pathlib import Path

import torch

from .errors import ConfigError, GinnError
from .train.config import config_to_dict, parse_set


def _check_device(device: str | None) -> None:
    if device is None:
        return
    if device == "cpu":
        return
    if device.startswith("cuda"):
        if not torch.cuda.is_available():
            raise ConfigError(f"--device {device}: CUDA is not available on this machine")
        return
    raise ConfigError(f"--device {device!r}: expected cpu or cuda[:N]")


def _say(msg: str, quiet: bool = False) -> None:
    if not quiet:
        print(msg, flush=True)


def _train_and_finish(trainer, task, run_dir: Path, quiet: bool, results: bool) -> int:
    from .train.run import write_status

    if not trainer.is_main:  # distributed: ranks > 0 train and write nothing
        return 130 if trainer.train().status == "interrupted" else 0
    write_status(run_dir, "running", trainer.step, trainer.elapsed)
    res = trainer.train()
    write_status(run_dir, res.status, res.step, res.seconds)
    if res.status == "interrupted":
        _say(f"interrupted at iteration {res.step}; checkpoint written. Continue with: ginn resume {run_dir}")
        return 130
    _say(f"trained {res.step} iterations in {res.seconds:.1f} s", quiet)
    if results:
        paths = task.finalize(trainer.model, run_dir)
        write_status(run_dir, "completed", res.step, res.seconds)
        if paths:
            _say("results:", quiet)
            for p in paths:
                _say(f"  {p}", quiet)
    _say(f"run directory: {run_dir}", quiet)
    return 0


def cmd_train(args) -> int:
    from .problems import load_spec
    from .train.registry import make_task, resolve_config
    from .train.run import new_run_dir, write_run_files
    from .train.distributed import init_distributed, on_main, shutdown
    from .train.trainer import Trainer

    _check_device(args.device)
    spec = load_spec(args.problem)
    over: dict = {"problem": str(Path(args.problem).resolve()) if Path(args.problem).suffix in (".yaml", ".yml") else spec.name}
    if args.seed is not None:
        over["seed"] = args.seed
    if args.device is not None:
        over["device"] = args.device
    if args.iterations is not None:
        if args.iterations < 0:
            raise ConfigError("--iterations must be >= 0")
        over["training"] = {"iterations": args.iterations}
    cfg = resolve_config(spec, args.preset, over, parse_set(args.sets))
    dist = init_distributed(cfg.device)  # None unless started by torchrun
    try:
        task = make_task(spec, dist.localize(cfg) if dist else cfg)
        run_dir = on_main(dist, lambda: new_run_dir(spec.name, args.out))
        if dist is None or dist.is_main:
            write_run_files(run_dir, cfg, Path(spec.source) if Path(spec.source).is_file() else None)
        where = f"{cfg.device}" if dist is None else f"{dist.world} x {dist.device} ({dist.backend})"
        _say(f"training {spec.name}" + (f" (preset {args.preset})" if args.preset else "") + f" on {where}; run directory {run_dir}",
             args.quiet or (dist is not None and not dist.is_main))
        trainer = Trainer(task, task.cfg, run_dir, progress=not args.quiet, dist=dist)
        return _train_and_finish(trainer, task, run_dir, args.quiet, not args.no_results)
    finally:
        shutdown(dist)


def cmd_resume(args) -> int:
    from .train.config import build_config
    from .train.distributed import init_distributed, shutdown
    from .train.run import load_run, read_config
    from .train.trainer import Trainer

    run_dir = Path(args.run_dir)
    cfg = read_config(run_dir)
    if args.iterations is not None:
        cfg = build_config(config_to_dict(cfg), {"training": {"iterations": args.iterations}})
    dist = init_distributed(cfg.device)  # None unless started by torchrun
    try:
        cfg = dist.localize(cfg) if dist else cfg
        run = load_run(run_dir, device=cfg.device)
        trainer = Trainer(run.task, cfg, run_dir, progress=not args.quiet, dist=dist)
        if not trainer.resume():
            raise GinnError(f"{run_dir}: no checkpoint to resume from")
        _say(f"resuming {run_dir} at iteration {trainer.step} of {cfg.training.iterations}", args.quiet or not trainer.is_main)
        return _train_and_finish(trainer, run.task, run_dir, args.quiet, not args.no_results)
    finally:
        shutdown(dist)


def cmd_problems(args) -> int:
    from .problems import list_problems, load_spec, spec_text

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


def cmd_eval(args) -> int:
    from .evaluate_run import evaluate_run_dir, print_table

    _check_device(args.device)
    results = []
    for rd in args.run_dirs:
        res = evaluate_run_dir(Path(rd), resolution=args.resolution, device=args.device)
        results.append(res)
        if not args.table:
            print(res["_text"])
    if args.table:
        print_table(results, [str(r) for r in args.run_dirs])
    return 0


def cmd_export(args) -> int:
    from .evaluate_run import export_run_dir

    paths = export_run_dir(Path(args.run_dir), args.latent, args.resolution, args.format, args.out)
    for p in paths:
        print(p)
    return 0


def cmd_plot(args) -> int:
    from .evaluate_run import plot_run_dir

    for p in plot_run_dir(Path(args.run_dir), args.resolution):
        print(p)
    return 0


def cmd_sweep(args) -> int:
    from .sweep import run_sweep_cli

    return run_sweep_cli(args)


