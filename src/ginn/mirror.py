"""The parabolic mirror (paper Section 4.1, Appendix A.3): a GINN for an explicit height function.

A mirror is the graph of a height function ``h: [-1, 1] -> R``. Vertical rays come down (direction
``(0, -1)``), hit the mirror at ``P = (x, h(x))`` and reflect about the unit normal
``n = (-h', 1) / sqrt(1 + h'^2)``. The reflected direction is

    r = d - 2 (d . n) n = (-2 h', 1 - h'^2) / (1 + h'^2)        (a unit vector),

and the distance from the focus ``Q = (0, F)`` to the line ``P + t r`` is the 2D cross product

    dist(x) = |(Q - P) x r| = |2 h' (F - h) - x (1 - h'^2)| / (1 + h'^2).

The constraints are ``h(0) = 0`` (interface) and ``dist(x) = 0`` for every ``x`` (optics). The unique
solution is the parabola ``h = x^2 / (4 F)``: with ``h' = x / (2F)`` the numerator vanishes identically.

Model input width: the paper lists ``[2, 40, 40, 1]`` without explaining the second input; a height
function of one variable has one input, so we use ``MLP(1, [40, 40], activation="tanh")``.

Public names: :class:`MirrorParams`, :func:`parse_mirror_params`, :func:`reflected_direction`,
:func:`focus_distance`, :func:`reflection_residual`, :func:`exact_height`, :class:`MirrorTask`,
:func:`evaluate_mirror`, :func:`plot_mirror`, :func:`write_profile`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from torch import Tensor, nn

from .errors import ConfigError
from .fields import evaluate, value
from .models import MLP
from .train.config import LossTerm, RunConfig
from .train.task import Task


# --- parameters ----------------------------------------------------------------------------------


class MirrorParams(BaseModel):
    """Task parameters of the mirror (``RunConfig.params``).

    Attributes:
        focus: height ``F > 0`` of the focus ``(0, F)``; the exact mirror is ``x^2 / (4 F)``.
        x_min, x_max: the aperture ``[x_min, x_max]`` (paper: ``[-1, 1]``).
        n_samples: ray positions per iteration.
        sampling: ``uniform`` (i.i.d. uniform) or ``stratified`` (one uniform point per equal cell,
            which always covers the ends of the aperture).
        reflection_weight: weight of the optics loss (the interface weight is
            ``losses.interface.weight``).
        reflection_start: first iteration of the optics loss.
        n_eval: grid points for the error against the exact parabola.
        n_rays_plot: rays drawn in the figure.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    focus: float = Field(1.0, gt=0)
    x_min: float = -1.0
    x_max: float = 1.0
    n_samples: int = Field(256, gt=0)
    sampling: Literal["uniform", "stratified"] = "stratified"
    reflection_weight: float = Field(1.0, ge=0)
    reflection_start: int = Field(0, ge=0)
    n_eval: int = Field(2001, ge=2)
    n_rays_plot: int = Field(15, ge=1)

    @model_validator(mode="after")
    def _aperture(self) -> "MirrorParams":
        if not self.x_min < self.x_max:
            raise ValueError("x_min must be smaller than x_max")
        return self


def parse_mirror_params(params: dict[str, Any] | MirrorParams | None) -> MirrorParams:
    """Validate ``RunConfig.params`` for the mirror. Raises :class:`ConfigError` (one line)."""
    if isinstance(params, MirrorParams):
        return params
    try:
        return MirrorParams.model_validate(dict(params or {}))
    except ValidationError as e:
        err = e.errors()[0]
        path = ".".join(str(p) for p in err.get("loc", ()))
        msg = "unknown key" if err.get("type") == "extra_forbidden" else err.get("msg", "invalid value")
        where = f"params.{path}" if path else "params"
        raise ConfigError(f"mirror config field '{where}': {msg}") from None


# --- the optics -----------------------------------------------------------------------------------


def exact_height(x: Tensor, focus: float) -> Tensor:
    """The exact mirror ``x^2 / (4 F)``, ``(n,) -> (n,)``."""
    return x * x / (4.0 * focus)


def reflected_direction(dh: Tensor) -> Tensor:
    """Unit direction of a vertical ray ``(0, -1)`` reflected at a mirror of slope ``dh``: ``(n,) -> (n, 2)``."""
    q = 1.0 + dh * dh
    return torch.stack([-2.0 * dh / q, (1.0 - dh * dh) / q], dim=-1)


def focus_distance(x: Tensor, h: Tensor, dh: Tensor, focus: float) -> Tensor:
    """Signed distance from the focus ``(0, F)`` to each reflected ray (as a line), ``(n,)``.

    Arguments:
        x: ray positions ``(n,)``; h: heights ``h(x)`` ``(n,)``; dh: slopes ``h'(x)`` ``(n,)``.
        focus: ``F``.
    """
    return (2.0 * dh * (focus - h) - x * (1.0 - dh * dh)) / (1.0 + dh * dh)


def reflection_residual(model: nn.Module, x: Tensor, focus: float, create_graph: bool = True) -> Tensor:
    """``focus_distance`` of the mirror ``h = model`` at ray positions ``x`` ``(n,)`` -> ``(n,)``.

    ``h`` and ``h'`` come from :func:`ginn.fields.evaluate` (the one derivative engine).
    """
    v = evaluate(model, x[:, None], None, grad=True, create_graph=create_graph)
    return focus_distance(v.x[:, 0], v.f, v.grad[:, 0], focus)


