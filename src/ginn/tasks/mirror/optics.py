"""The parabolic mirror (paper Section 4.1, Appendix A.3): a GINN for an explicit height function.

A mirror is the graph of a height function ``h: [-1, 1] -> R``. Vertical rays come down (direction
``(0, -1)``), hit the mirror at ``P = (x, h(x))`` and reflect about the unit normal
``n = (-h', 1) / sqrt(1 + h'^2)``. The reflected direction is

    r = d - 2 (d . n) n = (-2 h', 1 - h'^2) / (1 + h'^2)        (a unit vector),

and the distance from the focus ``Q = (0, F)`` to the line ``P + t r`` is the 2D cross product

    dist(x) = |(Q - P) x r| = |2 h' (F - h) - x (1 - h'^2)| / (1 + h'^2).

The constraints are ``h(0) = 0`` (interface) and ``dist(x) = 0`` for every ``x`` (optics). The unique
solution is the parabola ``h = x^2 / (4 F)``: with ``h' = x / (2F)`` the numerator vanishes identically.

This module holds the optics (used by the training loss of :class:`ginn.tasks.mirror.MirrorTask`
as well) and the evaluation of a trained mirror against the exact parabola.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor, nn

from ...config import MirrorParams, parse_task_params
from ...fields import evaluate, value

__all__ = ["exact_height", "reflected_direction", "focus_distance", "reflection_residual", "profile", "evaluate_mirror"]


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


def profile(model: nn.Module, p: MirrorParams, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The trained height ``h`` on ``n`` equally spaced points of the aperture: ``(x, h)``, float64 arrays."""
    par = next(model.parameters(), None)
    dtype = par.dtype if par is not None else torch.float32
    device = par.device if par is not None else torch.device("cpu")
    x = torch.linspace(p.x_min, p.x_max, n, dtype=dtype, device=device)
    h = value(model, x[:, None], None)
    return x.cpu().double().numpy(), h.cpu().double().numpy()


def evaluate_mirror(model: nn.Module, params: MirrorParams | dict | None = None) -> dict[str, float]:
    """Errors of a trained mirror against the exact parabola on a grid of ``params.n_eval`` points.

    Returns:
        ``max_abs_error_vs_exact`` (max ``|h - x^2/(4F)|``), ``rms_error_vs_exact``, ``interface_error``
        (``|h(0)|``) and ``max_focus_distance`` (max distance from the focus to a reflected ray).
    """
    p = params if isinstance(params, MirrorParams) else parse_task_params("mirror", params)
    x, h = profile(model, p, p.n_eval)
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
