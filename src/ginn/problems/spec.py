"""The problem spec schema (pydantic) and its translation into geometry objects.

A spec is data (YAML): see ``docs/problem-spec.md`` for the reference. :func:`validate_spec` turns
a parsed dict into a :class:`ProblemSpec` or raises :class:`~ginn.errors.SpecError` with ONE line
naming the field path (``spec field 'geometry.interfaces[1].radius': must be > 0``);
:meth:`ProblemSpec.build` creates the :class:`~ginn.problems.problem.Problem` (loading meshes and
checking that the interfaces lie in the domain), with the same kind of errors.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal, Union

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from ..errors import ConfigError, SpecError
from ..geometry import csg, interfaces as itf, primitives as prim
from ..geometry.base import Box, Interface, Region
from ..geometry.mesh import MeshInterface, MeshRegion, load_mesh
from .problem import Problem

# --- scalar and vector types ---------------------------------------------------------------------

Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]


def _dim(info: ValidationInfo) -> int | None:
    ctx = info.context or {}
    return ctx.get("dim")


def _check_point(v: list[float], info: ValidationInfo) -> list[float]:
    d = _dim(info)
    if d is not None and len(v) != d:
        raise ValueError(f"must have {d} coordinates (geometry.dim = {d}), got {len(v)}")
    return v


def _check_vec3(v: list[float]) -> list[float]:
    if len(v) != 3:
        raise ValueError(f"must have 3 coordinates, got {len(v)}")
    return v


def _check_vec2(v: list[float]) -> list[float]:
    if len(v) != 2:
        raise ValueError(f"must have 2 coordinates, got {len(v)}")
    return v


def _nonzero(v: list[float]) -> list[float]:
    if math.sqrt(sum(c * c for c in v)) <= 1e-12:
        raise ValueError("must be a non-zero vector")
    return v


Point = Annotated[list[Finite], AfterValidator(_check_point)]
Direction = Annotated[list[Finite], AfterValidator(_check_point), AfterValidator(_nonzero)]
Vec3 = Annotated[list[Finite], AfterValidator(_check_vec3)]
Dir3 = Annotated[list[Finite], AfterValidator(_check_vec3), AfterValidator(_nonzero)]
Point2 = Annotated[list[Finite], AfterValidator(_check_vec2)]


class _Node(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Transform(_Node):
    """A rigid motion applied to a node: rotate (degrees; about ``axis`` in 3D), then translate."""

    rotate: Finite = 0.0
    axis: Dir3 | None = None
    translate: Point | None = None

    @model_validator(mode="after")
    def _axis(self, info: ValidationInfo):
        d = _dim(info)
        if d == 3 and self.rotate != 0.0 and self.axis is None:
            raise ValueError("a 3D rotation needs 'axis'")
        if d == 2 and self.axis is not None:
            raise ValueError("'axis' is only used in 3D")
        return self

    def matrices(self, dim: int):
        R = None if self.rotate == 0.0 else csg.rotation_matrix(dim, self.rotate, self.axis)
        return R, self.translate


class _Shape(_Node):
    """Common to every node: an optional rigid ``transform`` and the dimensions it is valid in."""

    transform: Transform | None = None
    dims_allowed: ClassVar[tuple[int, ...]] = (2, 3)

    @model_validator(mode="after")
    def _check_dim(self, info: ValidationInfo):
        d = _dim(info)
        if d is not None and d not in self.dims_allowed:
            kind = getattr(self, "type", type(self).__name__)
            need = " or ".join(f"{x}D" for x in self.dims_allowed)
            raise ValueError(f"type '{kind}' needs a {need} geometry (geometry.dim = {d})")
        self._check(info)
        return self

    def _check(self, info: ValidationInfo) -> None:
        pass


# --- regions -------------------------------------------------------------------------------------


def _built(path: str, fn):
    """Run a constructor; a ValueError becomes a one-line SpecError naming ``path``."""
    try:
        return fn()
    except ValueError as e:
        raise SpecError(f"spec field '{path}': {e}") from None


class RegionNode(_Shape):
    def make(self, dim: int, base_dir: Path, path: str = "region") -> Region:
        """The geometry object; errors are SpecErrors naming ``path`` (this node's field path)."""
        r = self._make(dim, base_dir, path)
        if self.transform is not None:
            R, t = self.transform.matrices(dim)
            r = _built(f"{path}.transform", lambda: csg.Transformed(r, R, t))
        return r

    def _make(self, dim: int, base_dir: Path, path: str) -> Region:  # pragma: no cover - abstract
        raise NotImplementedError


def _lo_hi(lo: list[float], hi: list[float]) -> None:
    for i, (a, b) in enumerate(zip(lo, hi)):
        if not a < b:
            raise ValueError(f"lo[{i}] = {a} must be below hi[{i}] = {b}")


class BoxNode(RegionNode):
    """Axis-aligned box ``[lo, hi]`` (any dimension)."""

    type: Literal["box"]
    lo: Point
    hi: Point

    def _check(self, info):
        _lo_hi(self.lo, self.hi)

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: prim.AABox(self.lo, self.hi))


