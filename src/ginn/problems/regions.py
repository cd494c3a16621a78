"""Region nodes of the spec schema: primitives, meshes and CSG (``geometry.design_region``,
``geometry.obstacles``), tagged by ``type``."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated, ClassVar, Literal, Union

from pydantic import Field, field_validator

from ..geometry import csg
from ..geometry import primitives as prim
from ..geometry.base import Region
from ..geometry.mesh import MeshRegion, load_mesh
from .nodes import Dir3, Direction, Finite, MeshPath, Point, Point2, Positive, ShapeNode, Vec3, built, check_lo_hi


class RegionNode(ShapeNode):
    """A node that makes a :class:`~ginn.geometry.base.Region`."""

    wrap: ClassVar[Callable] = staticmethod(csg.Transformed)

    def make(self, dim: int, base_dir: Path, path: str) -> Region:
        return super().make(dim, base_dir, path)


class BoxNode(RegionNode):
    """Axis-aligned box ``[lo, hi]`` (any dimension)."""

    type: Literal["box"]
    lo: Point
    hi: Point

    def _check(self, info):
        check_lo_hi(self.lo, self.hi)

    def _make(self, dim, base_dir, path):
        return built(path, lambda: prim.AABox(self.lo, self.hi))


class RectangleNode(BoxNode):
    """2D rectangle ``[lo, hi]``."""

    type: Literal["rectangle"]  # type: ignore[assignment]
    dims_allowed: ClassVar[tuple[int, ...]] = (2,)


class BallNode(RegionNode):
    type: Literal["ball"]
    center: Point
    radius: Positive

    def _make(self, dim, base_dir, path):
        return built(path, lambda: prim.Ball(self.center, self.radius))


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
        return built(path, lambda: prim.Polygon(self.vertices))


class HalfSpaceNode(RegionNode):
    """``(x - point) . normal <= 0`` (``normal`` points out of the region)."""

    type: Literal["halfspace"]
    point: Point
    normal: Direction

    def _make(self, dim, base_dir, path):
        return built(path, lambda: prim.HalfSpace(self.point, self.normal))


class CylinderNode(RegionNode):
    """Finite solid cylinder: axis midpoint ``center``, direction ``axis``."""

    type: Literal["cylinder"]
    center: Vec3
    axis: Dir3
    radius: Positive
    length: Positive
    dims_allowed: ClassVar[tuple[int, ...]] = (3,)

    def _make(self, dim, base_dir, path):
        return built(path, lambda: prim.Cylinder(self.center, self.axis, self.radius, self.length))


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
        return built(path, lambda: prim.Extrusion(prim.Polygon(self.vertices), self.z0, self.z1))


class MeshNode(RegionNode):
    """A watertight triangle mesh (STL/OBJ/PLY); vertices mapped by ``p -> (p - center) / scale``.
    A relative ``path`` is resolved against the spec file's directory."""

    type: Literal["mesh"]
    path: MeshPath
    center: Vec3 | None = None
    scale: Positive | None = None
    dims_allowed: ClassVar[tuple[int, ...]] = (3,)

    def _make(self, dim, base_dir, path):
        mesh = built(f"{path}.path", lambda: load_mesh(self.path, self.center, self.scale))
        return built(path, lambda: MeshRegion(mesh))


class _CSGNode(RegionNode):
    children: list[RegionSpec]
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
