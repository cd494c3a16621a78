"""A size check before a run allocates anything: the memory its network and one training step
need at least, against what the device has free.

A width of 1e11 or a billion shapes would otherwise run until the allocator gives up (minutes,
gigabytes, a traceback); :func:`check_memory` refuses them with one line that names the sizes
and the estimate. The estimate counts the terms that grow with the sizes, each low:

- the network's parameters ``P`` (each layer ``(fan_in + 1) x fan_out``), held
  :data:`PARAMETER_COPIES` times (weights, gradients, Adam's two moments, the checks' interval mean
  and best candidate, a checkpoint being written);
- one step's hidden activations (shape problems): every shape of the step (``latents.n_shapes``)
  times the samples of a shape (the ``sampling`` counts) times the hidden units, each kept
  :data:`ACTIVATION_COPIES` times (value and gradient forward, their backward).

Free memory is ``MemAvailable`` of ``/proc/meminfo`` on the CPU (the physical memory where that
file does not exist) and ``torch.cuda.mem_get_info`` on a GPU.
"""

from __future__ import annotations

import os

import torch

from ..config import RunConfig
from ..errors import ConfigError

__all__ = ["PARAMETER_COPIES", "ACTIVATION_COPIES", "parameter_count", "step_bytes", "free_bytes", "check_memory"]

PARAMETER_COPIES = 7
ACTIVATION_COPIES = 4

#: inputs of the first layer besides the latent code: the coordinates and a margin for encodings
_INPUTS = 8


def _widths(cfg: RunConfig) -> list[int]:
    m = cfg.model
    return [m.width] * m.n_blocks if m.kind == "resmlp" else list(m.hidden)


def parameter_count(cfg: RunConfig) -> int:
    """The parameters of ``cfg.model`` for an input of the coordinates and the latent code (eight
    inputs besides the code: an encoding may have more), one network (the Gray-Scott task builds
    two, ``u`` and ``v``)."""
    w = [_INPUTS + cfg.latents.dim, *_widths(cfg), 1]
    return sum((a + 1) * b for a, b in zip(w[:-1], w[1:]))


def step_bytes(cfg: RunConfig) -> int:
    """The bytes a training step of ``cfg`` holds at least (module docstring)."""
    s = cfg.sampling
    points = s.n_domain + s.n_outside + s.n_obstacle + s.n_interface + s.n_band + s.n_boundary if cfg.kind == "shape" else 0
    size = torch.finfo(cfg.torch_dtype).bits // 8
    act = cfg.latents.n_shapes * points * sum(_widths(cfg)) * ACTIVATION_COPIES
    return size * (parameter_count(cfg) * PARAMETER_COPIES + act)


def free_bytes(device: str) -> int | None:
    """Memory free on ``device`` now (None where it cannot be read)."""
    if device.startswith("cuda"):
        try:
            return int(torch.cuda.mem_get_info(torch.device(device))[0])
        except (RuntimeError, AssertionError, ValueError):
            return None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return None


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB"


def check_memory(cfg: RunConfig, device: str | None = None) -> None:
    """Refuse ``cfg`` (:class:`ginn.errors.ConfigError`, one line) when one training step needs
    more memory than ``device`` (default ``cfg.device``) has free."""
    device = device or cfg.device
    need, free = step_bytes(cfg), free_bytes(device)
    if free is None or need <= free:
        return
    widths = _widths(cfg)
    raise ConfigError(
        f"the run needs at least {_gib(need)} ({parameter_count(cfg):.3g} parameters of model widths "
        f"{widths if len(widths) <= 6 else str(widths[:6])[:-1] + ', ...]'}, {cfg.latents.n_shapes} shapes per step "
        f"(latents.n_shapes)), more than the {_gib(free)} free on {device}: lower model.hidden / model.width, "
        "latents.n_shapes or the sampling counts")
