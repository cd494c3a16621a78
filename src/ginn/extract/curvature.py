"""The normals and curvatures of a field's zero level set at area-uniform points of its extracted
boundary.

The points are drawn by area on the level-set part of the boundary (not on the caps where the
domain cuts the shape), moved onto ``f = 0`` by two Newton steps of at most a grid cell, and the
normals (the field's unit gradient) and principal curvatures there come from the field (Hessians:
:func:`ginn.fields.principal_curvatures`; in 2D the curvature of the curve,
:func:`ginn.fields.mean_curvature`): exact for the field, where a mesh's discrete normals and
curvatures would depend on its triangles.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from .. import fields
from ..fields import Field
from ..levelset import project_to_zero
from .boundary import Boundary
from .sampling import field_dtype_device

__all__ = ["largest_curvature", "level_set_points", "boundary_points", "boundary_curvatures"]


def largest_curvature(grad: Tensor, hess: Tensor) -> Tensor:
    """The largest absolute principal curvature of the level set at each point, ``(m,)``: ``1 / r``
    on a circle or a sphere of radius ``r``, from its gradients ``(m, d)`` and Hessians ``(m, d, d)``."""
    if grad.shape[-1] == 2:
        return fields.mean_curvature(grad, hess).abs()
    return fields.principal_curvatures(grad, hess).abs().amax(dim=-1)


def level_set_points(field: Field, z: Tensor | None, boundary: Boundary, n_samples: int, rng: np.random.Generator,
                     step_cap: float | None, dtype: torch.dtype | None = None) -> tuple[Tensor, Tensor | None] | None:
    """``n_samples`` area-uniform points of the boundary's level-set part moved onto ``f = 0`` by
    two Newton steps of at most ``step_cap`` (a point whose projection fails keeps its place),
    ``(m, d)``, and their codes ``(m, k)`` (None without a latent); None when the boundary has no
    level-set part. In the field's dtype unless ``dtype`` is given."""
    x = boundary.sample(n_samples, rng, level_set_only=True)
    if x.shape[0] == 0:
        return None
    dt, dev = field_dtype_device(field, z)
    dt = dtype or dt
    xt = torch.as_tensor(x, dtype=dt, device=dev)
    zz = None if z is None else z.reshape(1, -1).to(dt).expand(xt.shape[0], -1)
    proj = project_to_zero(field, xt, zz, steps=2, tol=float("inf"), max_step=step_cap)
    return torch.where(torch.isfinite(proj.x).all(dim=1, keepdim=True), proj.x, xt), zz


def boundary_points(field: Field, z: Tensor | None, boundary: Boundary, n_samples: int = 2048,
                    rng: np.random.Generator | None = None, step_cap: float | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``n_samples`` area-uniform points on ``f = 0`` near ``boundary`` and the field's outward
    unit normal at each, ``(m, d)`` each, float64 (module docstring; empty when the boundary has no
    level-set part)."""
    on = level_set_points(field, z, boundary, n_samples, rng or np.random.default_rng(0), step_cap)
    if on is None:
        return np.zeros((0, boundary.dim)), np.zeros((0, boundary.dim))
    xp, zz = on
    g = fields.evaluate(field, xp, zz, grad=True, create_graph=False).grad
    n = g / g.norm(dim=-1, keepdim=True).clamp_min(1e-30)
    return xp.double().cpu().numpy(), n.double().cpu().numpy()


def boundary_curvatures(field: Field, z: Tensor | None, boundary: Boundary, n_samples: int = 2048,
                        rng: np.random.Generator | None = None, step_cap: float | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """``n_samples`` area-uniform points on ``f = 0`` near ``boundary`` and the largest absolute
    principal curvature at each, ``(m, d)`` and ``(m,)`` float64 (module docstring; empty when the
    boundary has no level-set part)."""
    on = level_set_points(field, z, boundary, n_samples, rng or np.random.default_rng(0), step_cap)
    if on is None:
        return np.zeros((0, boundary.dim)), np.zeros(0)
    xp, zz = on
    v = fields.evaluate(field, xp, zz, grad=False, hessian_at=True, create_graph=False)
    k = torch.nan_to_num(largest_curvature(v.hessian_grad, v.hessian), nan=float("inf"))
    return xp.double().cpu().numpy(), k.double().cpu().numpy()
