"""The writer's lock of a run directory: one process at a time trains, resumes or sweeps into a run.

``RUN/.ginn-lock`` is locked with ``flock(2)`` by the process that writes the run, from before its
first check of the run to its last write. The kernel drops the lock when that process ends, however
it ends (SIGKILL included), so a lock is never stale and needs no clean-up. The file also holds who
took it (pid, host, time) for the one line a second writer gets. Commands that only read a run
never take it.

``flock`` locks are local to a machine on most network file systems; two machines writing one run
directory over NFS are not kept apart (the heartbeat of ``status.json`` still tells a running run
from a dead one).
"""

from __future__ import annotations

import datetime as _dt
import errno
import fcntl
import json
import os
import socket
import time
from pathlib import Path

from ..errors import GinnError

__all__ = ["LOCK_NAME", "RunLock", "RunLocked", "lock_holder"]

#: the lock file's name in a run directory
LOCK_NAME = ".ginn-lock"


class RunLocked(GinnError):
    """Another process writes this run."""


class RunLock:
    """The exclusive lock of ``run_dir`` (a context manager; :meth:`acquire` raises
    :class:`RunLocked` naming the holder when another process holds it)."""

    def __init__(self, run_dir: str | Path):
        self.run_dir = Path(run_dir)
        self.path = self.run_dir / LOCK_NAME
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self) -> RunLock:
        if self._fd is not None:
            return self
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            os.close(fd)
            if e.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            raise RunLocked(f"{self.run_dir}: another process writes this run ({self.holder()}); "
                            "wait for it to end or stop it first") from None
        os.ftruncate(fd, 0)
        os.write(fd, json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "since": round(time.time(), 3)}).encode())
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        try:
            fcntl.flock(fd, fcntl.LOCK_UN)
        finally:
            os.close(fd)

    def holder(self, wait: float = 1.0) -> str:
        """Who took the lock last, as the lock file says: ``pid 4242 on host, since 2026-12-01 10:15:02``.
        A holder writes this just after it locks, so an empty file is read again for up to ``wait`` s."""
        deadline = time.monotonic() + wait
        while True:
            try:
                data = json.loads(self.path.read_text())
                since = _dt.datetime.fromtimestamp(float(data["since"])).isoformat(sep=" ", timespec="seconds")
                return f"pid {int(data['pid'])} on {data['host']}, since {since}"
            except (OSError, ValueError, KeyError, TypeError):
                if time.monotonic() >= deadline:
                    return "a process that has not yet said who it is"
                time.sleep(0.02)

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def lock_holder(run_dir: str | Path) -> int | None | bool:
    """The pid of the process on this machine that holds the lock of ``run_dir`` (None: nobody
    does), read from ``/proc/locks`` without touching the lock; False where that cannot be known
    (no lock file, or no ``/proc/locks``: not Linux)."""
    try:
        st = (Path(run_dir) / LOCK_NAME).stat()
    except OSError:
        return False
    try:
        table = Path("/proc/locks").read_text()
    except OSError:
        return False
    dev = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    for line in table.splitlines():
        f = line.split()
        # "1: FLOCK  ADVISORY  WRITE 4242 fe:00:2146642 0 EOF" (blocked waiters carry "->")
        if len(f) >= 6 and f[1] == "FLOCK" and f[3] == "WRITE" and f[5] == dev:
            return int(f[4])
    return None
