"""The parabolic mirror (paper Section 4.1, Appendix A.3): the task, its optics and exact answer,
its figure and view."""

from .optics import evaluate_mirror, exact_height, focus_distance, profile, reflected_direction, reflection_residual
from .results import MirrorResults, write_profile
from .task import MirrorTask, parse_mirror_params, sample_rays

__all__ = ["MirrorTask", "MirrorResults", "parse_mirror_params", "sample_rays", "write_profile", "evaluate_mirror",
           "exact_height", "focus_distance", "profile", "reflected_direction", "reflection_residual"]
