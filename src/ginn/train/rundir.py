"""Run directories: create them, record what a run is and how it is doing (``ginn.runs`` loads them).

Layout of ``runs/<problem>-<timestamp>/`` (or ``--out DIR``)::

    config.yaml         the resolved RunConfig (every default filled in)
    problem.yaml        a copy of the problem spec that was trained (the run reads its problem
                        from this copy only)
    inputs/             copies of the files the problem reads (meshes), which problem.yaml names
    env.json            package versions, device, seed, command line, start time
    metrics.jsonl       one JSON line per logged iteration: ``step`` is the 0-based index of the
                        iteration whose loss terms the line holds; events (rollback, interrupted)
    checkpoints/last.pt the latest checkpoint (atomic; safe to load)
    .ginn-lock          the writer's lock (ginn.train.lock), held by the process that trains it
    restarts/<n>/       metrics.jsonl and status.json of an attempt that ended before its first
                        checkpoint, set aside when the run was restarted from its config
    status.json         running | interrupted | completed | failed | pruned; ``step`` is the number
                        of completed iterations; a running process's pid, host and heartbeat
    ... result files written by the task at the end (shapes, meshes, figures)

Every write that fails (a read-only directory, a full disk) raises a one-line
:class:`~ginn.errors.GinnError` that names the file.
"""

from __future__ import annotations

import datetime as _dt
import errno
import json
import os
import platform
import shutil
import socket
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy
import scipy
import torch
import yaml

from ..config import RunConfig, config_to_dict
from ..errors import ConfigError, GinnError
from ..version import __version__
from ..yamlfile import load_yaml
from .lock import LOCK_NAME, RunLock, RunLocked, lock_holder

#: the files a run directory keeps about itself (a command that writes elsewhere never replaces them)
RUN_RECORDS = ("config.yaml", "problem.yaml", "env.json", "metrics.jsonl", "status.json", "metrics.json", LOCK_NAME)


def slug(name: str) -> str:
    """``name`` made safe for a directory name (letters, digits, ``-`` and ``_``; others become ``-``)."""
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in name)


def io_error(e: OSError, path: str | Path, doing: str = "write") -> GinnError:
    """A one-line error for a failed file operation (the disk full, no permission, ...)."""
    if e.errno == errno.ENOSPC:
        return GinnError(f"{path}: no space left on device")
    if e.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        why = "read-only file system" if e.errno == errno.EROFS else "permission denied"
        return GinnError(f"{path}: cannot {doing} ({why})")
    if e.errno == errno.ENAMETOOLONG:
        return GinnError(f"{path}: cannot {doing}: a name in the path is longer than the file system allows "
                         "(255 bytes on most)")
    return GinnError(f"{path}: cannot {doing} ({e.strerror or type(e).__name__})")


def new_run_dir(problem_name: str, out: str | Path | None = None, root: str | Path = "runs") -> tuple[Path, RunLock]:
    """A fresh directory ``root/<problem>-<timestamp>`` (or ``out``, which must be empty or new),
    with its writer's lock (:class:`~ginn.train.lock.RunLock`) taken: the caller holds it for the
    whole run and releases it.

    The directory is made with an exclusive ``mkdir`` or, for an existing ``out``, locked before it
    is checked to be empty, so two processes never share one.
    """
    try:
        if out is not None:
            p = Path(out)
            if p.exists() and not p.is_dir():
                raise ConfigError(f"--out {p}: exists and is not a directory")
            p.mkdir(parents=True, exist_ok=True)
            try:
                lock = RunLock(p).acquire()
            except RunLocked:
                raise ConfigError(f"--out {p}: another process writes a run there ({RunLock(p).holder()})") from None
            if any(q.name != LOCK_NAME for q in p.iterdir()):
                lock.release()
                raise ConfigError(f"--out {p}: directory exists and is not empty (use `ginn resume {p}` to continue it)")
            return p, lock
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        base = Path(root) / f"{slug(problem_name)}-{stamp}"
        base.parent.mkdir(parents=True, exist_ok=True)
        for i in range(1000):
            p = base if i == 0 else base.with_name(f"{base.name}-{i}")
            try:
                p.mkdir()
            except FileExistsError:
                continue
            return p, RunLock(p).acquire()
        raise GinnError(f"{root}: could not create a new run directory for {problem_name}")
    except OSError as e:
        raise io_error(e, out if out is not None else root,
                       "create the run directory" if out is not None else "create a run directory in it") from None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


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


