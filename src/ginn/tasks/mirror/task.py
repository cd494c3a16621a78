"""The parabolic mirror task (paper Section 4.1, Appendix A.3): a GINN for an explicit height function.

The constraints are ``h(0) = 0`` (interface) and that every vertical ray reflects through the focus
(optics; see :mod:`ginn.tasks.mirror.optics` for the geometry and the exact answer ``x^2 / (4 F)``).

Model input width: the paper lists ``[2, 40, 40, 1]`` without explaining the second input; a height
function of one variable has one input, so we use ``MLP(1, [40, 40], activation="tanh")``.
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor, nn

from ...config import LossTerm, MirrorParams, RunConfig, ShapeParams, parse_task_params
from ...errors import ConfigError
from ...fields import evaluate
from ...models import MLP
from ...train.task import Task
from .optics import exact_height, focus_distance
from .results import MirrorResults

__all__ = ["MirrorTask", "parse_mirror_params", "sample_rays"]


def parse_mirror_params(params: dict[str, Any] | MirrorParams | ShapeParams | None) -> MirrorParams:
    """Validate a mirror ``params`` mapping. Raises :class:`ConfigError` (one line naming ``params.<key>``)."""
    if isinstance(params, MirrorParams):
        return params
    if isinstance(params, ShapeParams):  # a config without a params group: the defaults
        return MirrorParams()
    return parse_task_params("mirror", params)


def sample_rays(p: MirrorParams, n: int, gen: torch.Generator, device, dtype) -> Tensor:
    """``n`` ray positions in ``[x_min, x_max]``, ``(n,)`` (``p.sampling`` decides how)."""
    u = torch.rand(n, generator=gen, dtype=dtype, device=gen.device).to(device)
    if p.sampling == "stratified":
        u = (torch.arange(n, dtype=dtype, device=device) + u) / n
    return p.x_min + (p.x_max - p.x_min) * u


# --- the task ---------------------------------------------------------------------------------


def _build_height_model(cfg: RunConfig) -> nn.Module:
    m = cfg.model
    if m.kind != "mlp":
        raise ConfigError(f"mirror: model.kind must be 'mlp', got {m.kind!r}")
    return MLP(1, list(m.hidden), activation=m.activation, beta=m.beta)


class MirrorTask(Task):
    """Train a height function ``h: [x_min, x_max] -> R`` whose mirror focuses vertical rays at ``(0, F)``.

    Loss terms: ``interface`` = ``h(0)^2`` (weight ``losses.interface``), ``reflection`` = mean squared
    distance from the focus to the reflected rays (weight ``params.reflection_weight``).
    Diagnostics: ``_max_abs_error`` against the exact parabola on the samples of the step.
    """

    kind = "mirror"

    def __init__(self, cfg: RunConfig, device: torch.device | str = "cpu", dtype: torch.dtype = torch.float32):
        super().__init__(cfg, torch.device(device), dtype)
        self.params = parse_mirror_params(cfg.params)

    def build_model(self) -> nn.Module:
        return _build_height_model(self.cfg).to(device=self.device, dtype=self.dtype)

    def terms(self) -> dict[str, LossTerm]:
        return {
            "interface": self.cfg.losses.interface,
            "reflection": LossTerm(weight=self.params.reflection_weight, start=self.params.reflection_start),
        }

    def loss_terms(self, model: nn.Module, step: int, active: set[str], gen: torch.Generator) -> dict[str, Tensor]:
        p = self.params
        out: dict[str, Tensor] = {}
        if "interface" in active:
            x0 = torch.zeros(1, 1, device=self.device, dtype=self.dtype)
            out["interface"] = model(x0, None).pow(2).mean()
        if "reflection" in active:
            x = sample_rays(p, p.n_samples, gen, self.device, self.dtype)
            v = evaluate(model, x[:, None], None, grad=True, create_graph=True)
            dist = focus_distance(v.x[:, 0], v.f, v.grad[:, 0], p.focus)
            out["reflection"] = dist.pow(2).mean()
            out["_max_abs_error"] = (v.f.detach() - exact_height(x, p.focus)).abs().max()
        return out

    @property
    def results(self) -> MirrorResults:
        return MirrorResults(self.params)
