"""Flat faces (``tolerances.faces``): inside each face's region the boundary faces along the
face's outward normal ``t`` within ``angle`` degrees, so that it is flat and parallel to the plane
with that normal (a mounting face, a face to clamp on).

Verdict: ``face_deviation``, the largest over the faces of the largest angle between the field's
unit normal and ``t`` at the area-uniform boundary points inside the face's region
(:func:`ginn.extract.curvature.boundary_points`), over the face's ``angle``: at most 1. A face
whose region holds no boundary is missing (infinite). ``face_angles`` lists each face's largest
angle in degrees.

Loss: at the surface samples inside each face's region, the mean of ``1 - n . t``, ``n`` the
field's unit normal, differentiable w.r.t. the parameters, summed over the faces (zero where a
region holds no sample).
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
from ..problems.problem import Problem
from .base import Constraint, Setting, Stage
from .batch import Batch
from .samples import DOMAIN
from .verdict import Verdict, Violation, number_text

__all__ = ["FlatFacesVerdict", "FlatFaces"]


class FlatFacesVerdict(Verdict):
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
        angles: list[float | None] = []
        for face in self.faces:
            with torch.no_grad():
                inside = face.region.contains(torch.as_tensor(x, dtype=torch.float64)).numpy() if len(x) else x[:0, 0] > 0
            if not inside.any():
                angles.append(None)
                continue
            cos = np.clip(n[inside] @ np.asarray(face.normal), -1.0, 1.0)
            angles.append(float(np.degrees(np.arccos(cos.min()))))
        ratios = [math.inf if a is None else a / f.angle for a, f in zip(angles, self.faces)]
        return {"face_deviation": max(ratios) if ratios else None, "face_angles": angles}

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
        return f"faces: normals {number_text(v.value)} times the allowed angle off"


class FlatFaces(Constraint):
    """The boundary flat along each face's normal inside its region (module docstring)."""

    name = "faces"
    stage = Stage.FIELD
    samples = (DOMAIN,)

    def __init__(self, setting: Setting):
        super().__init__(setting)
        self._verdict = FlatFacesVerdict(setting.problem)
        self.normals = [torch.tensor(f.normal, device=setting.device, dtype=setting.dtype) for f in self._verdict.faces]

    @property
    def verdict(self) -> FlatFacesVerdict:
        return self._verdict

    def loss(self, batch: Batch) -> Tensor | None:
        srf = batch.surface()
        p = srf.x.reshape(-1, batch.d)
        ok = srf.converged.reshape(-1)
        zs = None if batch.Z is None else batch.latents_of(srf.x)
        out = None
        for face, t in zip(self._verdict.faces, self.normals):
            with torch.no_grad():
                sel = ok & face.region.contains(p)
            if not bool(sel.any()):
                continue
            g = fields.evaluate(batch.model, p[sel], None if zs is None else zs[sel], grad=True, create_graph=True).grad
            n = g / g.norm(dim=-1, keepdim=True).clamp_min(1e-12)
            term = (1.0 - n @ t).mean()
            out = term if out is None else out + term
        return out

    def target(self) -> float:
        """0: every face along its normal."""
        return 0.0
