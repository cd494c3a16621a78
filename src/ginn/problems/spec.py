"""The problem spec schema (pydantic) and its translation into geometry objects.

A spec is data (YAML): see ``docs/problem-spec.md`` for the reference. :func:`validate_spec` turns
a parsed dict into a :class:`ProblemSpec` or raises :class:`~ginn.errors.SpecError` with ONE line
naming the field path (``spec field 'geometry.interfaces[1].radius': must be > 0``);
:meth:`ProblemSpec.build` creates the :class:`~ginn.problems.problem.Problem` (loading meshes and
checking that the interfaces lie in the domain), with the same kind of errors;
:meth:`ProblemSpec.config` resolves the run configuration. The nodes of ``geometry`` live in
:mod:`ginn.problems.regions` and :mod:`ginn.problems.interfaces`.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import torch
from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, ValidationInfo, field_validator, model_validator

from ..config import TASK_KINDS, RunConfig, build_config, flattened
from ..errors import ConfigError, SpecError, field_message, field_path
from ..geometry import csg
from ..geometry.base import Box
from ..geometry.symmetry import Mirror, Rotation, Symmetry
from .derived import derived_defaults, half_longest_side
from .forced import forced_holes, forced_tunnels
from .interfaces import INTERFACE_TYPES, InterfaceSpec
from .nodes import Dir3, Direction, Finite, Fraction, Node, NonNegative, Point, Positive, check_lo_hi, spec_dim
from .physics_spec import PhysicsSpec
from .problem import Bounds, CurvatureBound, Face, FeatureSize, Overhang, Problem, ReferenceBound, Tolerances, Topology
from .regions import REGION_TYPES, RegionSpec
from .symmetric import check_symmetric


class DomainSpec(Node):
    """The box X = [lo, hi]."""

    lo: Point
    hi: Point

    @model_validator(mode="after")
    def _order(self):
        check_lo_hi(self.lo, self.hi)
        return self


class GeometrySpec(Node):
    """Domain, design region, interfaces and obstacles of a shape problem."""

    dim: Literal[2, 3]
    domain: DomainSpec
    design_region: RegionSpec | None = None
    interfaces: list[InterfaceSpec] = Field(default_factory=list)
    obstacles: list[RegionSpec] = Field(default_factory=list)
    interface_band: NonNegative = 0.0
    unit_scale: Positive | None = Field(
        None, description="the length at which tolerances are stated; default half the longest side of the domain")


class _IntervalSpec(Node):
    """Bounds ``min <= value <= max`` (:class:`~ginn.problems.problem.Bounds`), one side or both."""

    @model_validator(mode="after")
    def _ordered(self):
        if self.min is None and self.max is None:
            raise ValueError("state min, max or both")
        if self.min is not None and self.max is not None and self.min > self.max:
            raise ValueError(f"min {self.min} is above max {self.max}")
        return self

    def build(self) -> Bounds:
        return Bounds(self.min, self.max)


class VolumeFractionSpec(_IntervalSpec):
    """Bounds on each shape's volume as a fraction of E."""

    min: Fraction | None = Field(None, description="the least vol(shape in E) / vol(E)")
    max: Fraction | None = Field(None, description="the largest vol(shape in E) / vol(E)")


class AreaSpec(_IntervalSpec):
    """Bounds on the area (2D: length) of each shape's boundary."""

    min: NonNegative | None = Field(None, description="the least area of the boundary")
    max: Positive | None = Field(None, description="the largest area of the boundary")


class FeatureSizeSpec(Node):
    """A least feature size (:class:`~ginn.problems.problem.FeatureSize`)."""

    size: Positive = Field(description="the diameter of the ball that must fit, a length in the problem's coordinates")
    removed: Annotated[float, Field(ge=0, lt=1, allow_inf_nan=False)] = Field(
        0.01, description="the share of the shape's volume the opening may remove (min_thickness) or the closing "
        "may add (min_gap)")

    def build(self) -> FeatureSize:
        return FeatureSize(self.size, self.removed)