def write_run_files(run_dir: Path, cfg: RunConfig, spec_path: Path | None, notes: list[str] | None = None,
                    spec_text: str | None = None, inputs: dict[str, Path] | None = None) -> None:
    """``config.yaml`` (headed by ``notes`` as comments: the settings derived from the problem's
    geometry and why), ``problem.yaml`` (a copy of the spec file ``spec_path``, or ``spec_text``
    when given), the files the problem reads (``inputs``: ``{path in the run: file to copy}``)
    and ``env.json``."""
    target = run_dir / "config.yaml"
    head = ""
    if notes:
        head = "# derived from the problem's geometry (ginn.problems.derived):\n" + "".join(f"#   {n}\n" for n in notes)
    try:
        target.write_text(head + yaml.safe_dump(config_to_dict(cfg, relevant_only=True), sort_keys=False))
        if spec_text is not None:
            (run_dir / "problem.yaml").write_text(spec_text)
        elif spec_path is not None:
            shutil.copyfile(spec_path, run_dir / "problem.yaml")
        for rel, src in (inputs or {}).items():
            (run_dir / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, run_dir / rel)
        (run_dir / "env.json").write_text(json.dumps(environment(cfg), indent=2))
    except OSError as e:
        raise io_error(e, e.filename or target) from None