class RectangleNode(BoxNode):
    """2D rectangle ``[lo, hi]``."""

    type: Literal["rectangle"]  # type: ignore[assignment]
    dims_allowed: ClassVar[tuple[int, ...]] = (2,)


class BallNode(RegionNode):
    type: Literal["ball"]
    center: Point
    radius: Positive

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: prim.Ball(self.center, self.radius))


class DiskNode(BallNode):
    type: Literal["disk"]  # type: ignore[assignment]
    dims_allowed: ClassVar[tuple[int, ...]] = (2,)


class SphereNode(BallNode):
    type: Literal["sphere"]  # type: ignore[assignment]
    dims_allowed: ClassVar[tuple[int, ...]] = (3,)


class PolygonNode(RegionNode):
    """Simple 2D polygon."""

    type: Literal["polygon"]
    vertices: Annotated[list[Point2], Field(min_length=3)]
    dims_allowed: ClassVar[tuple[int, ...]] = (2,)

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: prim.Polygon(self.vertices))


class HalfSpaceNode(RegionNode):
    """``(x - point) . normal <= 0`` (``normal`` points out of the region)."""

    type: Literal["halfspace"]
    point: Point
    normal: Direction

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: prim.HalfSpace(self.point, self.normal))


class CylinderNode(RegionNode):
    """Finite solid cylinder: axis midpoint ``center``, direction ``axis``."""

    type: Literal["cylinder"]
    center: Vec3
    axis: Dir3
    radius: Positive
    length: Positive
    dims_allowed: ClassVar[tuple[int, ...]] = (3,)

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: prim.Cylinder(self.center, self.axis, self.radius, self.length))


class ExtrusionNode(RegionNode):
    """2D polygon (xy) extruded along z over ``[z0, z1]``."""

    type: Literal["extrusion"]
    vertices: Annotated[list[Point2], Field(min_length=3)]
    z0: Finite
    z1: Finite
    dims_allowed: ClassVar[tuple[int, ...]] = (3,)

    def _check(self, info):
        if not self.z0 < self.z1:
            raise ValueError(f"z0 = {self.z0} must be below z1 = {self.z1}")

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: prim.Extrusion(prim.Polygon(self.vertices), self.z0, self.z1))


def _resolve(path: str, info: ValidationInfo) -> str:
    base = (info.context or {}).get("base_dir")
    p = Path(path).expanduser()
    if not p.is_absolute() and base is not None:
        p = Path(base) / p
    if not p.is_file():
        raise ValueError(f"mesh file not found: {p}")
    return str(p)


MeshPath = Annotated[str, Field(min_length=1), AfterValidator(_resolve)]


class MeshNode(RegionNode):
    """A watertight triangle mesh (STL/OBJ/PLY); vertices mapped by ``p -> (p - center) / scale``.
    A relative ``path`` is resolved against the spec file's directory."""

    type: Literal["mesh"]
    path: MeshPath
    center: Vec3 | None = None
    scale: Positive | None = None
    dims_allowed: ClassVar[tuple[int, ...]] = (3,)

    def _make(self, dim, base_dir, path):
        mesh = _built(f"{path}.path", lambda: load_mesh(self.path, self.center, self.scale))
        return _built(path, lambda: MeshRegion(mesh))