class OverhangSpec(Node):
    """A largest overhang angle for additive manufacturing (:class:`~ginn.problems.problem.Overhang`)."""

    angle: Annotated[float, Field(gt=0, lt=90, allow_inf_nan=False)] = Field(
        description="degrees below the horizontal that a down-facing surface may reach (45: the usual "
        "self-supporting limit)")
    up: Direction = Field(description="the build direction (need not be a unit vector)")
    plate: Finite | None = Field(
        None, description="the build plate's height along up (default: the domain's lowest point along up); the "
        "boundary on it is exempt")
    share: Annotated[float, Field(ge=0, lt=1, allow_inf_nan=False)] = Field(
        0.01, description="the largest share of the down-facing boundary that may overhang")

    def build(self) -> Overhang:
        n = math.sqrt(sum(c * c for c in self.up))
        return Overhang(float(self.angle), tuple(float(c) / n for c in self.up), self.plate, float(self.share))


class CurvatureBoundSpec(Node):
    """A smallest radius of curvature (:class:`~ginn.problems.problem.CurvatureBound`)."""

    radius: Positive = Field(description="the smallest fillet radius, a length in the problem's coordinates")
    share: Annotated[float, Field(ge=0, lt=1, allow_inf_nan=False)] = Field(
        0.01, description="the largest share of the boundary that may be curved more sharply")

    def build(self) -> CurvatureBound:
        return CurvatureBound(float(self.radius), float(self.share))


def _unit(v) -> tuple[float, ...]:
    n = math.sqrt(sum(float(c) ** 2 for c in v))
    return tuple(float(c) / n for c in v)


class FaceSpec(Node):
    """A prescribed face of the boundary (:class:`~ginn.problems.problem.Face`): flat with
    ``normal``, or on the boundary of the region ``surface``."""

    region: RegionSpec = Field(description="where the face is: a region of the problem's space")
    normal: Direction | None = Field(
        None, description="a flat face: its outward normal (need not be a unit vector); give normal or surface")
    surface: RegionSpec | None = Field(
        None, description="a face on a surface: the region whose boundary the face lies on, tangent to it")
    angle: Annotated[float, Field(gt=0, lt=90, allow_inf_nan=False)] = Field(
        2.0, description="the largest angle in degrees between the boundary's normal in the region and normal "
        "(the surface's normal, either way round)")
    distance: Positive | None = Field(
        None, description="with surface: the largest distance from the boundary in the region to the surface, "
        "in the problem's units (default: the interface tolerance)")

    @model_validator(mode="after")
    def _one_kind(self):
        if (self.normal is None) == (self.surface is None):
            raise ValueError("give one of normal (a flat face) and surface (a face on a surface)")
        if self.distance is not None and self.surface is None:
            raise ValueError("distance needs surface (a flat face is judged by its normals)")
        return self


class ReferenceBoundSpec(Node):
    """How close to the reference solution (:class:`~ginn.problems.problem.ReferenceBound`)."""

    cd2: Positive = Field(0.02, description="bound of the CD2 (paper eq. 4-5) between the shape's surface and the "
                          "reference surface, in the problem's units")
    area: Positive = Field(0.02, description="bound of |area - reference area| / reference area")

    def build(self) -> ReferenceBound:
        return ReferenceBound(float(self.cd2), float(self.area))


