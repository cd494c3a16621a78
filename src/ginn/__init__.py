"""ginn: geometry-informed neural networks.

The public API, re-exported here (everything else is internal and may change):

* front door: :func:`fit`, :func:`evaluate`
* fields and models: :mod:`ginn.fields` (the derivative engine), :class:`Siren`, :class:`ResMLP`,
  :class:`MLP`, :class:`FourierMLP`, :class:`PeriodicEncoding`, :func:`build_model`
* geometry: :class:`Box`, :class:`Region`, :class:`Interface`, primitives, CSG, meshes, samplers
* problems: :class:`Problem`, :func:`load_spec`, :func:`list_problems`
* training: :class:`RunConfig`, :func:`build_config`, :class:`Task`, :class:`ShapeTask`,
  :class:`Trainer`, :func:`make_task`, :func:`resolve_config`, :func:`load_run`
* losses: the constraint losses, :func:`diversity`, :func:`project_to_zero`
* evaluation: :func:`evaluate_shapes`
"""

from . import fields
from .api import evaluate, fit
from .evaluation import evaluate_shapes
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
    Polygon,
    Polyline,
    Rectangle,
    Region,
    Segment,
    Sphere,
    Transformed,
    Union,
    sample_band,
    sample_box,
    sample_inside,
    sample_interfaces,
    sample_outside,
)
from .levelset import project_to_zero
from .losses.constraints import (
    DesignRegionLoss,
    EikonalLoss,
    InterfaceLoss,
    MeanCurvatureLoss,
    NormalLoss,
    ObstacleLoss,
    StrainLoss,
)
from .losses.diversity import diversity
from .models import MLP, FourierMLP, NeuralField, PeriodicEncoding, ResMLP, Siren
from .models.factory import build_model
from .problems import Problem, list_problems, load_spec
from .train.config import RunConfig, build_config
from .train.registry import make_task, resolve_config
from .train.run import load_run
from .train.shape_task import ShapeTask
from .train.task import Task
from .train.trainer import Trainer

__version__ = "0.1.0"

__all__ = [
    "__version__",
    "fit", "evaluate",
    "fields", "NeuralField", "Siren", "ResMLP", "MLP", "FourierMLP", "PeriodicEncoding", "build_model",
    "Box", "Region", "Interface", "AABox", "Rectangle", "Cuboid", "Ball", "Disk", "Sphere", "HalfSpace",
    "Polygon", "Cylinder", "Extrusion", "Union", "Intersection", "Difference", "Transformed",
    "Segment", "Polyline", "Circle", "CylinderWall", "Annulus", "MeshRegion", "MeshInterface",
    "sample_box", "sample_inside", "sample_outside", "sample_interfaces", "sample_band",
    "Problem", "load_spec", "list_problems",
    "RunConfig", "build_config", "Task", "ShapeTask", "Trainer", "make_task", "resolve_config", "load_run",
    "DesignRegionLoss", "ObstacleLoss", "InterfaceLoss", "NormalLoss", "EikonalLoss", "MeanCurvatureLoss",
    "StrainLoss", "diversity", "project_to_zero",
    "evaluate_shapes",
]
