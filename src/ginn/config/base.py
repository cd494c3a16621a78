"""The building blocks of every configuration group: strict frozen models, loss terms, dtypes and
the default grid resolutions."""

from __future__ import annotations

import math
from typing import Literal

import torch
from pydantic import BaseModel, ConfigDict, Field, field_validator

__all__ = ["Strict", "LossTerm", "DTYPES", "STRAIN_CLIP", "RESOLUTION", "CELLS_PER_LENGTH", "HELDOUT_LATENTS", "HELDOUT_PER_SHAPE",
           "MIN_STEP_CODES", "default_resolution"]

#: Names of the floating-point types a run may train in (``training.dtype``).
DTYPES = {"float32": torch.float32, "float64": torch.float64}

#: Per-point surface strain is clipped at this value (training loss and metric alike).
STRAIN_CLIP = 1000.0

#: Grid cells along the longest domain axis when none is given, by purpose and dimension:
#: ``eval`` for the metrics of ``ginn eval``, ``output`` for the shapes a run writes, ``figure``
#: for a figure drawn on its own (3D renders cost time per triangle), ``check`` for the feasibility
#: checks during training.
RESOLUTION = {"eval": {2: 512, 3: 128}, "output": {2: 256, 3: 128}, "figure": {2: 256, 3: 64}, "check": {2: 128, 3: 64}}

#: A length a verdict measures on the grid (the diameter of a least feature size's ball) spans at
#: least this many cells of the checks' grid, or they judge on the ``eval`` grid
#: (:func:`ginn.eval.feasibility.check_resolution`); ``ginn eval`` names the grid on which it
#: does (:func:`ginn.eval.feasibility.unresolved`). Below two cells the opening by the ball
#: removes nothing whatever the shape: every node inside is at least a cell from one outside.
CELLS_PER_LENGTH = 3


#: Held-out latent codes a generative model is judged at beside its reported ones, by purpose and
#: dimension: ``check`` in the feasibility checks during training, ``eval`` in ``ginn eval``
#: (:func:`ginn.models.latents.heldout_latents`).
HELDOUT_LATENTS = {"eval": {2: 256, 3: 32}, "check": {2: 16, 3: 4}}

#: The checks during training judge at least this many held-out codes per reported shape (the
#: shapes a model spreads over its latent set change branch in bands of about a reported spacing or
#: less, which a coarser set steps over).
HELDOUT_PER_SHAPE = 2

#: A step that draws its codes from the latent set (``latents.draw: lattice``) trains at least this
#: many, by dimension: as many as a check judges (``HELDOUT_LATENTS["check"]``), so that training
#: covers Z at least as finely as it is judged. The samples of the ``n_shapes`` reported shapes are
#: spread over the step's codes (:func:`ginn.tasks.shape.task.spread_sampling`), so a step evaluates
#: as many points as before; the topology terms work per code and cost more (the obstacle's demo,
#: 4 shapes: 0.089 s per iteration against 0.072 with 4 codes). pins-2d (4 shapes, seed 1) trained
#: 4 codes a step with every reported shape's interface CD1 about twice its bound to the end, and
#: 16 codes of a quarter of the samples each with every reported shape within it
#: (``docs/results.md``, "The latent set").
MIN_STEP_CODES = dict(HELDOUT_LATENTS["check"])


def default_resolution(purpose: Literal["eval", "output", "figure", "check"], dim: int) -> int:
    """The grid resolution used for ``purpose`` in ``dim`` dimensions (see :data:`RESOLUTION`)."""
    return RESOLUTION[purpose][dim]


class Strict(BaseModel):
    """A configuration group: unknown keys refused, frozen, every float finite."""

    # every float is finite: nan and inf are refused where they are read, not found later as a divergence
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class LossTerm(Strict):
    """Weight and first iteration of one loss term (weight 0 switches it off)."""

    weight: float = Field(0.0, ge=0, description="weight of the term (0 switches it off; a finite number)")
    start: int = Field(0, ge=0, description="first iteration at which the term is active")

    @field_validator("weight")
    @classmethod
    def _finite(cls, v: float) -> float:
        if not math.isfinite(v):
            raise ValueError("weight must be finite")
        return v