class TolerancesSpec(Node):
    """When a shape is feasible (:class:`~ginn.problems.problem.Tolerances`)."""

    interface: Positive = Field(5e-3, description="bound of CD1 (RMS distance from the interfaces to the shape), "
                                "in units of geometry.unit_scale")
    volume_outside: NonNegative = Field(5e-3, description="bound of vol(shape outside E) / vol(X outside E)")
    connected: bool = Field(True, description="one piece inside E touching every interface component")
    normal_angle: Annotated[float, Field(gt=0, le=90)] = Field(
        10.0, description="mean deviation of the normals from the prescribed ones, degrees (a training target)")
    diversity: Positive | None = Field(
        None, description="the least diversity_mean of the set of shapes, in units of geometry.unit_scale: the set "
        "must be at least this diverse and is not pushed further (none: diversity is maximised)")
    symmetry: Positive = Field(5e-3, description="bound of the RMS distance from the shape's boundary mapped by each "
                               "symmetry to the boundary, in units of geometry.unit_scale (when a symmetry is stated)")
    volume_fraction: VolumeFractionSpec | None = Field(
        None, description="bounds on each shape's volume inside E as a fraction of vol(E) (E: the domain where "
        "there is no design region): {max: 0.3}, {min: 0.2}, or both; a number is the largest fraction")

    min_thickness: FeatureSizeSpec | None = Field(
        None, description="the least thickness of the solid: a ball of diameter size fits at every point of it "
        "(the morphological opening by the ball keeps all but the share removed of its volume): {size: 0.05}, "
        "{size: 0.05, removed: 0.01}; a number is size")
    min_gap: FeatureSizeSpec | None = Field(
        None, description="the least width of every gap and hole: the same for the void (the closing by the ball "
        "adds at most the share removed of the shape's volume); a number is size")
    overhang: OverhangSpec | None = Field(
        None, description="additive manufacturing: {angle: 45, up: [0, 0, 1]}: no surface faces down by more than "
        "angle degrees below the horizontal, up to share (0.01) of the down-facing boundary; the build plate and "
        "the interfaces are exempt")
    min_radius: CurvatureBoundSpec | None = Field(
        None, description="no edge sharper than a fillet of this radius: every principal curvature of the boundary "
        "at most 1 / radius in absolute value, up to share (0.01) of the boundary, the interfaces exempt: "
        "{radius: 0.02}; a number is radius")

    faces: list[FaceSpec] = Field(
        default_factory=list, description="prescribed faces: [{region: {...}, normal: [0, 0, 1], angle: 2}]: the "
        "boundary inside each region faces along its normal within angle degrees (flat and parallel to that plane); "
        "[{region: {...}, surface: {...}, angle: 2, distance: 0.005}]: it lies within distance of the surface's "
        "boundary, its normal within angle degrees of the surface's (tangent to it)")
    area: AreaSpec | None = Field(
        None, description="bounds on the area (2D: length) of each shape's boundary inside the domain, in the "
        "problem's units: {max: 2.5}, {min: 1.0}, or both; a number is the largest area")
    reference: ReferenceBoundSpec = Field(
        default_factory=ReferenceBoundSpec, description="where the problem states a reference solution: how close "
        "each shape's surface must come to it, {cd2: 0.02, area: 0.02} (the CD2 between the surfaces and the "
        "relative difference of their areas)")

    #: the key a bare number stands for, by field: ``min_thickness: 0.05`` is ``{size: 0.05}``
    NUMBER_MEANS: ClassVar[dict[str, str]] = {"volume_fraction": "max", "area": "max", "min_thickness": "size",
                                               "min_gap": "size", "min_radius": "radius"}

    @field_validator("volume_fraction", "area", "min_thickness", "min_gap", "min_radius", mode="before")
    @classmethod
    def _a_number_is_its_main_key(cls, v: Any, info: ValidationInfo) -> Any:
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            return {cls.NUMBER_MEANS[info.field_name]: v}
        return v


Count = Annotated[int, Field(ge=0, strict=True)]


class TopologySpec(Node):
    """The topology every shape must have inside E (:class:`~ginn.problems.problem.Topology`)."""

    components: Literal[1] | None = Field(None, description="1: one piece (the same as tolerances.connected: true)")
    holes: Count | None = Field(None, description="2D: the number of holes (b1)")
    tunnels: Count | None = Field(None, description="3D: the number of tunnels (b1)")
    cavities: Count | None = Field(None, description="3D: the number of enclosed cavities (b2)")

    @field_validator("components", mode="before")
    @classmethod
    def _one_piece(cls, v):
        if v is not None and v != 1:
            raise ValueError(f"only 1 is supported (one piece inside E), got {v!r}; leave it out for no requirement")
        return v

    @field_validator("holes")
    @classmethod
    def _holes_are_2d(cls, v, info: ValidationInfo):
        if v is not None and spec_dim(info) == 3:
            raise ValueError("a 2D target; a 3D problem states tunnels and cavities")
        return v

    @field_validator("tunnels", "cavities")
    @classmethod
    def _tunnels_are_3d(cls, v, info: ValidationInfo):
        if v is not None and spec_dim(info) == 2:
            raise ValueError("a 3D target; a 2D problem states holes")
        return v

    def build(self, dim: int) -> Topology:
        return Topology(b1=self.holes if dim == 2 else self.tunnels, b2=self.cavities if dim == 3 else None)


