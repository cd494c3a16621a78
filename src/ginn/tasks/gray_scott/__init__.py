"""Generative PINN for stationary Gray-Scott Turing patterns (paper Section 4.3, Appendix A.6).

See docs/gray-scott.md. One package holds the kind: the model (:mod:`.model`), the losses' pattern
distances and pseudo-time step (:mod:`.patterns`), periodic finite differences
(:mod:`.finite_diff`), the task (:mod:`.task`), the independent spectral solver (:mod:`.solver`),
the four checks of a trained model (:mod:`.checks`), the result files (:mod:`.figures`), the
explorer (:mod:`.explorer`) and what ``ginn eval``/``plot``/``view`` do (:mod:`.results`); its
parameters are :class:`ginn.config.GrayScottParams`.
"""

from .checks import Thresholds, sample_fields, translation_invariant_distance, verify_fields, verify_run
from .model import GrayScottField, build_field, fixed_latents, sample_grid
from .patterns import pattern_distance, pseudo_time_step, shift_invariant_sq_distance
from .results import GrayScottMetrics, GrayScottResults
from .solver import GrayScottSolver, phase_randomised, relative_residual, residuals
from .task import GrayScottTask, parse_params

__all__ = [
    "GrayScottTask",
    "GrayScottResults",
    "GrayScottMetrics",
    "GrayScottField",
    "build_field",
    "fixed_latents",
    "parse_params",
    "pattern_distance",
    "pseudo_time_step",
    "sample_grid",
    "shift_invariant_sq_distance",
    "GrayScottSolver",
    "phase_randomised",
    "relative_residual",
    "residuals",
    "Thresholds",
    "sample_fields",
    "translation_invariant_distance",
    "verify_fields",
    "verify_run",
]
