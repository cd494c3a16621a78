"""Problems: the Problem dataclass, the YAML spec format and the built-in problems."""

from .loader import builtin_path, get_spec, list_problems, load_spec, parse_spec, problem_summaries, spec_text
from .problem import Bounds, CurvatureBound, Face, FeatureSize, Overhang, Problem, Tolerances, VolumeBounds
from .spec import GeometrySpec, ProblemSpec, validate_spec

__all__ = [
    "Problem", "Tolerances", "Bounds", "VolumeBounds", "FeatureSize", "Overhang", "CurvatureBound", "Face",
    "ProblemSpec", "GeometrySpec",
    "load_spec", "parse_spec", "validate_spec", "get_spec", "builtin_path", "list_problems", "problem_summaries", "spec_text",
]