class MirrorSpec(Node):
    """A mirror plane (2D: line) through ``point`` with normal ``normal``."""

    point: Point
    normal: Direction


class RotationSpec(Node):
    """An n-fold rotation about ``center`` (3D: about the line through it along ``axis``)."""

    center: Point
    n: Annotated[int, Field(ge=2, strict=True)]
    axis: Dir3 | None = None

    @model_validator(mode="after")
    def _axis(self, info: ValidationInfo):
        d = spec_dim(info)
        if d == 3 and self.axis is None:
            raise ValueError("a 3D rotation needs 'axis'")
        if d == 2 and self.axis is not None:
            raise ValueError("'axis' is only used in 3D")
        return self


class SymmetrySpec(Node):
    """The symmetries every shape has (by construction; :mod:`ginn.geometry.symmetry`)."""

    mirrors: list[MirrorSpec] = Field(default_factory=list)
    rotation: RotationSpec | None = None

    @model_validator(mode="after")
    def _group(self):
        self.build()
        return self

    def build(self) -> Symmetry | None:
        if not self.mirrors and self.rotation is None:
            return None
        rot = self.rotation
        return Symmetry(
            tuple(Mirror(tuple(m.point), tuple(m.normal)) for m in self.mirrors),
            None if rot is None else Rotation(tuple(rot.center), rot.n, None if rot.axis is None else tuple(rot.axis)),
        )


