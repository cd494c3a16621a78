"""The point sets a step draws for its constraints: fresh Monte Carlo samples per shape.

A :class:`SampleSet` draws ``(S, n, d)`` points for ``S`` shapes from the step's generator. A step
draws every set an active constraint reads (and the sets marked ``always``), in the order of
their ``draw_rank`` (that order fixes the random stream, so it is part of what makes a run
reproducible), and evaluates them in one batched pass per kind: the sets with ``grad`` (values
and gradients, in the order of their ``pass_rank``, which fixes the rows of the batch) and the
others (values only: a value-only pass is about a third of a value-and-gradient one).

The built-in sets, in draw order:

==============  =====  ===========================================================================
set             grad   points per shape (``sampling.*``)
==============  =====  ===========================================================================
``DOMAIN``      yes    ``n_domain`` uniform in X (eikonal; the pool of the surface samples); always
``OUTSIDE``     no     ``n_outside`` uniform in X \\ E (design region)
``OBSTACLE``    no     ``n_obstacle`` inside the obstacles, split evenly among them
``INTERFACE``   yes    ``n_interface`` on the interfaces, with the prescribed normals (``normals``)
``BAND``        yes    ``n_band`` in a band of ``interface_band`` around the interfaces (eikonal);
                       always, when the problem has a band
==============  =====  ===========================================================================

A new set is a subclass with a ``draw`` method; a constraint that lists it gets its points in
``batch.x[name]``, its values in ``batch.f[name]`` (and gradients in ``batch.g[name]``).
"""

from __future__ import annotations

from typing import ClassVar

import torch
from torch import Tensor

from ..geometry import sampling
from .base import Setting

__all__ = ["SampleSet", "DOMAIN", "OUTSIDE", "OBSTACLE", "INTERFACE", "BAND", "BUILTIN_SETS"]


class SampleSet:
    """A set of points drawn per shape at every step.

    Class attributes: ``name`` (its key in the batch), ``grad`` (evaluated with gradients),
    ``draw_rank`` and ``pass_rank`` (orders of drawing and of the rows of the main pass; a new
    set goes after the built-in ones), ``always`` (drawn whether or not an active constraint
    reads it).
    """

    name: ClassVar[str]
    grad: ClassVar[bool] = True
    draw_rank: ClassVar[int] = 100
    pass_rank: ClassVar[int] = 100
    always: ClassVar[bool] = False

    def available(self, setting: Setting) -> bool:
        """Whether the problem and the point budgets give this set any points."""
        return True

    def draw(self, setting: Setting, S: int, gen: torch.Generator) -> tuple[Tensor, dict[str, Tensor]]:
        """Points ``(S, n, d)`` and named per-point attributes ``{name: (S, n, ...)}``."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def _perm(n: int, gen: torch.Generator, device: torch.device) -> Tensor:
    return torch.randperm(n, generator=gen, device=gen.device).to(device)


class _Domain(SampleSet):
    name, grad, draw_rank, pass_rank, always = "domain", True, 0, 0, True

    def draw(self, setting: Setting, S: int, gen: torch.Generator) -> tuple[Tensor, dict[str, Tensor]]:
        s = setting.cfg.sampling
        x = sampling.sample_box(setting.problem.domain, S * s.n_domain, gen, device=setting.device, dtype=setting.dtype)
        return x.reshape(S, -1, setting.dim), {}


class _Outside(SampleSet):
    name, grad, draw_rank, pass_rank = "outside", False, 1, 0

    def available(self, setting: Setting) -> bool:
        return setting.cfg.sampling.n_outside > 0 and setting.problem.design_region is not None

    def draw(self, setting: Setting, S: int, gen: torch.Generator) -> tuple[Tensor, dict[str, Tensor]]:
        n = S * setting.cfg.sampling.n_outside
        x = sampling.sample_outside(setting.membership, setting.problem.domain, n, gen, device=setting.device,
                                    dtype=setting.dtype)
        return x.reshape(S, -1, setting.dim), {}


class _Obstacle(SampleSet):
    name, grad, draw_rank, pass_rank = "obstacle", False, 2, 1

    def available(self, setting: Setting) -> bool:
        return setting.cfg.sampling.n_obstacle > 0 and bool(setting.problem.obstacles)

    def draw(self, setting: Setting, S: int, gen: torch.Generator) -> tuple[Tensor, dict[str, Tensor]]:
        p, d = setting.problem, setting.dim
        # split among the obstacles per shape, so that every shape gets the same number
        per = max(1, setting.cfg.sampling.n_obstacle // len(p.obstacles))
        obs = [sampling.sample_inside(o, p.domain, S * per, gen, device=setting.device, dtype=setting.dtype)
               for o in p.obstacles]
        return torch.cat([o.reshape(S, -1, d) for o in obs], dim=1), {}


class _Interface(SampleSet):
    name, grad, draw_rank, pass_rank = "interface", True, 3, 2

    def available(self, setting: Setting) -> bool:
        return bool(setting.problem.interfaces)

    def draw(self, setting: Setting, S: int, gen: torch.Generator) -> tuple[Tensor, dict[str, Tensor]]:
        d = setting.dim
        xi, ni = sampling.sample_interfaces(setting.problem.interfaces, S * setting.cfg.sampling.n_interface, gen,
                                            device=setting.device, dtype=setting.dtype)
        # the samplers return points grouped interface by interface: shuffle before splitting
        # them among the shapes, or each shape would see only some of the interfaces
        perm = _perm(xi.shape[0], gen, setting.device)
        return xi[perm].reshape(S, -1, d), {"normals": ni[perm].reshape(S, -1, d)}


class _Band(SampleSet):
    name, grad, draw_rank, pass_rank, always = "band", True, 4, 1, True

    def available(self, setting: Setting) -> bool:
        p = setting.problem
        return setting.cfg.sampling.n_band > 0 and bool(p.interfaces) and p.interface_band > 0

    def draw(self, setting: Setting, S: int, gen: torch.Generator) -> tuple[Tensor, dict[str, Tensor]]:
        p = setting.problem
        xb = sampling.sample_band(p.interfaces, S * setting.cfg.sampling.n_band, p.interface_band, gen, box=p.domain,
                                  device=setting.device, dtype=setting.dtype)
        return xb[_perm(xb.shape[0], gen, setting.device)].reshape(S, -1, setting.dim), {}


DOMAIN, OUTSIDE, OBSTACLE, INTERFACE, BAND = _Domain(), _Outside(), _Obstacle(), _Interface(), _Band()

#: the built-in sets in draw order
BUILTIN_SETS: tuple[SampleSet, ...] = (DOMAIN, OUTSIDE, OBSTACLE, INTERFACE, BAND)