class _CSGNode(RegionNode):
    children: list["RegionSpec"]
    min_children: ClassVar[int] = 1

    @field_validator("children")
    @classmethod
    def _count(cls, v: list) -> list:
        if len(v) < cls.min_children:
            raise ValueError(f"needs at least {cls.min_children} child{'ren' if cls.min_children > 1 else ''}, got {len(v)}")
        return v

    def _kids(self, dim, base_dir, path) -> list[Region]:
        return [c.make(dim, base_dir, f"{path}.children[{i}]") for i, c in enumerate(self.children)]


class UnionNode(_CSGNode):
    type: Literal["union"]

    def _make(self, dim, base_dir, path):
        return csg.Union(*self._kids(dim, base_dir, path))


class IntersectionNode(_CSGNode):
    type: Literal["intersection"]

    def _make(self, dim, base_dir, path):
        return csg.Intersection(*self._kids(dim, base_dir, path))


class DifferenceNode(_CSGNode):
    """The first child minus all the others."""

    type: Literal["difference"]
    min_children: ClassVar[int] = 2

    def _make(self, dim, base_dir, path):
        parts = self._kids(dim, base_dir, path)
        return csg.Difference(parts[0], *parts[1:])


RegionSpec = Annotated[
    Union[
        BoxNode, RectangleNode, BallNode, DiskNode, SphereNode, PolygonNode, HalfSpaceNode, CylinderNode,
        ExtrusionNode, MeshNode, UnionNode, IntersectionNode, DifferenceNode,
    ],
    Field(discriminator="type"),
]
for _cls in (UnionNode, IntersectionNode, DifferenceNode):
    _cls.model_rebuild()

REGION_TYPES = ("box", "rectangle", "ball", "disk", "sphere", "polygon", "halfspace", "cylinder", "extrusion", "mesh",
                "union", "intersection", "difference")

# --- interfaces ----------------------------------------------------------------------------------


class InterfaceNode(_Shape):
    def make(self, dim: int, base_dir: Path, path: str = "interface") -> Interface:
        """The interface object; errors are SpecErrors naming ``path``."""
        i = self._make(dim, base_dir, path)
        if self.transform is not None:
            R, t = self.transform.matrices(dim)
            i = _built(f"{path}.transform", lambda: itf.TransformedInterface(i, R, t))
        return i

    def _make(self, dim: int, base_dir: Path, path: str) -> Interface:  # pragma: no cover - abstract
        raise NotImplementedError


class SegmentNode(InterfaceNode):
    """Segment ``a``-``b`` with an optional constant prescribed ``normal``."""

    type: Literal["segment"]
    a: Point
    b: Point
    normal: Direction | None = None

    def _check(self, info):
        if self.a == self.b:
            raise ValueError("a and b must differ")

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: itf.Segment(self.a, self.b, self.normal))


class PolylineNode(InterfaceNode):
    """Polyline through ``points`` (optionally ``closed``); ``normal``: omitted (none), one vector,
    one vector per segment, or (2D) ``left`` / ``right``."""

    type: Literal["polyline"]
    points: Annotated[list[Point], Field(min_length=2)]
    closed: bool = False
    normal: Any = None

    def _check(self, info):
        n = self.normal
        if n is None or n in ("left", "right"):
            return
        d = _dim(info)
        m = len(self.points) if self.closed else len(self.points) - 1

        def vec(v) -> bool:
            return isinstance(v, list) and len(v) == d and all(isinstance(c, (int, float)) and math.isfinite(c) for c in v)

        if vec(n) or (isinstance(n, list) and len(n) == m and all(vec(v) for v in n)):
            return
        raise ValueError(f"normal must be omitted, 'left', 'right', one {d}D vector or {m} of them (one per segment)")

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: itf.Polyline(self.points, self.closed, self.normal))


NormalDir = Literal["inward", "outward", "none"]


class CircleNode(InterfaceNode):
    """2D circle; normals ``inward`` (toward the centre: out of a shape around a hole), ``outward``, ``none``."""

    type: Literal["circle"]
    center: Point
    radius: Positive
    normals: NormalDir = "inward"
    dims_allowed: ClassVar[tuple[int, ...]] = (2,)

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: itf.Circle(self.center, self.radius, self.normals))


