"""Crash-safe checkpoints: written atomically, loaded without unpickling arbitrary objects.

A checkpoint is a dict of tensors and plain Python data (numbers, strings, lists, dicts) saved
with :func:`torch.save` to a temporary file in the same directory, flushed to disk and renamed
over the old one (``os.replace`` is atomic on POSIX). Loading uses
``torch.load(weights_only=True)``, whose restricted unpickler refuses any other object, so a
crafted checkpoint cannot execute code.
"""

from __future__ import annotations

import os
import pickle
import pickletools
import tempfile
import zipfile
from pathlib import Path
from typing import Any

import torch

from ..errors import GinnError


class CheckpointError(GinnError):
    """A checkpoint is missing, corrupt or unsafe."""


def save_checkpoint(path: str | Path, state: dict[str, Any]) -> None:
    """Atomically write ``state`` to ``path`` (temporary file + fsync + rename): a failure (a full
    disk, a kill) leaves the previous checkpoint as it was.

    Raises:
        OSError: the file could not be written (torch's own error for a short write is turned
            back into the ``OSError`` behind it, e.g. ``ENOSPC``).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            torch.save(state, fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        if os.path.exists(tmp):
            os.unlink(tmp)
        cause = e.__cause__ or e.__context__
        if not isinstance(e, OSError) and isinstance(cause, OSError):
            raise OSError(cause.errno, cause.strerror, str(path)) from None
        raise
    try:  # make the rename durable
        dfd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass


def _first_line(e: BaseException, limit: int = 160) -> str:
    """The first line of an error's message, shortened at a word boundary."""
    text = str(e).strip()
    line = text.splitlines()[0] if text else type(e).__name__
    if len(line) > limit:
        line = line[:limit].rsplit(" ", 1)[0] + " ..."
    return line


def load_checkpoint(path: str | Path, map_location: str | torch.device = "cpu") -> dict[str, Any]:
    """Load a checkpoint safely. Raises :class:`CheckpointError` (one line) for a missing, empty,
    corrupt or unsafe file."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"no checkpoint at {path}")
    try:
        size = path.stat().st_size
    except OSError as e:
        raise CheckpointError(f"cannot read checkpoint {path}: {e.strerror}") from None
    if size == 0:
        raise CheckpointError(f"checkpoint {path} is empty (0 bytes): not a ginn checkpoint")
    if not zipfile.is_zipfile(path) and not _is_pickle(path):
        raise CheckpointError(f"checkpoint {path} is not a torch checkpoint (corrupt, or another kind of file)")
    try:
        state = torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as e:
        what = [line.strip() for line in str(e).splitlines() if line.strip().startswith("Unsupported")]
        raise CheckpointError(f"refusing to load {path}: it contains objects other than tensors and plain data"
                              + (f" ({what[0][:120]})" if what else "")) from None
    except Exception as e:  # noqa: BLE001 - torch raises many kinds for a damaged archive; one line for the user
        raise CheckpointError(f"cannot read checkpoint {path}: {_first_line(e)}") from None
    if not isinstance(state, dict):
        raise CheckpointError(f"checkpoint {path} is not a ginn checkpoint (not a mapping)")
    model, step = state.get("model"), state.get("step")
    if not isinstance(model, dict) or not all(isinstance(v, torch.Tensor) for v in model.values()):
        raise CheckpointError(f"checkpoint {path} is not a ginn checkpoint (no model weights)")
    if isinstance(step, bool) or not isinstance(step, int) or step < 0:
        raise CheckpointError(f"checkpoint {path} is not a ginn checkpoint (its step is {step!r}, not a count)")
    return state


def load_weights(model: torch.nn.Module, state: dict[str, Any], path: str | Path) -> None:
    """``model.load_state_dict(state["model"])`` with a one-line :class:`CheckpointError` where the
    weights do not fit the model (``config.yaml`` edited to another model, say)."""
    try:
        model.load_state_dict(state["model"])
    except RuntimeError as e:
        detail = next((line.strip() for line in str(e).splitlines()[1:] if line.strip()), _first_line(e))
        raise CheckpointError(f"checkpoint {path} does not fit the model of the run's config.yaml ({detail[:200]})") from None


def _is_pickle(path: Path) -> bool:
    """Whether a file parses as a pickle stream (read with ``pickletools``, nothing is executed)."""
    try:
        with open(path, "rb") as fh:
            for _ in pickletools.genops(fh):
                pass
        return True
    except Exception:  # noqa: BLE001 - any parse failure means: not a pickle
        return False


def rng_state(gen: torch.Generator) -> dict[str, Any]:
    """RNG states to store: torch's global CPU RNG, the sampling generator, and CUDA's if used."""
    out: dict[str, Any] = {"torch_cpu": torch.get_rng_state(), "sampler": gen.get_state()}
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        out["torch_cuda"] = torch.cuda.get_rng_state_all()
    return out


def set_rng_state(state: dict[str, Any], gen: torch.Generator) -> None:
    """Restore :func:`rng_state` (each state a byte tensor on the host, wherever the checkpoint was
    mapped)."""
    torch.set_rng_state(state["torch_cpu"].cpu())
    gen.set_state(state["sampler"].cpu())
    if "torch_cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all([s.cpu() for s in state["torch_cuda"]])
