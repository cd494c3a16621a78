"""The task of a shape problem (obstacle, bracket, Plateau, user specs): its constraints, trained
from one shared evaluation per step.

Per step the task draws the latent codes, then fresh samples of the sets its active constraints
read (:mod:`ginn.constraints.samples`), evaluates every shape and every set in one batched pass
(:class:`ginn.constraints.Batch`), and asks each active constraint for its loss, stage by stage
(:class:`ginn.constraints.Stage`); Hessians are taken only at the surface samples, when a
curvature term asks. Its plug-in checks feasibility during training
(:mod:`ginn.tasks.shape.checks`); :class:`~ginn.tasks.shape.results.ShapeResults` evaluates,
exports and draws the trained model.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from torch import Tensor, nn

from ...config import HELDOUT_LATENTS, HELDOUT_PER_SHAPE, MIN_STEP_CODES, LossTerm, RunConfig
from ...constraints import BUILTIN_SETS, Batch, Constraint, SampleSet, Setting, Verdict, shape_constraints, verdicts_of
from ...errors import ConfigError, SpecError
from ...eval.feasibility import FeasibilityCheck, check_resolution
from ...eval.plateau import ReferenceVerdict
from ...geometry.base import Region
from ...models.factory import build_model
from ...models.frame import DomainFrame
from ...models.latents import fixed_latents, heldout_latents, latent_dim, step_codes, step_latents
from ...models.symmetric import FOLD_SMOOTHING, SymmetricField
from ...problems.derived import length_scale
from ...problems.problem import Problem
from ...train.balancing import Balance
from ...train.callbacks import Callback
from ...train.distributed import DistContext
from ...train.task import Task
from .checks import FeasibilityChecks
from .results import ShapeResults

__all__ = ["ShapeTask", "spread_sampling"]


def spread_sampling(cfg: RunConfig, codes: int) -> RunConfig:
    """``cfg`` with the per-shape sample counts of a step that trains ``codes`` codes: the samples
    of the ``n_shapes`` reported shapes (``sampling.n_*`` each) spread over the codes, ``round(n
    * n_shapes / codes)`` each and at least 1 (``cfg`` itself when ``codes == n_shapes``). A step
    estimates the loss averaged over ``Z x X``; with its samples fixed in number, more codes
    estimate the average over ``Z`` better (:data:`ginn.config.MIN_STEP_CODES`)."""
    S = cfg.latents.n_shapes
    if codes == S:
        return cfg
    s = cfg.sampling
    counts = {k: (max(1, round(getattr(s, k) * S / codes)) if getattr(s, k) > 0 else 0)
              for k in ("n_domain", "n_outside", "n_obstacle", "n_interface", "n_band", "n_boundary")}
    return cfg.model_copy(update={"sampling": s.model_copy(update=counts)})


class ShapeTask(Task):
    """A GINN shape problem: a (generative) implicit shape trained from constraints.

    Arguments:
        problem: the geometry (domain, design region, interfaces, obstacles).
        cfg, device, dtype: see :class:`ginn.train.task.Task`.
        extra: further constraints, each made from the task's :class:`~ginn.constraints.Setting`
            (a :class:`~ginn.constraints.Constraint` subclass): they join the problem's own
            (:func:`ginn.constraints.shape_constraints`) at the end of the list.

    The problem's ``reference`` (``minimal-surface``: Plateau) adds the comparison with the
    reference surface to the evaluation and to the result files.
    """

    kind = "shape"

    def __init__(self, problem: Problem, cfg: RunConfig, device, dtype,
                 extra: Sequence[Callable[[Setting], Constraint]] = ()):
        super().__init__(cfg, device, dtype)
        self.problem = problem
        self.d = problem.dim
        #: codes per training step (:func:`ginn.models.latents.step_codes`)
        self.step_codes = step_codes(cfg.latents, MIN_STEP_CODES[self.d])
        self.setting = Setting(problem, spread_sampling(cfg, self.step_codes), self.device, dtype)
        #: the terms of the problem, in the order of its loss terms (:func:`ginn.constraints.shape_constraints`)
        self.constraints: list[Constraint] = shape_constraints(self.setting) + [make(self.setting) for make in extra]
        self.Z = fixed_latents(cfg.latents, self.device, dtype)
        self._check: FeasibilityCheck | None = None
        self._verdicts: list[Verdict] | None = None
        self.dist: DistContext | None = None  # when trained data-parallel (see distribute)
        self.shard: tuple[int, int] | None = None

    @classmethod
    def from_spec(cls, spec, cfg: RunConfig) -> ShapeTask:
        """The task of a shape spec: its geometry built (meshes loaded, interfaces checked).

        Raises:
            SpecError: the problem has no interface (the shape would attach to nothing).
        """
        problem = spec.build()
        if not problem.interfaces:
            raise SpecError("spec field 'geometry.interfaces': a shape problem needs at least one interface "
                            "(the shape has nothing to attach to)")
        return cls(problem, cfg, cfg.device, cfg.torch_dtype)

    # --- Task API ----------------------------------------------------------------------------

    def build_model(self) -> nn.Module:
        """The field of ``cfg.model``; with ``model.frame: domain`` in the domain's frame
        (:class:`ginn.models.frame.DomainFrame`); symmetric by construction where the problem
        states a symmetry (:class:`ginn.models.symmetric.SymmetricField`, folds smoothed over
        :data:`FOLD_SMOOTHING` of the domain's half longest side)."""
        sym = self.problem.symmetry
        model = build_model(self.cfg.model, self.d if sym is None else sym.fold_dim, latent_dim(self.cfg.latents))
        dom = self.problem.domain
        center, scale = [0.5 * (a + b) for a, b in zip(dom.lo, dom.hi)], length_scale(self.problem)
        if self.cfg.model.frame == "domain":
            if sym is not None:
                model = SymmetricField(model, sym.in_frame(center, scale), FOLD_SMOOTHING)
            return DomainFrame(model, center, scale)
        if sym is not None:
            model = SymmetricField(model, sym, FOLD_SMOOTHING * scale)
        return model

    def terms(self) -> dict[str, LossTerm]:
        return {c.name: c.term(self.cfg) for c in self.constraints}

    def latents(self) -> Tensor | None:
        return self.Z

    def state_dict(self) -> dict:
        """Each constraint's state that is not empty, under its name."""
        return {c.name: st for c in self.constraints if (st := c.state_dict())}

    def load_state_dict(self, state: dict) -> None:
        for c in self.constraints:
            if state.get(c.name):
                c.load_state_dict(state[c.name])

    def verdicts(self) -> list[Verdict]:
        """The problem's verdicts and those of its constraints (:func:`ginn.constraints.verdicts_of`),
        and the comparison with the reference solution where the problem has one
        (:class:`ginn.eval.plateau.ReferenceVerdict`), built once per task."""
        if self._verdicts is None:
            self._verdicts = verdicts_of(self.problem, self.constraints)
            if self.problem.reference == "minimal-surface":
                self._verdicts.append(ReferenceVerdict(self.problem))
        return list(self._verdicts)

    def distribute(self, ctx: DistContext) -> None:
        """Train only this rank's slice of the shapes (``ginn.train.distributed``)."""
        if self.cfg.latents.n_shapes == 1:
            raise ConfigError("distributed training shards the shapes of a generative model: set latents.n_shapes > 1")
        self.dist, self.shard = ctx, ctx.shard(self.step_codes)

    @property
    def membership(self) -> Region | None:
        """The design region's fastest membership test (:attr:`ginn.constraints.Setting.membership`)."""
        return self.setting.membership

    # --- one step ---------------------------------------------------------------------------

    def _step_latents(self, gen: torch.Generator) -> Tensor | None:
        return step_latents(self.cfg.latents, gen, self.Z, self.device, self.dtype, n=self.step_codes)

    def draw_batch(self, S: int, active: set[str], gen: torch.Generator, Z: Tensor | None = None, step: int = 0) -> Batch:
        """Fresh per-shape samples of the sets the active constraints read (and those drawn at
        every step), each ``(S, n, d)``: the :class:`~ginn.constraints.Batch` of a step before
        its evaluation."""
        sets: dict[str, SampleSet] = {}
        for c in self.constraints:
            if c.name in active:
                sets.update({s.name: s for s in c.samples})
        sets.update({s.name: s for s in BUILTIN_SETS if s.always})
        chosen = [s for s in sets.values() if s.available(self.setting)]
        return Batch.draw(self.setting, chosen, S, Z, gen, step)

    def loss_terms(self, model: nn.Module, step: int, active: set[str], gen: torch.Generator) -> dict[str, Tensor]:
        """Every active constraint's loss from one shared evaluation: the step's latents and
        samples are drawn, evaluated in one batched pass, and the constraints are evaluated stage
        by stage (:class:`~ginn.constraints.Stage`); the terms are returned in the order of the
        task's list, then the diagnostics."""
        Z = self._step_latents(gen)
        batch = self.draw_batch(1 if Z is None else Z.shape[0], active, gen, Z, step)
        if self.shard is not None:  # distributed: every rank samples all shapes, keeps its slice
            batch.shard(*self.shard)
        batch.dist = self.dist
        batch.evaluate(model)
        mine = [c for c in self.constraints if c.name in active]
        values: dict[str, Tensor] = {}
        for c in sorted(mine, key=lambda c: c.stage):
            v = c.loss(batch)
            if v is not None:
                values[c.name] = v
        out = {c.name: values[c.name] for c in mine if c.name in values}
        out.update(batch.diagnostics)
        return out

    # --- results and plug-ins ---------------------------------------------------------------------

    @property
    def results(self) -> ShapeResults:
        return ShapeResults(self)

    def balance(self) -> Balance:
        """Each constraint's target, the verdict's constraints with the terms that enforce them
        (a verdict that is no constraint's own, such as the reference, with its ``enforced_by``),
        the hard bounds and the gated objectives."""
        groups: dict[str, tuple[str, ...]] = {}
        for c in self.constraints:
            if c.verdict is not None:
                groups[c.verdict.name] = groups.get(c.verdict.name, ()) + (c.name,)
        for v in self.verdicts():
            if v.enforced_by:
                groups[v.name] = groups.get(v.name, ()) + v.enforced_by
        return Balance(targets={c.name: t for c in self.constraints if (t := c.target()) is not None}, groups=groups,
                       hard=tuple(c.verdict.name for c in self.constraints if c.verdict is not None and c.verdict.hard),
                       gated=tuple(c.name for c in self.constraints if c.gated))

    def checker(self) -> FeasibilityCheck:
        """The coarse-grid check of the problem's tolerances (``RESOLUTION['check']``, finer where
        a least feature size needs it: :func:`~ginn.eval.feasibility.check_resolution`), with the
        definitions of ``ginn eval``, built once per task."""
        if self._check is None:
            n = None if self.Z is None else max(HELDOUT_LATENTS["check"][self.d], HELDOUT_PER_SHAPE * self.Z.shape[0])
            verdicts = self.verdicts()
            self._check = FeasibilityCheck(self.problem, check_resolution(self.problem, verdicts), seed=self.cfg.seed,
                                           verdicts=verdicts, heldout=self.heldout("check", n))
        return self._check

    def heldout(self, purpose: str = "eval", n: int | None = None) -> Tensor | None:
        """The held-out codes of the latent set judged for ``purpose`` (``check`` or ``eval``;
        :data:`ginn.config.HELDOUT_LATENTS`, or ``n``), ``(H, k)``; None for a single shape."""
        if self.Z is None:
            return None
        return heldout_latents(self.cfg.latents, n or HELDOUT_LATENTS[purpose][self.d], self.device, self.dtype)

    def callbacks(self, dist: DistContext | None = None) -> list[Callback]:
        """The feasibility checks (:class:`~ginn.tasks.shape.checks.FeasibilityChecks`) with
        ``training.feasibility_checks > 0``; in a data-parallel run rank 0 judges for every rank."""
        t = self.cfg.training
        if t.feasibility_checks <= 0 or t.iterations <= 0:
            return []
        measures = [v for v in self.verdicts() if v.objective]
        objective = None if not measures else (lambda model: measures[0].objective_of(model, self.Z))
        return [FeasibilityChecks(lambda model: self.checker()(model, self.Z), t, self.verdicts(), self.constraints, dist,
                                  objective=objective)]
