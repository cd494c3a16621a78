"""Generative PINN for stationary Gray-Scott Turing patterns (paper Section 4.3, Appendix A.6).

See docs/gray-scott.md. The task and its model live here; its parameters are
:class:`ginn.config.GrayScottParams`; the independent solver and the four checks of a trained
model are :mod:`ginn.eval.reference.gray_scott` and :mod:`ginn.eval.gray_scott`.
"""

from .task import (
    GrayScottField,
    GrayScottTask,
    build_field,
    fixed_latents,
    parse_params,
    pattern_distance,
    pseudo_time_step,
    sample_grid,
    shift_invariant_sq_distance,
)

__all__ = [
    "GrayScottTask",
    "GrayScottField",
    "build_field",
    "fixed_latents",
    "parse_params",
    "pattern_distance",
    "pseudo_time_step",
    "sample_grid",
    "shift_invariant_sq_distance",
]