class CylinderWallNode(InterfaceNode):
    """Lateral surface of a finite cylinder (axis midpoint ``center``); normals default ``inward``."""

    type: Literal["cylinder_wall"]
    center: Vec3
    axis: Dir3
    radius: Positive
    length: Positive
    normals: NormalDir = "inward"
    dims_allowed: ClassVar[tuple[int, ...]] = (3,)

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: itf.CylinderWall(self.center, self.axis, self.radius, self.length, self.normals))


class AnnulusNode(InterfaceNode):
    """Flat ring (3D) with prescribed normal ``normal`` (``normals: none`` to drop it)."""

    type: Literal["annulus"]
    center: Vec3
    normal: Dir3
    r_inner: NonNegative = 0.0
    r_outer: Positive
    normals: Literal["given", "none"] = "given"
    dims_allowed: ClassVar[tuple[int, ...]] = (3,)

    def _check(self, info):
        if not self.r_inner < self.r_outer:
            raise ValueError(f"r_inner = {self.r_inner} must be below r_outer = {self.r_outer}")

    def _make(self, dim, base_dir, path):
        return _built(path, lambda: itf.Annulus(self.center, self.normal, self.r_inner, self.r_outer, self.normals))


class MeshInterfaceNode(InterfaceNode):
    """A mesh surface; one component per connected component of the mesh. ``normals``: ``faces``
    (as stored), ``flipped`` or ``none``."""

    type: Literal["mesh"]
    path: MeshPath
    center: Vec3 | None = None
    scale: Positive | None = None
    normals: Literal["faces", "flipped", "none"] = "faces"
    dims_allowed: ClassVar[tuple[int, ...]] = (3,)

    def _make(self, dim, base_dir, path):
        mesh = _built(f"{path}.path", lambda: load_mesh(self.path, self.center, self.scale))
        return _built(path, lambda: MeshInterface(mesh, self.normals))


class GroupNode(InterfaceNode):
    """Several interfaces forming ONE component (e.g. a bolt hole's wall and its top ring)."""

    type: Literal["group"]
    parts: list["InterfaceSpec"]

    @field_validator("parts")
    @classmethod
    def _count(cls, v: list) -> list:
        if not v:
            raise ValueError("needs at least 1 part, got 0")
        return v

    def _make(self, dim, base_dir, path):
        parts = [p.make(dim, base_dir, f"{path}.parts[{i}]") for i, p in enumerate(self.parts)]
        return _built(path, lambda: itf.InterfaceUnion(parts, merge=True))


InterfaceSpec = Annotated[
    Union[SegmentNode, PolylineNode, CircleNode, CylinderWallNode, AnnulusNode, MeshInterfaceNode, GroupNode],
    Field(discriminator="type"),
]
GroupNode.model_rebuild()

INTERFACE_TYPES = ("segment", "polyline", "circle", "cylinder_wall", "annulus", "mesh", "group")

# --- geometry and the whole spec -----------------------------------------------------------------


class DomainSpec(_Node):
    """The box X = [lo, hi]."""

    lo: Point
    hi: Point

    @model_validator(mode="after")
    def _order(self):
        _lo_hi(self.lo, self.hi)
        return self


class GeometrySpec(_Node):
    """Domain, design region, interfaces and obstacles of a shape problem."""

    dim: Literal[2, 3]
    domain: DomainSpec
    design_region: RegionSpec | None = None
    interfaces: list[InterfaceSpec] = Field(default_factory=list)
    obstacles: list[RegionSpec] = Field(default_factory=list)
    interface_band: NonNegative = 0.0
    unit_scale: Positive = 1.0


