"""Symmetry: every shape has the symmetry group the spec states.

There is no loss term: the model is symmetric by construction
(:class:`ginn.models.symmetric.SymmetricField`). Verdict: ``symmetry_error <= tolerances.symmetry *
unit_scale`` (:func:`ginn.eval.metrics.symmetry_error`), which checks that construction.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..problems.problem import Problem
from .verdict import Verdict, Violation

__all__ = ["SymmetryVerdict"]


class SymmetryVerdict(Verdict):
    """The symmetry error within its tolerance (problems that state a symmetry)."""

    name = "symmetry"

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.metrics = ("symmetry_error",)
        self.bound = problem.tolerances.symmetry * problem.unit_scale

    def violation(self, metrics: Mapping) -> Violation | None:
        sym = metrics.get("symmetry_error")
        if self.problem.symmetry is None or sym is None or sym <= self.bound:
            return None
        return Violation(float(sym), self.bound)

    def ratio(self, metrics: Mapping) -> float | None:
        sym = metrics.get("symmetry_error")
        return None if self.problem.symmetry is None or sym is None else float(sym) / self.bound