def sample_rays(p: MirrorParams, n: int, gen: torch.Generator, device, dtype) -> Tensor:
    """``n`` ray positions in ``[x_min, x_max]``, ``(n,)`` (``p.sampling`` decides how)."""
    u = torch.rand(n, generator=gen, dtype=dtype).to(device)
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

    def finalize(self, model: nn.Module, run_dir: Path) -> list[Path]:
        run_dir = Path(run_dir)
        run_dir.mkdir(parents=True, exist_ok=True)
        paths = write_profile(model, self.params, run_dir)
        paths.append(plot_mirror(model, self.params, run_dir / "mirror.png"))
        return paths


# --- evaluation and output ------------------------------------------------------------------------


def _profile(model: nn.Module, p: MirrorParams, n: int) -> tuple[np.ndarray, np.ndarray]:
    par = next(model.parameters(), None)
    dtype = par.dtype if par is not None else torch.float32
    device = par.device if par is not None else torch.device("cpu")
    x = torch.linspace(p.x_min, p.x_max, n, dtype=dtype, device=device)
    h = value(model, x[:, None], None)
    return x.cpu().double().numpy(), h.cpu().double().numpy()


def evaluate_mirror(model: nn.Module, params: dict[str, Any] | MirrorParams | None = None) -> dict[str, float]:
    """Errors of a trained mirror against the exact parabola on a grid of ``params.n_eval`` points.

    Returns:
        ``max_abs_error_vs_exact`` (max ``|h - x^2/(4F)|``), ``rms_error_vs_exact``, ``interface_error``
        (``|h(0)|``) and ``max_focus_distance`` (max distance from the focus to a reflected ray).
    """
    p = parse_mirror_params(params)
    x, h = _profile(model, p, p.n_eval)
    err = h - x * x / (4.0 * p.focus)
    par = next(model.parameters())
    xt = torch.as_tensor(x, dtype=par.dtype, device=par.device)
    dist = reflection_residual(model, xt, p.focus, create_graph=False)
    h0 = value(model, torch.zeros(1, 1, dtype=par.dtype, device=par.device), None)
    return {
        "max_abs_error_vs_exact": float(np.abs(err).max()),
        "rms_error_vs_exact": float(np.sqrt(np.mean(err * err))),
        "interface_error": float(h0.abs().item()),
        "max_focus_distance": float(dist.abs().max().item()),
    }


def write_profile(model: nn.Module, params: dict[str, Any] | MirrorParams | None, run_dir: Path) -> list[Path]:
    """Write the profile ``x, h(x), x^2/(4F)`` as ``mirror_profile.csv`` and ``mirror_profile.npy`` ``(n, 3)``."""
    p = parse_mirror_params(params)
    x, h = _profile(model, p, p.n_eval)
    table = np.stack([x, h, x * x / (4.0 * p.focus)], axis=1)
    run_dir = Path(run_dir)
    csv, npy = run_dir / "mirror_profile.csv", run_dir / "mirror_profile.npy"
    np.savetxt(csv, table, delimiter=",", header="x,h,exact", comments="")
    np.save(npy, table)
    return [csv, npy]


def plot_mirror(model: nn.Module, params: dict[str, Any] | MirrorParams | None, path: Path) -> Path:
    """Figure 1 (top row): the mirror, incoming vertical rays and their reflections, and the focus."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = parse_mirror_params(params)
    x, h = _profile(model, p, 400)
    par = next(model.parameters())
    xr = torch.linspace(p.x_min, p.x_max, p.n_rays_plot + 2, dtype=par.dtype, device=par.device)[1:-1]
    v = evaluate(model, xr[:, None], None, grad=True, create_graph=False)
    hr = v.f.cpu().double().numpy()
    r = reflected_direction(v.grad[:, 0]).cpu().double().numpy()
    xr_np = xr.cpu().double().numpy()
    top = max(p.focus * 1.6, float(h.max()) + 0.5)

    fig, ax = plt.subplots(figsize=(5, 5))
    for xi, hi, ri in zip(xr_np, hr, r):
        ax.plot([xi, xi], [top, hi], color="0.6", lw=0.8)
        # reflected ray, continued until it passes the focus height (or a fixed length)
        t = (p.focus - hi) / ri[1] * 1.3 if ri[1] > 1e-6 else 2.0 * p.focus
        ax.plot([xi, xi + t * ri[0]], [hi, hi + t * ri[1]], color="tab:orange", lw=0.8)
    ax.plot(x, x * x / (4 * p.focus), "k--", lw=0.8, label="exact $x^2/4F$")
    ax.plot(x, h, color="tab:blue", lw=2, label="GINN mirror")
    ax.plot([0], [p.focus], "r*", ms=10, label="focus")
    ax.set_aspect("equal")
    ax.set_xlim(p.x_min - 0.1, p.x_max + 0.1)
    ax.set_ylim(min(float(h.min()), 0.0) - 0.1, top)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=3, fontsize=8, frameon=False)
    ax.set_title("parabolic mirror")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
