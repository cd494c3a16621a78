"""Prescribed faces (``tolerances.faces``): inside each face's region the boundary is

* flat: its outward normal within ``angle`` degrees of the face's normal ``t``, so that it is flat
  and parallel to the plane with that normal (a mounting face, a face to clamp on); or
* on a surface: within ``distance`` of the boundary of the face's ``surface`` region, its normal
  within ``angle`` degrees of that surface's unit normal ``nu`` either way round, so that it lies on
  the surface, tangent to it (a seat on a pipe, a face wrapped round a boss).

``nu`` is the normalised gradient of the surface region's signed distance ``s``, by central
differences (every region kind, meshes included, without a differentiable distance).

Verdict: ``face_deviation``, the largest over the faces of the largest ratio of a measure to its
bound at the area-uniform boundary points inside the face's region
(:func:`ginn.extract.curvature.boundary_points`): the angle between the field's unit normal and
``t`` (or ``nu``) over ``angle``, and for a face on a surface ``|s|`` over ``distance``; at most 1.
A face whose region holds no boundary is missing (infinite). ``face_angles`` lists each face's
largest angle in degrees, ``face_distances`` each face's largest ``|s|`` (``None`` for flat faces).

Loss, summed over the faces, at the surface samples inside each face's region (zero where a
region holds no sample), ``n`` the field's unit normal, differentiable w.r.t. the parameters:

* flat: the mean of ``1 - n . t``;
* on a surface: the mean of ``1 - |n . nu|`` plus ``(1 - cos angle)`` times the mean of
  ``(s_1 / distance)^2``, where ``s_1 = s - f (nu . grad f) / |grad f|^2`` is ``s`` at the point
  moved with the zero set to first order (``f = 0`` there, but its derivative w.r.t. the
  parameters is the boundary's motion). Both parts equal ``1 - cos angle`` at their bounds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from torch import Tensor

from .. import fields
from ..extract.curvature import boundary_points
from ..geometry.base import Region
from ..problems.problem import Problem
from .base import Constraint, Setting, Stage
from .batch import Batch
from .samples import DOMAIN
from .verdict import Verdict, Violation, number_text

__all__ = ["FacesVerdict", "Faces", "surface_distance"]


def surface_distance(surface: Region, x: Tensor, step: float) -> tuple[Tensor, Tensor]:
    """The signed distance of ``surface`` at ``x (m, d)`` and its unit normal (the normalised
    gradient by central differences of step ``step``), ``(m,)`` and ``(m, d)``, float64, no
    gradient."""
    with torch.no_grad():
        xd = x.detach().to(torch.float64)
        m, d = xd.shape
        e = step * torch.eye(d, dtype=xd.dtype, device=xd.device)
        probes = torch.cat([xd, (xd[:, None, :] + e).reshape(-1, d), (xd[:, None, :] - e).reshape(-1, d)])
        v = surface.sdf(probes).to(torch.float64)
        g = (v[m:m + m * d] - v[m + m * d:]).reshape(m, d) / (2.0 * step)
        return v[:m], g / g.norm(dim=-1, keepdim=True).clamp_min(1e-30)


def _step(problem: Problem) -> float:
    """The central-difference step of :func:`surface_distance`: a millionth of the unit scale."""
    return 1e-6 * float(problem.unit_scale)


class FacesVerdict(Verdict):
    """``face_deviation`` at most 1 (module docstring)."""

    name = "faces"
    #: area-uniform boundary points per shape
    n_samples = 4096

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("face_deviation",)
        self.faces = problem.tolerances.faces

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        x, n = boundary_points(field, z, shape.boundary, self.n_samples, np.random.default_rng(0),
                               step_cap=float(context.grid.spacing.max()))
        xt = torch.as_tensor(x, dtype=torch.float64)
        angles: list[float | None] = []
        distances: list[float | None] = []
        ratios: list[float] = []
        for face in self.faces:
            with torch.no_grad():
                inside = face.region.contains(xt).numpy() if len(x) else x[:0, 0] > 0
            if not inside.any():
                angles.append(None)
                distances.append(None)
                ratios.append(math.inf)
                continue
            if face.surface is None:
                cos = n[inside] @ np.asarray(face.normal)
                dist = None
            else:
                s, nu = surface_distance(face.surface, xt[inside], _step(self.problem))
                cos = np.abs(np.einsum("md,md->m", n[inside], nu.numpy()))
                dist = float(s.abs().max())
            angle = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0).min())))
            angles.append(angle)
            distances.append(dist)
            ratios.append(max(angle / face.angle, 0.0 if dist is None else dist / face.distance))
        return {"face_deviation": max(ratios) if ratios else None, "face_angles": angles,
                "face_distances": distances}

    def violation(self, metrics: Mapping) -> Violation | None:
        v = metrics.get("face_deviation")
        if v is None or v <= 1.0:
            return None
        return Violation(float(v), 1.0)

    def ratio(self, metrics: Mapping) -> float | None:
        v = metrics.get("face_deviation")
        return None if v is None else float(v)

    @classmethod
    def describe(cls, v: Violation) -> str:
        if math.isinf(v.value):
            return "faces: a face's region holds no boundary"
        return f"faces: {number_text(v.value)} times the allowed angle or distance off"


class Faces(Constraint):
    """The boundary flat along each face's normal, or on each face's surface, inside its region
    (module docstring)."""

    name = "faces"
    stage = Stage.FIELD
    samples = (DOMAIN,)

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = FacesVerdict(setting.problem)
        self.normals = [None if f.normal is None else torch.tensor(f.normal, device=setting.device, dtype=setting.dtype)
                        for f in self._verdict.faces]

    @property
    def verdict(self) -> FacesVerdict:
        return self._verdict

    def loss(self, batch: Batch) -> Tensor | None:
        srf = batch.surface()
        p = srf.x.reshape(-1, batch.d)
        ok = srf.converged.reshape(-1)
        with torch.no_grad():
            sels = [ok & face.region.contains(p) for face in self._verdict.faces]
        if not any(bool(sel.any()) for sel in sels):
            return None
        # every sample, each face's own masked: one shape of call per run (a compiled SIREN's
        # kernels are made per shape of input, and a face's share of the samples varies by step)
        zs = None if batch.Z is None else batch.latents_of(srf.x)
        v = fields.evaluate(batch.model, p, zs, grad=True, create_graph=True)
        n = v.grad / v.grad.norm(dim=-1, keepdim=True).clamp_min(1e-12)
        g2 = (v.grad * v.grad).sum(-1).clamp_min(1e-24)
        out = None
        for face, t, sel in zip(self._verdict.faces, self.normals, sels):
            count = int(sel.sum())
            if count == 0:
                continue
            if t is not None:
                term = torch.where(sel, 1.0 - n @ t, 0.0).sum() / count
            else:
                s, nu = surface_distance(face.surface, p, _step(batch.setting.problem))
                s, nu = torch.where(sel, s.to(v.grad.dtype), 0.0), nu.to(v.grad.dtype)
                s1 = s - v.f * (nu * v.grad).sum(-1) / g2
                term = (torch.where(sel, 1.0 - (n * nu).sum(-1).abs(), 0.0).sum()
                        + (1.0 - math.cos(math.radians(face.angle))) * torch.where(sel, (s1 / face.distance) ** 2, 0.0).sum()) / count
            out = term if out is None else out + term
        return out

    def target(self) -> float:
        """0: every face along its normal."""
        return 0.0
