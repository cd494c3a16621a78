"""ginn: geometry-informed neural networks.

The public API, re-exported here (everything else is internal and may change):

* front door: :func:`fit` (train a problem, as ``ginn train``), :func:`evaluate` (as ``ginn eval``),
  :func:`load_run`, :func:`resolve`
* configuration: :class:`RunConfig`, :func:`build_config`
* fields and models: :mod:`ginn.fields` (the derivative engine), :class:`Siren`, :class:`Wire`, :class:`ResMLP`,
  :class:`MLP`, :class:`FourierMLP`, :class:`PeriodicEncoding`, :func:`build_model`,
  :class:`SymmetricField` (symmetric by construction)
* geometry: :class:`Box`, :class:`Region`, :class:`Interface`, primitives, CSG, meshes, samplers,
  symmetries (:class:`Mirror`, :class:`Rotation`, :class:`Symmetry`)
* problems: :class:`Problem`, :class:`ProblemSpec`, :func:`load_spec`, :func:`list_problems`
* constraints: :class:`Constraint` (one object per term of a shape problem), :class:`SampleSet`,
  :class:`Stage`, :class:`Verdict`, :class:`Violation`, :func:`shape_constraints`
* training: :class:`Task`, :class:`Results`, :class:`ShapeTask`, :class:`Trainer`, :class:`Callback`
  (its plug-ins), :func:`make_task`, :data:`TASKS`
* losses: the constraint losses, :func:`diversity`, :func:`project_to_zero`
* structural physics: :mod:`ginn.physics` (:class:`~ginn.physics.ElementGrid`,
  :class:`~ginn.physics.ElasticitySolver`, :func:`~ginn.physics.compliance`, :func:`~ginn.physics.simp`)
* evaluation: :func:`evaluate_shapes`, :func:`check_feasibility` (the problem's tolerances), their
  results :class:`ShapeEvaluation`, :class:`ShapeMetrics`, :class:`FeasibilitySummary`
"""

from . import constraints, fields, physics
from .config import RunConfig, build_config
from .constraints import Constraint, SampleSet, Stage, Verdict, Violation, shape_constraints
from .eval.feasibility import check_feasibility
from .eval.results import FeasibilitySummary, ShapeEvaluation, ShapeMetrics
from .eval.shapes import evaluate_shapes
from .geometry import (
    AABox,
    Annulus,
    Ball,
    Box,
    Circle,
    Cuboid,
    Cylinder,
    CylinderWall,
    Difference,
    Disk,
    Extrusion,
    HalfSpace,
    Interface,
    Intersection,
    MeshInterface,
    MeshRegion,
    Mirror,
    Polygon,
    Polyline,
    Rectangle,
    Region,
    Rotation,
    Segment,
    Sphere,
    Symmetry,
    Transformed,
    Union,
    sample_band,
    sample_box,
    sample_inside,
    sample_interfaces,
    sample_outside,
)
from .levelset import project_to_zero
from .losses import (
    DesignRegionLoss,
    EikonalLoss,
    InterfaceLoss,
    MeanCurvatureLoss,
    NormalLoss,
    ObstacleLoss,
    StrainLoss,
    diversity,
)
from .models import MLP, FourierMLP, NeuralField, PeriodicEncoding, ResMLP, Siren, SymmetricField, Wire, build_model
from .problems import Problem, ProblemSpec, list_problems, load_spec
from .runs import Run, evaluate, fit, load_run, resolve
from .tasks import TASKS, ShapeTask, make_task
from .train import Callback, Results, Task, Trainer
from .version import __version__

__all__ = [
    "__version__",
    "fit", "evaluate", "load_run", "resolve", "Run",
    "RunConfig", "build_config",
    "fields", "NeuralField", "Siren", "Wire", "SymmetricField", "ResMLP", "MLP", "FourierMLP", "PeriodicEncoding", "build_model",
    "Box", "Region", "Interface", "AABox", "Rectangle", "Cuboid", "Ball", "Disk", "Sphere", "HalfSpace",
    "Polygon", "Cylinder", "Extrusion", "Union", "Intersection", "Difference", "Transformed",
    "Segment", "Polyline", "Circle", "CylinderWall", "Annulus", "MeshRegion", "MeshInterface",
    "sample_box", "sample_inside", "sample_outside", "sample_interfaces", "sample_band",
    "Mirror", "Rotation", "Symmetry",
    "Problem", "ProblemSpec", "load_spec", "list_problems",
    "constraints", "Constraint", "SampleSet", "Stage", "Verdict", "Violation", "shape_constraints",
    "Task", "Results", "ShapeTask", "Trainer", "Callback", "make_task", "TASKS",
    "DesignRegionLoss", "ObstacleLoss", "InterfaceLoss", "NormalLoss", "EikonalLoss", "MeanCurvatureLoss",
    "StrainLoss", "diversity", "project_to_zero",
    "physics",
    "evaluate_shapes", "check_feasibility", "ShapeEvaluation", "ShapeMetrics", "FeasibilitySummary",
]