def read_config_dict(run_dir: Path) -> dict:
    """The raw ``config.yaml`` of a run directory.

    Raises:
        GinnError: no run directory, no or an unreadable ``config.yaml`` (one line).
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise GinnError(f"{run_dir} is not a ginn run directory (no such directory)")
    p = run_dir / "config.yaml"
    if not p.is_file():
        raise GinnError(f"{run_dir} is not a ginn run directory (no config.yaml)")
    try:
        data = load_yaml(_text(p), str(p))
    except OSError as e:
        raise io_error(e, p, "read") from None
    except ConfigError as e:
        raise GinnError(str(e)) from None
    if not isinstance(data, dict):
        raise GinnError(f"{p}: not a run configuration (expected a mapping)")
    return data


def set_aside(run_dir: Path, names: tuple[str, ...]) -> Path | None:
    """Move those of the files ``names`` of ``run_dir`` that exist into a new folder
    ``run_dir/restarts/<n>/`` (n = 1, 2, ...), so that a restart never overwrites them; returns
    the folder (None: there was nothing to move)."""
    found = [run_dir / n for n in names if (run_dir / n).exists()]
    if not found:
        return None
    try:
        (run_dir / "restarts").mkdir(exist_ok=True)
        n = 1
        while True:
            dest = run_dir / "restarts" / str(n)
            try:
                dest.mkdir()
                break
            except FileExistsError:
                n += 1
        for f in found:
            os.replace(f, dest / f.name)
    except OSError as e:
        raise io_error(e, e.filename or run_dir) from None
    return dest


# --- status ---------------------------------------------------------------------------------------


@dataclass
class Status:
    """What ``status.json`` says about a run.

    Attributes:
        status: ``running``, ``interrupted``, ``completed``, ``failed``, ``pruned`` (or ``unknown``).
        step: completed iterations.
        seconds: training time so far.
        reason: why it failed or was stopped (one line), or "".
        pid, host: the training process while running.
        heartbeat: wall-clock time (seconds since the epoch) of the last update while running.
        heartbeat_every: the longest expected interval between updates (seconds).
        run_dir: the run directory it was read from (not in the file).
    """

    status: str
    step: int = 0
    seconds: float = 0.0
    reason: str = ""
    pid: int | None = None
    host: str = ""
    heartbeat: float | None = None
    heartbeat_every: float = 60.0
    run_dir: Path | None = None

    @property
    def stale_after(self) -> float:
        """Seconds after which a heartbeat is stale: three intervals and a minute."""
        return 3 * self.heartbeat_every + 60

    def judge(self, now: float | None = None) -> tuple[bool, str]:
        """Whether a ``running`` run's process is still there, and why it is judged so.

        On the machine that runs it: whether a process holds the run's lock (``/proc/locks``, which
        the kernel keeps true); where that cannot be read, whether its pid exists and its heartbeat
        is fresh (:attr:`stale_after`; a pid alone may have been reused). From another machine:
        whether the heartbeat is fresh."""
        if self.status != "running":
            return False, ""
        now = time.time() if now is None else now
        age = None if self.heartbeat is None else now - self.heartbeat
        fresh = age is not None and age <= self.stale_after
        beat = "no heartbeat" if age is None else f"its last heartbeat {age:.0f} s ago (stale after {self.stale_after:.0f} s)"
        if self.host == socket.gethostname():
            holder = lock_holder(self.run_dir) if self.run_dir is not None else False
            if holder is not False:
                if holder and (holder != os.getpid() or self.pid == os.getpid()):
                    return True, f"pid {holder} holds its lock"
                # a resume in this process took the lock of a run whose own process is gone
                return False, "no process holds its lock" if not holder else f"pid {self.pid} left it; this process holds it now"
            if self.pid is None or not _pid_alive(self.pid):
                return False, f"pid {self.pid} is gone"
            return (True, f"pid {self.pid} is alive, {beat}") if fresh else (False, f"{beat}; pid {self.pid} is another process")
        return fresh, f"{beat}; judged by the heartbeat, the process runs on {self.host or 'another machine'}"

    def alive(self, now: float | None = None) -> bool:
        """Whether a ``running`` run's process is still there (:meth:`judge`)."""
        return self.judge(now)[0]

    def describe(self) -> str:
        """One line: ``completed at iteration 500 (41.2 s)``, ``running at iteration 120 (pid 4242 on
        host: pid 4242 holds its lock)``, ``not running (last seen 2026-12-01 10:15:02 at iteration
        180: no process holds its lock; ...)``, ``failed at ...: reason``."""
        if self.status == "running":
            alive, why = self.judge()
            if alive:
                return f"running at iteration {self.step} (pid {self.pid} on {self.host}: {why})"
            seen = _dt.datetime.fromtimestamp(self.heartbeat).isoformat(sep=" ", timespec="seconds") if self.heartbeat else "never"
            return f"not running (last seen {seen} at iteration {self.step}: {why}; `ginn resume` continues it)"
        text = f"{self.status} at iteration {self.step} ({self.seconds:.1f} s of training)"
        return text + (f": {self.reason}" if self.reason else "")


def write_status(run_dir: Path, status: str, step: int, seconds: float, reason: str = "",
                 heartbeat_every: float = 60.0) -> None:
    """Write ``status.json`` atomically; a running status carries this process's pid, host and a
    heartbeat (now)."""
    data: dict = {"status": status, "step": int(step), "seconds": round(float(seconds), 2)}
    if reason:
        data["reason"] = reason
    if status == "running":
        data.update(pid=os.getpid(), host=socket.gethostname(), heartbeat=round(time.time(), 3),
                    heartbeat_every=round(float(heartbeat_every), 3))
    path = Path(run_dir) / "status.json"
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(data))
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise io_error(e, path) from None


def read_status(run_dir: Path) -> Status:
    """The run's :class:`Status` (``unknown`` when ``status.json`` is missing or unreadable)."""
    p = Path(run_dir) / "status.json"
    try:
        data = json.loads(p.read_text())
        fields = {k: data[k] for k in Status.__dataclass_fields__ if k in data and k != "run_dir"}
        return Status(**fields, run_dir=Path(run_dir))
    except (OSError, ValueError, TypeError):
        return Status("unknown", run_dir=Path(run_dir))


# --- metrics.jsonl --------------------------------------------------------------------------------


