"""Constraints of shape problems: one object per term, each in its own module.

A :class:`Constraint` declares the samples it reads and the stage at which it is evaluated,
computes its loss from one shared batched evaluation of the field (:class:`Batch`), and carries
its target, the :class:`Verdict` it enforces (the same object judges ``ginn eval``) and its
checkpoint state. :func:`shape_constraints` assembles the terms of a problem;
:func:`problem_verdicts` its verdicts. A new kind of constraint is a subclass, passed to
:class:`ginn.tasks.shape.ShapeTask` (``extra=``) or added to :func:`shape_constraints`.
"""

from .area import Area, AreaVerdict
from .attachment import Attachment, AttachmentVerdict
from .base import Constraint, Setting, Stage
from .batch import Batch, Surface
from .catalog import describe, problem_verdicts, shape_constraints, verdict_text, verdicts_of
from .connectedness import Connected, Connectedness
from .containment import DesignRegion, Obstacle, VolumeOutside, containment_floor, judged_volume_outside
from .curvature import MeanCurvature, Strain
from .diversity import Diversity, LeastDiversity
from .eikonal import Eikonal
from .faces import Faces, FacesVerdict
from .feature_size import GapEdges, MinGap, MinGapVerdict, MinThickness, MinThicknessVerdict, ThicknessEdges
from .fillet import MinRadius, MinRadiusVerdict
from .holes import BETTI_METRICS, HoleTargets, TopologyTargets
from .interface import Interface, InterfaceVerdict
from .normal import Normal
from .overhang import Overhang, OverhangVerdict
from .samples import BAND, BUILTIN_SETS, DOMAIN, INTERFACE, OBSTACLE, OUTSIDE, SampleSet
from .symmetry import SymmetryVerdict
from .verdict import Verdict, Violation
from .volume import VolumeFraction, VolumeFractionVerdict

__all__ = [
    "Constraint", "Setting", "Stage", "Batch", "Surface", "SampleSet", "Verdict", "Violation",
    "DOMAIN", "OUTSIDE", "OBSTACLE", "INTERFACE", "BAND", "BUILTIN_SETS",
    "Eikonal", "DesignRegion", "Obstacle", "Interface", "Normal", "MeanCurvature", "Strain", "Diversity",
    "Connectedness", "HoleTargets", "VolumeFraction", "MinThickness", "MinGap", "ThicknessEdges", "GapEdges", "Overhang",
    "MinRadius", "Area", "Faces", "Attachment",
    "InterfaceVerdict", "VolumeOutside", "Connected", "TopologyTargets", "SymmetryVerdict", "LeastDiversity",
    "VolumeFractionVerdict", "MinThicknessVerdict", "MinGapVerdict", "OverhangVerdict", "MinRadiusVerdict", "AreaVerdict",
    "FacesVerdict", "AttachmentVerdict",
    "BETTI_METRICS", "containment_floor", "judged_volume_outside",
    "shape_constraints", "problem_verdicts", "verdicts_of", "describe", "verdict_text",
]