class ProblemSpec(BaseModel):
    """A validated problem spec. ``defaults`` and ``presets`` are partial RunConfig dicts.

    Use :func:`ginn.problems.load_spec` to read one; :meth:`build` for the geometry;
    :meth:`config` for the run configuration.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: Annotated[str, Field(min_length=1, pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")]
    kind: Literal["shape", "mirror", "gray-scott"] = "shape"
    description: str = ""
    geometry: GeometrySpec | None = Field(default=None, validate_default=True)
    defaults: dict[str, Any] = Field(default_factory=dict)
    presets: dict[str, dict[str, Any]] = Field(default_factory=dict)
    _base_dir: Path | None = PrivateAttr(default=None)
    _source: str = PrivateAttr(default="")

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

    def config(self, preset: str | None = None, *overrides: dict):
        """The resolved :class:`~ginn.train.config.RunConfig`: ``{problem, preset}``, then
        ``defaults``, then ``presets[preset]``, then each override dict.

        Raises:
            ConfigError: unknown preset or an invalid value (overrides); values from the spec
                itself were already checked by :func:`validate_spec`.
        """
        from ..train.config import build_config

        if preset is not None and preset not in self.presets:
            avail = ", ".join(sorted(self.presets)) or "none"
            raise ConfigError(f"unknown preset '{preset}' for problem '{self.name}' (available: {avail})")
        head = {"problem": self.name, "preset": preset}
        return build_config(head, self.defaults, self.presets.get(preset, {}) if preset else {}, *overrides)

    # -- geometry --

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
        lo, hi = domain.tensors(dtype=_f64())
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
        return Problem(
            name=self.name,
            domain=domain,
            design_region=design,
            interfaces=faces,
            obstacles=obstacles,
            interface_band=float(g.interface_band),
            unit_scale=float(g.unit_scale),
            description=self.description,
            extra={"kind": self.kind, "source": self._source},
        )


def _f64():
    import torch

    return torch.float64


def _fmt(t) -> str:
    return "(" + ", ".join(f"{float(v):.4g}" for v in t) + ")"


# --- validation with one-line errors -------------------------------------------------------------

_ALL_TAGS = set(REGION_TYPES) | set(INTERFACE_TYPES)


def _field_path(loc: tuple, data: Any) -> str:
    """Readable path from a pydantic ``loc``: ``geometry.interfaces[1].radius`` (discriminator
    tags and validator wrappers dropped)."""
    out = ""
    cur = data
    for el in loc:
        if isinstance(el, int):
            out += f"[{el}]"
            cur = cur[el] if isinstance(cur, list) and -len(cur) <= el < len(cur) else None
            continue
        el = str(el)
        if isinstance(cur, dict) and el in cur:
            out += ("." if out else "") + el
            cur = cur[el]
        elif isinstance(cur, dict) and cur.get("type") == el and el in _ALL_TAGS:
            continue  # the discriminator tag
        elif "[" in el or "-" in el:
            continue  # a validator wrapper such as function-after[...]
        else:
            out += ("." if out else "") + el
            cur = None
    return out or "<root>"


def _message(err: dict) -> str:
    t = err.get("type", "")
    ctx = err.get("ctx") or {}
    msg = str(err.get("msg", "invalid value"))
    if t == "missing":
        return "required field is missing"
    if t == "extra_forbidden":
        return "unknown key"
    if t == "greater_than":
        return f"must be > {ctx.get('gt')}"
    if t == "greater_than_equal":
        return f"must be >= {ctx.get('ge')}"
    if t == "finite_number":
        return "must be a finite number (not nan or inf)"
    if t == "too_short":
        return f"needs at least {ctx.get('min_length')} item(s), got {ctx.get('actual_length')}"
    if t == "union_tag_invalid":
        return f"unknown type '{ctx.get('tag')}' (expected one of: {str(ctx.get('expected_tags', '')).replace(chr(39), '')})"
    if t == "union_tag_not_found":
        return "missing key 'type'"
    if t == "value_error":
        return msg.removeprefix("Value error, ")
    if t in ("float_parsing", "float_type"):
        return "must be a number"
    if t == "literal_error":
        return "must be " + msg.removeprefix("Input should be ")
    return msg[:1].lower() + msg[1:]


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
        raise SpecError(f"spec field '{_field_path(tuple(err.get('loc', ())), data)}': {_message(err)}") from None
    _check_configs(spec)
    spec._base_dir = base_dir
    spec._source = source
    return spec


def _check_configs(spec: ProblemSpec) -> None:
    """Validate ``defaults`` and every preset with :func:`ginn.train.config.build_config`."""
    from ..train.config import build_config

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

    run("defaults", spec.defaults)
    for name, over in spec.presets.items():
        run(f"presets.{name}", spec.defaults, over)
