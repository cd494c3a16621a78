"""The geometric description of a GINN design problem, as objects (the spec loader builds it)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..geometry.base import Box, Interface, Region, near_any_interface, near_any_rim
from ..geometry.symmetry import Symmetry


@dataclass(frozen=True)
class Bounds:
    """An interval ``[min, max]`` a per-shape quantity must lie in (None: no bound on that side):
    the volume fraction ``vol(Omega cap E) / vol(E)`` of every shape (E: the design region, or the
    domain where there is none), or the area of its boundary."""

    min: float | None = None
    max: float | None = None

    def violated(self, value: float) -> bool:
        """Whether ``value`` lies outside the bounds."""
        return (self.max is not None and value > self.max) or (self.min is not None and value < self.min)


#: the volume fraction's bounds (the name the volume bound was introduced with)
VolumeBounds = Bounds


@dataclass(frozen=True)
class FeatureSize:
    """A least feature size: every ball of diameter ``size`` (a length in the problem's
    coordinates) must fit, up to a share ``removed`` of the shape's volume
    (:func:`ginn.extract.morphology.opening_removed`).

    For the solid (``tolerances.min_thickness``) the morphological opening by the ball may remove at
    most that share; for the void (``tolerances.min_gap``) the closing may add at most that share."""

    size: float
    removed: float = 0.01


@dataclass(frozen=True)
class Overhang:
    """A largest overhang for additive manufacturing: no surface may face down by more than
    ``angle`` degrees below the horizontal (its outward normal ``n`` with ``-n . up > sin(angle)``),
    up to a share ``share`` of the down-facing area, except on the build plate (the boundary within
    the interface tolerance of the height ``plate`` along ``up``) and at the interfaces
    (:func:`ginn.extract.overhang.overhang_share`).

    Attributes:
        angle: degrees, in (0, 90).
        up: the build direction, a unit vector ``(d,)``.
        plate: the build plate's height along ``up`` (None: the domain's lowest).
        share: the largest share of the down-facing area in violation.
    """

    angle: float
    up: tuple[float, ...]
    plate: float | None = None
    share: float = 0.01


@dataclass(frozen=True)
class CurvatureBound:
    """No edge sharper than a fillet of radius ``radius``: the largest absolute principal curvature
    of the boundary at most ``1 / radius``, up to a share ``share`` of the boundary (the interfaces
    exempt; :mod:`ginn.constraints.fillet`)."""

    radius: float
    share: float = 0.01


@dataclass(frozen=True)
class ReferenceBound:
    """How close a shape must come to its problem's reference solution (``reference:
    minimal-surface``): the CD2 between the two surfaces at most ``cd2`` and the relative
    difference of their areas at most ``area`` in absolute value (:class:`ginn.eval.plateau.ReferenceVerdict`)."""

    cd2: float = 0.02
    area: float = 0.02


@dataclass(frozen=True)
class Face:
    """A prescribed face of the boundary inside ``region`` (:mod:`ginn.constraints.faces`), one of:

    * flat: ``normal`` given; the boundary's outward normal within ``angle`` degrees of it (flat
      and parallel to the plane with that normal);
    * on a surface: ``surface`` given; the boundary within ``distance`` of the boundary of the
      region ``surface`` and its normal within ``angle`` degrees of that surface's normal, either
      way round (the face lies on the surface, tangent to it: a seat on a pipe, a face round a boss).

    Attributes:
        region: where the face is (a region of the problem's space).
        normal: the flat face's outward unit normal ``(d,)``; ``None`` for a face on a surface.
        angle: degrees.
        surface: the region whose boundary the face lies on; ``None`` for a flat face.
        distance: the largest distance from ``surface``, in the problem's units (with ``surface``).
    """

    region: Region
    normal: tuple[float, ...] | None = None
    angle: float = 2.0
    surface: Region | None = None
    distance: float | None = None


@dataclass(frozen=True)
class Tolerances:
    """When a shape counts as feasible (:mod:`ginn.eval.feasibility`), in the problem's units.

    Attributes:
        interface: bound of ``CD1(dOmega, I)``, the root mean square distance from the interfaces
            to the shape's boundary, in units of ``unit_scale``.
        volume_outside: bound of ``vol(Omega \\ E) / vol(X \\ E)`` (the obstacles are outside E).
        connected: the shape must be one piece inside E that touches every interface component
            (``b0(Omega cap E) = 1`` and ``CI / n_I = 1``).
        normal_angle: the angle in degrees by which the shape's normals may deviate from the
            prescribed ones, on average (a training target; not part of the verdict).
        diversity: the least ``diversity_mean`` of the set, in units of ``unit_scale`` (None:
            the diversity is maximised as an objective, the paper's setting).
        symmetry: bound of the symmetry error (:func:`ginn.eval.metrics.symmetry_error`) in units
            of ``unit_scale``, where the problem states a symmetry.
        volume_fraction: bounds on each shape's volume as a fraction of E (None: free).
        min_thickness: the least thickness of the solid (None: free).
        min_gap: the least width of the gaps and holes between parts of the solid (None: free).
        overhang: the largest overhang for additive manufacturing (None: free).
        min_radius: the smallest radius of curvature of the boundary (None: free).
        area: bounds on the area (2D: length) of each shape's boundary, in the problem's units
            (None: free).
        faces: flat faces the boundary must have (none: free).
        reference: how close to the reference solution, where the problem has one.
    """

    interface: float = 5e-3
    volume_outside: float = 5e-3
    connected: bool = True
    normal_angle: float = 10.0
    symmetry: float = 5e-3
    diversity: float | None = None
    volume_fraction: VolumeBounds | None = None
    min_thickness: FeatureSize | None = None
    min_gap: FeatureSize | None = None
    overhang: Overhang | None = None
    min_radius: CurvatureBound | None = None
    area: Bounds | None = None
    faces: tuple[Face, ...] = ()
    reference: ReferenceBound = ReferenceBound()


@dataclass(frozen=True)
class Support:
    """Degrees of freedom held at zero: the components ``axes`` (0: x, 1: y, 2: z) of the finite-element
    nodes within half an element of any of ``where`` (interfaces or regions), and with ``normal``
    the component along the normal of the nearest interface (a frictionless pin in a round hole's
    rim: the part turns about it)."""

    where: tuple[Interface | Region, ...]
    axes: tuple[int, ...]
    normal: bool = False


@dataclass(frozen=True)
class Load:
    """A force and a torque on the finite-element nodes within half an element of any of ``where``
    (interfaces or regions).

    Attributes:
        where: the interfaces or regions.
        force: ``(d,)``, the total force, shared equally by the nodes.
        torque: the moment of a couple (zero net force) about the nodes' centroid: ``(1,)`` in 2D
            (about z), ``(3,)`` in 3D; the nodal forces are those of a rigid rotation's
            displacements, scaled to give this moment (``ginn.problems.structural``).
    """

    where: tuple[Interface | Region, ...]
    force: tuple[float, ...]
    torque: tuple[float, ...] = ()


@dataclass(frozen=True)
class LoadCase:
    """Loads that act together; the objective weighs each case's compliance by ``weight``."""

    loads: tuple[Load, ...]
    weight: float = 1.0


@dataclass(frozen=True)
class Physics:
    """Linear elasticity of the shape (``docs/structural.md``): an isotropic material, supports and
    load cases; the objective is the weighted sum of the load cases' compliances.

    Attributes:
        youngs_modulus: in the problem's force per area (2D: per length, unit thickness).
        poisson_ratio: in (-1, 0.5).
        supports: the held degrees of freedom.
        load_cases: the load cases.
        labels: ``(supports, load cases)``: the spec field of each support and each load case's
            loads, for messages (``physics.supports[0]``).
    """

    youngs_modulus: float
    poisson_ratio: float
    supports: tuple[Support, ...]
    load_cases: tuple[LoadCase, ...]
    labels: tuple[tuple[str, ...], tuple[tuple[str, ...], ...]] = ((), ())


@dataclass(frozen=True)
class Topology:
    """The Betti numbers every shape must have inside E (None: free), counted as
    :func:`ginn.topology.betti_numbers` counts them (holes round an obstacle count).

    Attributes:
        b1: 2D: holes; 3D: tunnels.
        b2: 3D: cavities (enclosed voids).
    """

    b1: int | None = None
    b2: int | None = None

    @property
    def targets(self) -> dict[int, int]:
        """``{dimension: target}`` for the stated ones."""
        return {k: v for k, v in ((1, self.b1), (2, self.b2)) if v is not None}


@dataclass(frozen=True)
class Problem:
    """A design problem: the shape ``Omega = {f <= 0}`` must lie in ``design_region`` inside
    ``domain``, touch every interface (with its prescribed normals), and avoid the obstacles.

    Attributes:
        name: short name (``obstacle``, ``bracket``, ...).
        domain: the box X in which the field is trained and evaluated.
        design_region: E (None: the whole domain).
        interfaces: I, one object per *kind* of interface; ``sum(i.n_components)`` components.
        obstacles: regions the shape must not enter (also removed from E by the spec builder).
        interface_band: half-width of the denser sampling band around the interfaces (0: none).
        unit_scale: length scale at which metric tolerances such as eps = 0.01 are stated.
        tolerances: when a shape is feasible (:class:`Tolerances`).
        topology: the Betti numbers each shape must have (:class:`Topology`; part of the verdict).
        symmetry: the symmetry group every shape has (:class:`ginn.geometry.symmetry.Symmetry`;
            the field is symmetric by construction), or None.
        reference: an independent reference solution evaluation compares against
            (``"minimal-surface"``), or None.
        physics: the structural problem (:class:`Physics`), or None (geometry only).
    """

    name: str
    domain: Box
    design_region: Region | None = None
    interfaces: tuple[Interface, ...] = ()
    obstacles: tuple[Region, ...] = ()
    interface_band: float = 0.0
    unit_scale: float = 1.0
    tolerances: Tolerances = field(default_factory=Tolerances)
    topology: Topology = field(default_factory=Topology)
    symmetry: Symmetry | None = None
    description: str = ""
    reference: str | None = None
    physics: Physics | None = None
    extra: dict = field(default_factory=dict)

    @property
    def dim(self) -> int:
        return self.domain.dim

    @property
    def interface_tolerance(self) -> float:
        """The interface tolerance as a distance, ``tolerances.interface * unit_scale``."""
        return float(self.tolerances.interface) * float(self.unit_scale)

    def near_interfaces(self, x):
        """``(n,)`` bool tensor: the points of ``x (n, d)`` (a tensor) within the interface tolerance
        of an interface, the neighbourhood the verdicts leave to the interfaces."""
        return near_any_interface(self.interfaces, x, self.interface_tolerance)

    def near_rims(self, x, radius: float):
        """``(n,)`` bool tensor: the points of ``x (n, d)`` within the interface tolerance plus
        ``radius`` of an interface's rim (:meth:`ginn.geometry.Interface.rim_distance`). An
        interface's rim is an edge the spec prescribes: no shape that meets the interface rounds it
        to ``radius`` there, so the verdicts and losses of a least radius (thickness, gap, fillet)
        leave this neighbourhood to the interfaces."""
        return near_any_rim(self.interfaces, x, self.interface_tolerance + float(radius))

    @property
    def n_interface_components(self) -> int:
        return sum(i.n_components for i in self.interfaces)