class RunRecord:
    """What a training process keeps current in its run directory: ``metrics.jsonl`` (one line
    per record) and ``status.json``. Nothing is written without a directory, nor on ranks other
    than 0 (``writes`` False). A failed write is one line that names the file and says what the
    last checkpoint left intact.

    Arguments:
        run_dir: the run directory, or None.
        writes: whether this process writes (rank 0).
        checkpoint: the checkpoint file, for the message after a failed write.
    """

    def __init__(self, run_dir: Path | None, writes: bool, checkpoint: Path | None):
        self.run_dir, self.writes, self.checkpoint = run_dir, writes and run_dir is not None, checkpoint

    def intact(self) -> str:
        """What is left after a failed write: the last checkpoint, which a failed write never touches."""
        if self.checkpoint is not None and self.checkpoint.is_file():
            return f"the last checkpoint ({self.checkpoint}) is intact; `ginn resume {self.run_dir}` continues from it"
        return "no checkpoint had been written yet"

    def append(self, record: dict) -> bool:
        """Add ``record`` to ``metrics.jsonl``; returns whether this process writes."""
        if not self.writes:
            return False
        path = self.run_dir / "metrics.jsonl"
        try:
            with open(path, "a") as fh:
                fh.write(json.dumps(record) + "\n")
        except OSError as e:
            raise GinnError(f"{io_error(e, path)}; {self.intact()}") from None
        return True

    def status(self, status: str, step: int, seconds: float, reason: str = "", heartbeat_every: float = 60.0) -> None:
        """Write ``status.json`` (:func:`write_status`)."""
        if self.writes:
            write_status(self.run_dir, status, step, seconds, reason, heartbeat_every=heartbeat_every)

    def try_status(self, *args, **kwargs) -> None:
        """:meth:`status`, if the disk still lets us (after a failure: the original error is what matters)."""
        try:
            self.status(*args, **kwargs)
        except GinnError:
            pass


def _text(path: Path) -> str:
    """A run file's text; bytes that are not UTF-8 (a damaged file) read as U+FFFD, so that the line
    that holds them is the one refused, not the whole file."""
    return Path(path).read_bytes().decode("utf-8", errors="replace")


def metrics_lines(text: str) -> list[tuple[int, str, dict | None]]:
    """``(line number, line, record)`` of every non-empty line of a ``metrics.jsonl``'s text; the
    record is None for a line that is not a JSON object (a partial last line, say)."""
    out = []
    for i, line in enumerate(text.split("\n"), 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except ValueError:
            rec = None
        out.append((i, line, rec if isinstance(rec, dict) else None))
    return out


def read_metrics(path: Path) -> list[dict]:
    """The records of a ``metrics.jsonl``; a line that is not a JSON object is skipped with a warning."""
    try:
        text = _text(path)
    except OSError as e:
        raise io_error(e, path, "read") from None
    out = []
    for i, _, rec in metrics_lines(text):
        if rec is None:
            warnings.warn(f"{path}:{i}: skipped a line that is not a JSON record", stacklevel=2)
        else:
            out.append(rec)
    return out


def truncate_metrics(path: Path, step: int) -> int:
    """Cut ``metrics.jsonl`` back to a checkpoint at ``step`` completed iterations: the records of
    iterations ``>= step`` (logged after that checkpoint) and any partial last line are dropped
    (the latter with a warning). Rewritten atomically; returns the number of records dropped."""
    path = Path(path)
    if not path.is_file():
        return 0
    try:
        text = _text(path)
    except OSError as e:
        raise io_error(e, path, "read") from None
    keep, dropped = [], 0
    last = text.count("\n") + 1
    for i, line, rec in metrics_lines(text):
        if rec is None:
            where = "the partial last line" if i >= last - 1 else f"line {i}"
            warnings.warn(f"{path}: dropped {where}, which is not a JSON record", stacklevel=2)
            dropped += 1
            continue
        s = rec.get("step")
        # iteration records (and skipped iterations) carry the 0-based index of their iteration;
        # other events the number of completed iterations when they happened
        index = "event" not in rec or rec["event"] == "skipped_non_finite"
        if isinstance(s, int) and (s >= step if index else s > step):
            dropped += 1
            continue
        keep.append(line)
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text("".join(line + "\n" for line in keep))
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise io_error(e, path) from None
    return dropped
