"""Run directories: create and record (``ginn.runs`` loads them).

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
from pathlib import Path

import numpy
import scipy
import torch
import yaml

from ..config import RunConfig, config_to_dict
from ..errors import ConfigError, GinnError
from ..version import __version__


def slug(name: str) -> str:
    """``name`` made safe for a directory name (letters, digits, ``-`` and ``_``; others become ``-``)."""
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in name)


def new_run_dir(problem_name: str, out: str | Path | None = None, root: str | Path = "runs") -> Path:
    """A fresh directory ``root/<problem>-<timestamp>`` (or ``out``, which must be empty or new)."""
    if out is not None:
        p = Path(out)
        if p.exists() and any(p.iterdir()):
            raise ConfigError(f"--out {p}: directory exists and is not empty (use `ginn resume {p}` to continue it)")
    else:
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        safe = slug(problem_name)
        p = Path(root) / f"{safe}-{stamp}"
        i = 1
        while p.exists():
            p = Path(root) / f"{safe}-{stamp}-{i}"
            i += 1
    p.mkdir(parents=True, exist_ok=True)
    return p


def environment(cfg: RunConfig) -> dict:
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


def read_config_dict(run_dir: Path) -> dict:
    """The raw ``config.yaml`` of a run directory. Raises :class:`GinnError` if there is none."""
    p = Path(run_dir) / "config.yaml"
    if not p.is_file():
        raise GinnError(f"{run_dir} is not a ginn run directory (no config.yaml)")
    return yaml.safe_load(p.read_text()) or {}
