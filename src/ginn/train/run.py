"""Run directories: create, record, load.

Layout of ``runs/<problem>-<timestamp>/`` (or ``--out DIR``)::

    config.yaml         the resolved RunConfig (every default filled in)
    problem.yaml        a copy of the problem spec that was trained
    env.json            package versions, device, seed, command line, start time
    metrics.jsonl       one JSON line per logging step with every loss term
    checkpoints/last.pt the latest checkpoint (atomic; safe to load)
    status.json         "running" / "interrupted" / "completed", step, wall time
    ... result files written by the task at the end (shapes, meshes, figures)
"""

from __future__ import annotations

import datetime as _dt
import json
import platform
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import torch
import yaml
from torch import nn

from ..errors import ConfigError, GinnError
from .checkpoint import load_checkpoint
from .config import RunConfig, build_config, config_to_dict
from .task import Task
from .trainer import DTYPES


def new_run_dir(problem_name: str, out: str | Path | None = None, root: str | Path = "runs") -> Path:
    """A fresh directory ``root/<problem>-<timestamp>`` (or ``out``, which must be empty or new)."""
    if out is not None:
        p = Path(out)
        if p.exists() and any(p.iterdir()):
            raise ConfigError(f"--out {p}: directory exists and is not empty (use `ginn resume {p}` to continue it)")
    else:
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        safe = "".join(c if c.isalnum() or c in "-_" else "-" for c in problem_name)
        p = Path(root) / f"{safe}-{stamp}"
        i = 1
        while p.exists():
            p = Path(root) / f"{safe}-{stamp}-{i}"
            i += 1
    p.mkdir(parents=True, exist_ok=True)
    return p


def environment(cfg: RunConfig) -> dict:
    import numpy
    import scipy

    from .. import __version__

    env = {
        "ginn": __version__,
        "python": sys.version.split()[0],
        "torch": torch.__version__,
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
        "platform": platform.platform(),
        "device": cfg.device,
        "seed": cfg.seed,
        "threads": cfg.training.threads or torch.get_num_threads(),
        "command": sys.argv,
        "started": _dt.datetime.now().isoformat(timespec="seconds"),
    }
    if cfg.device.startswith("cuda") and torch.cuda.is_available():
        env["cuda_device"] = torch.cuda.get_device_name()
    return env


def write_run_files(run_dir: Path, cfg: RunConfig, spec_path: Path | None) -> None:
    (run_dir / "config.yaml").write_text(yaml.safe_dump(config_to_dict(cfg), sort_keys=False))
    if spec_path is not None:
        shutil.copyfile(spec_path, run_dir / "problem.yaml")
    (run_dir / "env.json").write_text(json.dumps(environment(cfg), indent=2))


def write_status(run_dir: Path, status: str, step: int, seconds: float) -> None:
    (run_dir / "status.json").write_text(json.dumps({"status": status, "step": step, "seconds": round(seconds, 2)}))


def read_config(run_dir: Path) -> RunConfig:
    p = Path(run_dir) / "config.yaml"
    if not p.is_file():
        raise GinnError(f"{run_dir} is not a ginn run directory (no config.yaml)")
    return build_config(yaml.safe_load(p.read_text()) or {})


@dataclass
class Run:
    """A loaded run: its config, problem spec, task and trained model (from the last checkpoint)."""

    path: Path
    config: RunConfig
    spec: object
    task: Task
    model: nn.Module
    step: int

    @property
    def latents(self):
        return self.task.latents()


def load_run(run_dir: str | Path, device: str | None = None) -> Run:
    """Rebuild the task and model of a run directory and load the last checkpoint's weights."""
    from ..problems import load_spec
    from .registry import make_task

    run_dir = Path(run_dir)
    cfg = read_config(run_dir)
    if device is not None and device != cfg.device:
        cfg = build_config(config_to_dict(cfg), {"device": device})
    spec_file = run_dir / "problem.yaml"
    spec = load_spec(cfg.problem) if not spec_file.is_file() else _load_recorded_spec(spec_file, cfg.problem)
    task = make_task(spec, cfg)
    model = task.build_model().to(device=cfg.device, dtype=DTYPES[cfg.training.dtype])
    ck = load_checkpoint(run_dir / "checkpoints" / "last.pt", map_location=cfg.device)
    model.load_state_dict(ck["model"])
    task.load_state_dict(ck.get("task", {}))
    model.eval()
    return Run(run_dir, cfg, spec, task, model, int(ck["step"]))


def _load_recorded_spec(spec_file: Path, original: str):
    """The copied spec; if it names files relative to the original spec's folder, use the original."""
    from ..problems import load_spec

    try:
        return load_spec(spec_file)
    except GinnError:
        return load_spec(original)
