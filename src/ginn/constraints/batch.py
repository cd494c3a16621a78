"""One step's shared evaluation of the field: every sample set of every shape in one batched pass.

:meth:`Batch.draw` draws the sample sets the active constraints read (:mod:`ginn.constraints.samples`);
:meth:`Batch.evaluate` runs the main pass: one value-and-gradient pass over the sets with ``grad``
and one value-only pass over the rest, all shapes concatenated with their latent codes
(:func:`ginn.fields.broadcast_latents`), differentiable w.r.t. the parameters. What only some
constraints need is computed when one first asks, once per step:

* :meth:`Batch.surface`: per-shape points on ``f = 0``, the ``n_boundary`` domain samples with the
  smallest ``|f| / |grad f|``, moved by one Newton step with the main pass's values and gradients
  (no extra evaluation) and then by ``sampling.projection_steps`` further steps, which also check
  convergence (``_boundary_converged``, the share that did, is logged);
* :meth:`Batch.surface_hessians`: gradients and Hessians at the converged surface samples (one
  pass; the curvature and strain terms share it);
* :meth:`Batch.field_at`: values at fixed points every shape shares (the element centres of a
  structural problem, which its compliance and volume terms share).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor, nn

from .. import fields
from ..fields import FieldValues
from ..levelset import project_to_zero
from ..train.distributed import DistContext
from .base import Setting
from .samples import SampleSet

__all__ = ["Batch", "Surface"]


@dataclass
class Surface:
    """Points on the zero level set of every shape.

    Attributes:
        x: ``(S, m, d)`` (detached).
        converged: ``(S, m)``: whether the projection of each point converged.
    """

    x: Tensor
    converged: Tensor


class Batch:
    """The samples of one step and the field's values and gradients there.

    Attributes:
        setting: the problem and configuration.
        model: the field ``(x, z) -> (n,)``.
        Z: the step's latent codes ``(S, k)``, or None for a single shape.
        S: the number of shapes.
        x: the drawn points of each set, ``{name: (S, n, d)}``.
        attrs: per-point attributes of the sets (``normals`` of the interface samples), ``(S, n, ...)``.
        f: values after :meth:`evaluate`, ``{name: (S, n)}``.
        g: gradients of the sets with ``grad``, ``{name: (S, n, d)}``.
        step: the iteration.
        dist: the data-parallel context when the shapes are sharded over ranks (None otherwise).
        diagnostics: values logged beside the losses (names starting with ``_``).
    """

    def __init__(self, setting: Setting, x: dict[str, Tensor], attrs: dict[str, Tensor], sets: dict[str, SampleSet],
                 Z: Tensor | None, step: int = 0):
        self.setting = setting
        self.x, self.attrs, self.sets = x, attrs, sets
        self.Z = Z
        self.step = step
        self.model: nn.Module | None = None
        self.dist: DistContext | None = None
        self.f: dict[str, Tensor] = {}
        self.g: dict[str, Tensor] = {}
        self.diagnostics: dict[str, Tensor] = {}
        self._surface: Surface | None = None
        self._hessians: tuple[FieldValues, Tensor] | None = None
        self._at: dict[str, Tensor] = {}

    @property
    def S(self) -> int:
        return 1 if self.Z is None else int(self.Z.shape[0])

    @property
    def d(self) -> int:
        return self.setting.dim

    @classmethod
    def draw(cls, setting: Setting, sets: list[SampleSet], S: int, Z: Tensor | None, gen: torch.Generator,
             step: int = 0) -> Batch:
        """Draw ``sets`` (in draw order) for ``S`` shapes with latent codes ``Z``."""
        x: dict[str, Tensor] = {}
        attrs: dict[str, Tensor] = {}
        for s in sorted(sets, key=lambda s: s.draw_rank):
            x[s.name], extra = s.draw(setting, S, gen)
            attrs.update(extra)
        return cls(setting, x, attrs, {s.name: s for s in sets}, Z, step)

    def shard(self, lo: int, hi: int) -> None:
        """Keep the shapes ``lo:hi`` only (data parallelism: every rank draws all shapes)."""
        self.Z = self.Z[lo:hi]
        self.x = {k: v[lo:hi] for k, v in self.x.items()}
        self.attrs = {k: v[lo:hi] for k, v in self.attrs.items()}

    def evaluate(self, model: nn.Module) -> None:
        """The main pass: values and gradients of the sets with ``grad``, values of the others."""
        self.model = model
        grad_sets = sorted((s for s in self.sets.values() if s.grad and s.name in self.x), key=lambda s: s.pass_rank)
        value_sets = sorted((s for s in self.sets.values() if not s.grad and s.name in self.x), key=lambda s: s.pass_rank)
        self.f, self.g = self._pass([s.name for s in grad_sets], grad=True)
        self.f.update(self._pass([s.name for s in value_sets], grad=False)[0])

    def _pass(self, names: list[str], grad: bool) -> tuple[dict[str, Tensor], dict[str, Tensor]]:
        """One batched evaluation of the sets ``names`` (each ``(S, n_k, d)``): their values
        ``(S, n_k)`` and, with ``grad``, gradients ``(S, n_k, d)``, differentiable w.r.t. the
        parameters."""
        if not names:
            return {}, {}
        sizes = [self.x[k].shape[1] for k in names]
        X = torch.cat([self.x[k] for k in names], dim=1)  # (S, N, d)
        S, N = X.shape[:2]
        Xf, Zf = (X.reshape(-1, self.d), None) if self.Z is None else fields.broadcast_latents(X, self.Z)
        v = fields.evaluate(self.model, Xf, Zf, grad=grad, create_graph=True)
        f = dict(zip(names, torch.split(v.f.reshape(S, N), sizes, dim=1)))
        if not grad:
            return f, {}
        return f, dict(zip(names, torch.split(v.grad.reshape(S, N, self.d), sizes, dim=1)))

    def field_at(self, key: str, x: Tensor) -> Tensor:
        """The field of every shape at the points ``x (n, d)`` that all shapes share, ``(S, n)``,
        differentiable w.r.t. the parameters; evaluated at the first call with ``key`` in a step."""
        if key not in self._at:
            Xf, Zf = (x, None) if self.Z is None else fields.broadcast_latents(x, self.Z)
            v = fields.evaluate(self.model, Xf, Zf, grad=False, create_graph=True)
            self._at[key] = v.f.reshape(self.S, -1)
        return self._at[key]

    def latents_of(self, x: Tensor) -> Tensor | None:
        """The latent code of every point of per-shape points ``x (S, m, d)``, flattened
        shape-major to ``(S * m, k)`` (None for a single shape)."""
        if self.Z is None:
            return None
        return self.Z[:, None, :].expand(*x.shape[:2], self.Z.shape[-1]).reshape(-1, self.Z.shape[-1])

    def surface(self) -> Surface:
        """Points on ``f = 0`` per shape (see the module docstring), computed at the first call."""
        if self._surface is None:
            self._surface = self._project()
            self.diagnostics["_boundary_converged"] = self._surface.converged.float().mean()
        return self._surface

    def _project(self) -> Surface:
        xd, fd, gd = self.x["domain"], self.f["domain"], self.g["domain"]
        S, d = xd.shape[0], self.d
        m = min(self.setting.cfg.sampling.n_boundary, xd.shape[1])
        with torch.no_grad():
            fd, gd = fd.detach(), gd.detach()
            g2 = (gd * gd).sum(-1).clamp_min(1e-12)
            dist = fd.abs() / g2.sqrt()
            idx = dist.topk(m, dim=1, largest=False).indices  # (S, m)
            take = lambda t: torch.gather(t, 1, idx[:, :, None].expand(S, m, t.shape[-1]))  # noqa: E731
            step = (fd / g2)[:, :, None] * gd
            x0 = take(xd.detach() - step)
        X = x0.reshape(-1, d)
        Zf = None if self.Z is None else fields.broadcast_latents(x0, self.Z)[1]
        # converged within a thousandth of the problem's length scale (absolute, a problem drawn in
        # other units would keep other samples)
        tol = 1e-3 * self.setting.scale
        lo, hi = self.setting.problem.domain.tensors(self.setting.device, self.setting.dtype)
        proj = project_to_zero(self.model, X, Zf, steps=self.setting.cfg.sampling.projection_steps, tol=tol, bounds=(lo, hi))
        return Surface(proj.x.reshape(S, m, d), proj.converged.reshape(S, m))

    def surface_hessians(self) -> tuple[FieldValues, Tensor]:
        """The field at the surface samples with gradients ``hessian_grad (q, d)`` and Hessians
        ``hessian (q, d, d)`` at the converged ones (``hessian_index``), differentiable, and the
        flattened points ``(S * m, d)``; one pass, at the first call."""
        if self._hessians is None:
            srf = self.surface()
            Xf = srf.x.reshape(-1, self.d)
            v = fields.evaluate(self.model, Xf, self.latents_of(srf.x), grad=False, hessian_at=srf.converged.reshape(-1),
                                create_graph=True)
            self._hessians = (v, Xf)
        return self._hessians
