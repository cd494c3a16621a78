"""Shape problems: the task that trains them from their constraints, its feasibility checks during
training, and what it does with a trained model (evaluation, export, figures, explorer)."""

from .checks import FeasibilityChecks, candidate_ratios
from .results import ShapeResults
from .task import ShapeTask

__all__ = ["ShapeTask", "ShapeResults", "FeasibilityChecks", "candidate_ratios"]
