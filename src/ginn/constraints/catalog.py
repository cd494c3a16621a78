"""The constraints and verdicts of a shape problem, assembled from its geometry and tolerances."""

from __future__ import annotations

from ..problems.problem import Problem
from .area import Area, AreaVerdict
from .attachment import Attachment, AttachmentVerdict
from .base import Constraint, Setting
from .compliance import Compliance, ComplianceReport
from .connectedness import Connected, Connectedness
from .containment import DesignRegion, Obstacle, VolumeOutside
from .curvature import MeanCurvature, Strain
from .diversity import Diversity, LeastDiversity
from .eikonal import Eikonal
from .faces import Faces, FacesVerdict
from .feature_size import GapEdges, MinGap, MinGapVerdict, MinThickness, MinThicknessVerdict, ThicknessEdges
from .fillet import MinRadius, MinRadiusVerdict
from .holes import HoleTargets, TopologyTargets
from .interface import Interface, InterfaceVerdict
from .normal import Normal
from .overhang import Overhang, OverhangVerdict
from .symmetry import SymmetryVerdict
from .verdict import Verdict, Violation, number_text
from .volume import VolumeFraction, VolumeFractionVerdict

__all__ = ["shape_constraints", "problem_verdicts", "verdicts_of", "describe", "verdict_text"]

#: the built-in verdicts by name (their texts)
#: the terms a tolerance adds, each with its verdict, in the order of the loss terms and of the
#: verdicts: ``(tolerances field, constraint or constraints, verdict)``, present where the field is
#: stated
TOLERANCE_TERMS: tuple[tuple[str, type[Constraint] | tuple[type[Constraint], ...], type[Verdict]], ...] = (
    ("volume_fraction", VolumeFraction, VolumeFractionVerdict),
    ("area", Area, AreaVerdict),
    ("min_thickness", (MinThickness, ThicknessEdges), MinThicknessVerdict),
    ("min_gap", (MinGap, GapEdges), MinGapVerdict),
    ("overhang", Overhang, OverhangVerdict),
    ("min_radius", MinRadius, MinRadiusVerdict),
    ("faces", Faces, FacesVerdict),
)

BUILTIN_VERDICTS: dict[str, type[Verdict]] = {
    v.name: v for v in (InterfaceVerdict, VolumeOutside, Connected, TopologyTargets, SymmetryVerdict, LeastDiversity,
                        AttachmentVerdict,
                        *(verdict for _, _, verdict in TOLERANCE_TERMS))}


def _stated(problem: Problem, field: str) -> bool:
    v = getattr(problem.tolerances, field)
    return v is not None and v != ()


def shape_constraints(setting: Setting) -> list[Constraint]:
    """Every term a shape problem can have, in the order of its loss terms: the eikonal
    objective, containment in E and out of the obstacles, the interfaces and their normals, the
    curvature objectives, the diversity (generative models), connectedness, the hole targets, the
    terms of the other tolerances (:data:`TOLERANCE_TERMS`).
    A term applies where the geometry has what it acts on (E, obstacles, interfaces with normals,
    topology targets); whether it is active is the trainer's business (its weight and start)."""
    p = setting.problem
    out: list[Constraint] = [Eikonal(setting)]
    if p.design_region is not None:
        out.append(DesignRegion(setting))
    if p.obstacles:
        out.append(Obstacle(setting))
    if p.interfaces:
        out.append(Interface(setting))
    if any(getattr(i, "has_normals", True) for i in p.interfaces):
        out.append(Normal(setting))
    out += [MeanCurvature(setting), Strain(setting)]
    if setting.cfg.latents.n_shapes > 1:
        out.append(Diversity(setting))
    out.append(Connectedness(setting))
    if p.topology.targets:
        out.append(HoleTargets(setting))
    out += [term(setting) for field, terms, _ in TOLERANCE_TERMS if _stated(p, field)
            for term in (terms if isinstance(terms, tuple) else (terms,))]
    if p.physics is not None:
        out += [Attachment(setting), Compliance(setting)]
    return out


def problem_verdicts(problem: Problem) -> list[Verdict]:
    """The verdicts of ``problem``'s tolerances, in the order ``ginn eval`` reports them: the
    interfaces, the volume outside E, connectedness, the topology targets, the symmetry, those of
    the other tolerances (:data:`TOLERANCE_TERMS`), and the least diversity of the set."""
    out: list[Verdict] = []
    if problem.interfaces:
        out.append(InterfaceVerdict(problem))
    out.append(VolumeOutside(problem))
    if problem.tolerances.connected:
        out.append(Connected(problem))
    if problem.topology.targets:
        out.append(TopologyTargets(problem))
    if problem.symmetry is not None:
        out.append(SymmetryVerdict(problem))
    out += [verdict(problem) for field, _, verdict in TOLERANCE_TERMS if _stated(problem, field)]
    if problem.physics is not None:
        out += [AttachmentVerdict(problem), ComplianceReport(problem)]
    if problem.tolerances.diversity is not None:
        out.append(LeastDiversity(problem))
    return out


def verdicts_of(problem: Problem, constraints: list[Constraint]) -> list[Verdict]:
    """The problem's verdicts and those of ``constraints`` that it does not state (a verdict is
    known by its name)."""
    out = problem_verdicts(problem)
    names = {v.name for v in out}
    for c in constraints:
        v = c.verdict
        if v is not None and v.name not in names:
            out.append(v)
            names.add(v.name)
    return out


def describe(name: str, v: Violation, verdicts: list[Verdict] | tuple = ()) -> str:
    """The text of a violation of the constraint ``name``: that of its verdict among ``verdicts``
    or the built-in ones, or ``name value > bound``."""
    for verdict in verdicts:
        if verdict.name == name:
            return verdict.describe(v)
    if name in BUILTIN_VERDICTS:
        return BUILTIN_VERDICTS[name].describe(v)
    return f"{name} {number_text(v.value)} > {number_text(v.bound)}"


def verdict_text(violated: dict[str, Violation], verdicts: list[Verdict] | tuple = ()) -> str:
    """``feasible``, or each violated constraint with its value and bound."""
    if not violated:
        return "feasible"
    return "; ".join(describe(name, v, verdicts) for name, v in violated.items())
