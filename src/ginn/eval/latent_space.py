"""A generative model judged over its latent set, not only at the codes it reports.

The solution set of a generative GINN is the image of the whole latent set ``Z`` (paper,
Section 3.2). ``ginn eval`` therefore judges, beside the reported shapes, a fixed set of held-out
codes spread over ``Z`` (:func:`ginn.models.latents.heldout_latents`) and reports:

* the **feasible share of Z**: how many held-out codes give a feasible shape, and the worst code
  (the largest value of a constraint over its bound);
* the **smoothness of z -> shape** along paths through ``Z`` (in one dimension the held-out codes
  in order; in ``k`` dimensions a line along each latent axis through the centre of ``Z``):

  - ``change_rate_max`` / ``change_rate_mean``: the largest and the mean shape change per unit of
    latent distance between neighbouring codes, the change measured as the two-sided chamfer
    distance (equation 5) between their boundaries, in the problem's length unit;
  - ``topology_changes``: how many neighbouring codes differ in the number of pieces inside E
    (or in the Betti numbers the verdicts measure).

Every code is judged by one :class:`LatentJudge`: the feasibility check of ``ginn eval``'s
resolution, with its interface samples and seed; ``ginn export --latent`` and ``ginn view`` judge
the codes they draw with the same judge, so a verdict shown for a code is the verdict
``ginn eval`` gives for it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from ..constraints.verdict import Verdict
from ..fields import Field
from ..problems.problem import Problem
from .feasibility import FeasibilityCheck, evaluating, summarize
from .results import FeasibilitySummary

__all__ = ["LatentJudge", "LatentSurvey", "survey_latents", "axis_paths", "TOPOLOGY_KEYS"]

#: The metrics whose change between neighbouring codes counts as a change of topology.
TOPOLOGY_KEYS = ("b0_in_design_region", "b1_in_design_region", "b2_in_design_region")

#: Boundary samples per shape for the chamfer distance between neighbouring codes.
PATH_SAMPLES = 1024


class LatentJudge(FeasibilityCheck):
    """The verdict of any latent code as ``ginn eval`` gives it: the feasibility metrics at the
    evaluation resolution, interface samples and seed of ``ginn eval``
    (:func:`ginn.eval.shapes.evaluate_shapes`)."""

    def __init__(self, problem: Problem, resolution: int, verdicts: Sequence[Verdict] | None = None):
        super().__init__(problem, resolution, seed=0, verdicts=verdicts)


@dataclass
class LatentSurvey:
    """What :func:`survey_latents` found.

    Attributes:
        summary: the verdict at each held-out code (naming the codes).
        smoothness: ``change_rate_max``, ``change_rate_mean`` (length per unit latent),
            ``topology_changes`` and ``path_codes`` (how many codes the paths hold); empty without
            a path of two codes.
        resolution: the grid of the verdicts (cells along the longest axis).
    """

    summary: FeasibilitySummary
    smoothness: dict
    resolution: int

    def to_json(self) -> dict:
        return {"resolution": self.resolution, **self.smoothness}


def axis_paths(low: float, high: float, dim: int, n: int) -> list[Tensor]:
    """One path of ``n`` evenly spaced codes along each latent axis through the centre of
    ``[low, high]^dim``, each ``(n, dim)`` (float64)."""
    t = torch.linspace(low, high, n, dtype=torch.float64)
    out = []
    for a in range(dim):
        P = torch.full((n, dim), 0.5 * (low + high), dtype=torch.float64)
        P[:, a] = t
        out.append(P)
    return out


def _chamfer(a, b, xa: np.ndarray, xb: np.ndarray) -> float:
    """The two-sided chamfer distance between boundaries ``a`` and ``b`` from their samples."""
    if a.n_elements == 0 or b.n_elements == 0 or len(xa) == 0 or len(xb) == 0:
        return float("inf") if (a.n_elements == 0) != (b.n_elements == 0) else 0.0
    da, db = b.distance(xa), a.distance(xb)
    return float(np.sqrt(np.mean(da * da) + np.mean(db * db)))


def survey_latents(field: Field, heldout: Tensor, judge: LatentJudge, paths: Sequence[Tensor] | None = None) -> LatentSurvey:
    """Judge the codes ``heldout (H, k)`` and measure the smoothness along ``paths`` (each ``(n, k)``
    codes in order; None: ``heldout`` itself is the path, as in one dimension), in one pass over
    the codes.

    The codes of the paths that are not held-out codes are judged for the smoothness only."""
    dev, dt = heldout.device, heldout.dtype
    walks = [heldout] if paths is None else [p.to(device=dev, dtype=dt) for p in paths]
    rates: list[float] = []
    changes = 0
    metrics_at: dict[int, object] = {}
    rng = np.random.default_rng(0)
    with evaluating(field):
        for w, P in enumerate(walks):
            prev = None
            for i in range(P.shape[0]):
                m, sh = judge.shape(field, P[i])
                if paths is None:
                    metrics_at[i] = m
                b = sh.boundary
                x = b.sample(PATH_SAMPLES, rng) if b.n_elements else np.zeros((0, judge.problem.dim))
                topo = tuple(m.get(k) for k in TOPOLOGY_KEYS)
                if prev is not None:
                    dz = float((P[i] - P[i - 1]).double().norm())
                    if dz > 0:
                        rates.append(_chamfer(prev[0], b, prev[1], x) / dz)
                    changes += int(topo != prev[2])
                prev = (b, x, topo)
                del sh
        shapes = [metrics_at[i] for i in range(heldout.shape[0])] if paths is None else [
            judge.shape(field, heldout[i])[0] for i in range(heldout.shape[0])]
    summary = summarize(shapes, judge.problem, None, [v for v in judge.verdicts if not v.on_set], latents=heldout)
    smooth = {}
    if rates:
        finite = [r for r in rates if np.isfinite(r)]
        smooth = {"change_rate_max": max(rates) if finite else None,
                  "change_rate_mean": float(np.mean(finite)) if finite else None,
                  "topology_changes": changes, "path_codes": sum(int(P.shape[0]) for P in walks)}
        if len(finite) < len(rates):  # a shape appeared from or vanished into nothing along the way
            smooth["change_rate_max"] = None
    return LatentSurvey(summary, smooth, judge.resolution)