class ProblemSpec(BaseModel):
    """A validated problem spec. ``defaults`` and ``presets`` are partial RunConfig dicts.

    Use :func:`ginn.problems.load_spec` to read one; :meth:`build` for the geometry;
    :meth:`config` for the run configuration.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    # the run directory is `<name>-<timestamp>-<n>`: 200 characters keep it within the 255 bytes of a file name
    name: Annotated[str, Field(min_length=1, max_length=200, pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")]
    kind: Literal[TASK_KINDS] = "shape"  # type: ignore[valid-type]
    description: str = ""
    reference: Literal["minimal-surface"] | None = Field(
        None, description="an independent reference solution that evaluation compares against: minimal-surface "
        "(the interfaces are a closed polygon; the discrete minimal surface spanning it)")
    geometry: GeometrySpec | None = Field(default=None, validate_default=True)
    tolerances: TolerancesSpec = Field(default_factory=TolerancesSpec)
    topology: TopologySpec = Field(default_factory=TopologySpec)
    symmetry: SymmetrySpec = Field(default_factory=SymmetrySpec)
    physics: PhysicsSpec | None = Field(
        None, description="a structural problem: material, supports and load cases; the weighted compliance is "
        "minimised (docs/structural.md)")
    defaults: dict[str, Any] = Field(default_factory=dict)
    presets: dict[str, dict[str, Any]] = Field(default_factory=dict)
    _base_dir: Path | None = PrivateAttr(default=None)
    _source: str = PrivateAttr(default="")
    _derived: tuple | None = PrivateAttr(default=None)

    @field_validator("name", mode="before")
    @classmethod
    def _name_is_text(cls, v):
        # YAML reads off, no, yes, 1e3 ... as booleans and numbers
        if not isinstance(v, str):
            raise ValueError(f"must be text; YAML read it as {v!r}: put the name in quotes")
        return v

    @field_validator("physics")
    @classmethod
    def _needs_volume_bound(cls, v, info: ValidationInfo):
        t = info.data.get("tolerances")
        if v is not None and (t is None or t.volume_fraction is None or t.volume_fraction.max is None):
            raise ValueError("a structural problem needs tolerances.volume_fraction.max (without a volume bound the "
                             "stiffest shape is all of E)")
        return v

    @field_validator("geometry")
    @classmethod
    def _needs_geometry(cls, v, info: ValidationInfo):
        if v is None and info.data.get("kind", "shape") == "shape":
            raise ValueError("required for a 'shape' problem")
        return v

    @property
    def source(self) -> str:
        """The file the spec was read from (or ``<dict>``)."""
        return self._source

    # -- configuration --

    def config(self, preset: str | None = None, *overrides: dict) -> RunConfig:
        """The resolved :class:`~ginn.config.RunConfig`: ``{problem, preset, params.kind}``, then
        (shape problems) the settings derived from the geometry (:mod:`ginn.problems.derived`),
        then ``defaults``, then ``presets[preset]``, then each override dict. The one place a
        spec becomes a run configuration.

        Raises:
            ConfigError: unknown preset or an invalid value (overrides); values from the spec
                itself were already checked by :func:`validate_spec`.
        """
        if preset is not None and preset not in self.presets:
            avail = ", ".join(sorted(self.presets)) or "none"
            raise ConfigError(f"unknown preset '{preset}' for problem '{self.name}' (available: {avail})")
        upper = [self.defaults, *self.preset_layers(preset), *overrides]
        return self.check_kind(build_config(self._head(preset), self._derived_for(upper), *upper))

    def check_kind(self, cfg: RunConfig) -> RunConfig:
        """``cfg``, if its task parameters are of this problem's kind (``params.kind``); else a
        one-line :class:`ConfigError`."""
        if cfg.params.kind != self.kind:
            raise ConfigError(f"config field 'params.kind': {cfg.params.kind!r} is not the kind of problem {self.name} ({self.kind!r})")
        return cfg

    def _derived_for(self, upper: list[dict]) -> dict:
        """The derived layer under the partial configurations ``upper``: a budget stated there
        (``training.iterations``) keeps the derived schedule's shape, the learning rate halved every
        third of the run (``training.lr_decay_every``) and a structural problem's connectedness term
        from half the run (``losses.connectedness.start``), where those are not stated too."""
        derived = self.derived()[0]
        stated = [layer for layer in upper if isinstance(layer, dict)]
        trainings = [layer.get("training") or {} for layer in stated]
        iterations = [t["iterations"] for t in trainings if isinstance(t, dict) and "iterations" in t]
        n = iterations[-1] if iterations else None
        if not isinstance(n, int) or isinstance(n, bool) or n < 3:
            return derived  # nothing stated, or left to the configuration's own checks

        def given(group: str, *keys: str) -> bool:
            for layer in stated:
                node = layer.get(group)
                for k in keys:
                    node = node.get(k) if isinstance(node, dict) else None
                if node is not None:
                    return True
            return False

        out = dict(derived)
        if "lr_decay_every" in derived.get("training", {}) and not given("training", "lr_decay_every"):
            out["training"] = {**derived["training"], "lr_decay_every": n // 3}
        connectedness = derived.get("losses", {}).get("connectedness", {})
        if "start" in connectedness and not given("losses", "connectedness", "start"):
            share = connectedness["start"] * n // derived["training"]["iterations"]  # the same share of the budget
            out["losses"] = {**derived["losses"], "connectedness": {**connectedness, "start": share}}
        return out

    def preset_layers(self, preset: str | None) -> list[dict]:
        """The partial configurations of ``preset``, outermost first: a preset that says
        ``extends: OTHER`` is ``OTHER``'s layers with its own on top (the paper's settings once,
        their variants as differences)."""
        layers: list[dict] = []
        seen: list[str] = []
        while preset is not None:
            if preset in seen:
                raise SpecError(f"spec field 'presets.{seen[0]}.extends': a cycle ({' -> '.join([*seen, preset])})")
            if preset not in self.presets:
                raise SpecError(f"spec field 'presets.{seen[-1]}.extends': unknown preset '{preset}' "
                                f"(available: {', '.join(sorted(self.presets))})")
            seen.append(preset)
            layer = dict(self.presets[preset])
            preset = layer.pop("extends", None)
            if preset is not None and not isinstance(preset, str):
                raise SpecError(f"spec field 'presets.{seen[-1]}.extends': must be the name of another preset")
            layers.insert(0, layer)
        return layers

    def derived(self) -> tuple[dict, dict[str, str]]:
        """The settings derived from the geometry and why (:func:`ginn.problems.derived.derived_defaults`);
        nothing for problems without geometry."""
        if self.geometry is None:
            return {}, {}
        if self._derived is None:
            self._derived = derived_defaults(self.build())
        return self._derived

    def derived_notes(self, cfg: RunConfig) -> list[str]:
        """``path = value  (why)`` for each derived setting whose value ``cfg`` holds (one that the
        spec, a preset or an override changed is left out)."""
        values, why = self.derived()
        flat = flattened(cfg.model_dump(mode="json"))
        return [f"{path} = {value!r}" + (f"  ({why[path]})" if path in why else "")
                for path, value in flattened(values).items() if flat.get(path) == value]

    def _head(self, preset: str | None) -> dict:
        return {"problem": self.name, "preset": preset, "params": {"kind": self.kind}}

    # -- geometry --

    def _tolerances(self) -> Tolerances:
        t = self.tolerances
        built = {k: getattr(t, k) and getattr(t, k).build()
                 for k in ("volume_fraction", "area", "min_thickness", "min_gap", "overhang", "min_radius", "reference")}
        built["faces"] = ()  # regions need the geometry's build (ProblemSpec.build)
        return Tolerances(**{**t.model_dump(exclude=set(built)), **built,
                             "connected": t.connected or self.topology.components == 1})

    @staticmethod
    def _face(f: FaceSpec, path: str, make, interface_tolerance: float) -> Face:
        region = make(f.region, f"{path}.region")
        if f.surface is None:
            return Face(region, _unit(f.normal), float(f.angle))
        distance = float(f.distance) if f.distance is not None else float(interface_tolerance)
        return Face(region, None, float(f.angle), make(f.surface, f"{path}.surface"), distance)

    def build(self) -> Problem:
        """The :class:`Problem` (loads meshes; checks interfaces and obstacles against the domain).

        Raises:
            SpecError: one line naming the field (unreadable or non-watertight mesh, an interface
                outside the domain, a problem kind without geometry, ...).
        """
        if self.geometry is None:
            raise SpecError(f"spec field 'geometry': problem kind '{self.kind}' has no geometry")
        g = self.geometry
        base = self._base_dir or Path.cwd()
        dim = g.dim
        domain = Box(tuple(float(v) for v in g.domain.lo), tuple(float(v) for v in g.domain.hi))

        def make(node, path: str):
            return node.make(dim, base, path)

        design = make(g.design_region, "geometry.design_region") if g.design_region is not None else None
        obstacles = tuple(make(o, f"geometry.obstacles[{i}]") for i, o in enumerate(g.obstacles))
        faces = tuple(make(n, f"geometry.interfaces[{i}]") for i, n in enumerate(g.interfaces))
        lo, hi = domain.tensors(dtype=torch.float64)
        tol = 1e-9 * float((hi - lo).abs().max())
        for i, f in enumerate(faces):
            b = f.bounds()
            if b is not None and (bool((b[0] < lo - tol).any()) or bool((b[1] > hi + tol).any())):
                raise SpecError(
                    f"spec field 'geometry.interfaces[{i}]': lies outside the domain "
                    f"(extent {_fmt(b[0])}..{_fmt(b[1])}, domain {_fmt(lo)}..{_fmt(hi)})"
                )
        if design is not None and obstacles:
            design = csg.Difference(design, *obstacles)
        symmetry = self.symmetry.build()
        unit_scale = float(g.unit_scale) if g.unit_scale is not None else half_longest_side(domain)
        flat = tuple(self._face(f, f"tolerances.faces[{i}]", make, self.tolerances.interface * unit_scale)
                     for i, f in enumerate(self.tolerances.faces))
        if symmetry is not None:
            check_symmetric(symmetry, domain, design, faces, self.tolerances.interface * unit_scale)
        if dim == 2 and self.topology.holes is not None:
            _refuse_below(self.topology.holes, forced_holes(domain, design, faces), "holes", "hole",
                          "round the parts of X \\ E inside its interface circles")
        if dim == 3 and self.topology.tunnels is not None:
            _refuse_below(self.topology.tunnels, forced_tunnels(domain, design, faces), "tunnels", "tunnel",
                          "round the channels through X \\ E inside its interface cylinder walls")
        return Problem(
            name=self.name,
            domain=domain,
            design_region=design,
            interfaces=faces,
            obstacles=obstacles,
            interface_band=float(g.interface_band),
            unit_scale=unit_scale,
            tolerances=replace(self._tolerances(), faces=flat),
            topology=self.topology.build(dim),
            symmetry=symmetry,
            description=self.description,
            reference=self.reference,
            physics=None if self.physics is None else self.physics.build(faces, dim, base),
            extra={"kind": self.kind, "source": self._source},
        )


def _refuse_below(target: int, forced: list[int], key: str, noun: str, why: str) -> None:
    """A one-line SpecError when ``target`` is below the features the interfaces ``forced`` make."""
    if target < len(forced):
        n = len(forced)
        which = ", ".join(f"interfaces[{i}]" for i in forced)
        raise SpecError(f"spec field 'topology.{key}': {target} is fewer than the {n} {noun}{'' if n == 1 else 's'} "
                        f"every shape has {why} ({which})")


def _fmt(t) -> str:
    return "(" + ", ".join(f"{float(v):.4g}" for v in t) + ")"


# --- validation with one-line errors -------------------------------------------------------------

_ALL_TAGS = set(REGION_TYPES) | set(INTERFACE_TYPES)


def validate_spec(data: Any, base_dir: Path | None = None, source: str = "<dict>") -> ProblemSpec:
    """Validate a parsed spec (dict) into a :class:`ProblemSpec`.

    Arguments:
        data: the parsed YAML.
        base_dir: directory against which relative mesh paths resolve.
        source: the file name, for messages.

    Raises:
        SpecError: one line, ``spec field '<path>': <what is wrong>``.
    """
    if not isinstance(data, dict):
        raise SpecError(f"spec {source}: the top level must be a mapping (name, kind, geometry, ...)")
    dim = None
    geo = data.get("geometry")
    if isinstance(geo, dict) and geo.get("dim") in (2, 3) and not isinstance(geo.get("dim"), bool):
        dim = geo["dim"]
    try:
        spec = ProblemSpec.model_validate(data, context={"dim": dim, "base_dir": base_dir})
    except ValidationError as e:
        err = e.errors()[0]
        raise SpecError(f"spec field '{field_path(err.get('loc', ()), data, _ALL_TAGS)}': {field_message(err)}") from None
    _check_configs(spec)
    spec._base_dir = base_dir
    spec._source = source
    return spec


def _check_configs(spec: ProblemSpec) -> None:
    """Validate ``defaults`` and every preset with :func:`ginn.config.build_config`."""
    def run(prefix: str, *layers: dict) -> None:
        try:
            build_config(*layers)
        except ConfigError as e:
            text = str(e)
            if text.startswith("config field '"):
                inner, _, rest = text[len("config field '"):].partition("'")
                rest = rest.replace("Value error, ", "")
                raise SpecError(f"spec field '{prefix}.{inner}'{rest}") from None
            raise SpecError(f"spec field '{prefix}': {text}") from None

    run("defaults", spec._head(None), spec.defaults)
    for name in spec.presets:
        run(f"presets.{name}", spec._head(name), spec.defaults, *spec.preset_layers(name))
