"""Generative PINN for stationary Gray-Scott Turing patterns (paper Section 4.3, Appendix A.6).

See docs/gray-scott.md. Public names:

* :class:`GrayScottTask`, :class:`GrayScottParams`, :class:`GrayScottField` (the model and losses);
* :class:`GrayScottSolver`, :class:`GSParams`, :func:`relative_residual` (the independent solver);
* :func:`verify_run`, :func:`verify_fields`, :class:`Thresholds` (the four checks).
"""

from .gray_scott import GrayScottField, GrayScottParams, GrayScottTask, parse_params
from .solver import GrayScottSolver, GSParams, phase_randomised, relative_residual
from .verify import Thresholds, translation_invariant_distance, verify_fields, verify_run

__all__ = [
    "GrayScottTask",
    "GrayScottParams",
    "GrayScottField",
    "parse_params",
    "GrayScottSolver",
    "GSParams",
    "relative_residual",
    "phase_randomised",
    "verify_run",
    "verify_fields",
    "Thresholds",
    "translation_invariant_distance",
]
