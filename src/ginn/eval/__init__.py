"""Evaluation of trained shapes: the paper's Appendix B.1 metrics, the verdict of a problem's
tolerances on them, their typed results, and the comparison with a known answer (Plateau's minimal
surface; references in :mod:`ginn.eval.reference`). The other kinds' evaluations live in their
task packages (:mod:`ginn.tasks.mirror`, :mod:`ginn.tasks.gray_scott`)."""

from .feasibility import FeasibilityCheck, check_feasibility, format_feasibility
from .plateau import evaluate_plateau
from .report import METRIC_LABELS, format_comparison_table, format_table
from .results import FeasibilitySummary, ShapeEvaluation, ShapeMetrics
from .shapes import evaluate_shapes

__all__ = [
    "evaluate_shapes", "format_table", "check_feasibility", "FeasibilityCheck", "format_feasibility",
    "format_comparison_table", "METRIC_LABELS", "FeasibilitySummary", "ShapeEvaluation", "ShapeMetrics",
    "evaluate_plateau",
]
