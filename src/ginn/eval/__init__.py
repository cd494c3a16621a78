"""Evaluation of trained models: the paper's Appendix B.1 shape metrics, and one evaluator per kind
of problem with a known answer (Plateau's minimal surface, the parabolic mirror, Gray-Scott
patterns checked by an independent solver). References live in :mod:`ginn.eval.reference`."""

from .feasibility import FeasibilityCheck, check_feasibility, format_feasibility
from .gray_scott import Thresholds, verify_fields, verify_run
from .mirror import evaluate_mirror
from .plateau import evaluate_plateau
from .shapes import METRIC_LABELS, evaluate_shapes, format_comparison_table, format_table

__all__ = [
    "evaluate_shapes", "format_table", "check_feasibility", "FeasibilityCheck", "format_feasibility",
    "format_comparison_table", "METRIC_LABELS",
    "evaluate_plateau", "evaluate_mirror", "verify_run", "verify_fields", "Thresholds",
]
