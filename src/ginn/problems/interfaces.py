"""Interface nodes of the spec schema (``geometry.interfaces``), tagged by ``type``."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal, Union

from pydantic import Field, field_validator

from ..geometry import interfaces as itf
from ..geometry.base import Interface
from ..geometry.mesh import MeshInterface, load_mesh
from .nodes import Dir3, Direction, MeshPath, NonNegative, Point, Positive, ShapeNode, Vec3, built, spec_dim


class InterfaceNode(ShapeNode):
    """A node that makes an :class:`~ginn.geometry.base.Interface`."""

    wrap: ClassVar[Callable] = staticmethod(itf.TransformedInterface)

    def make(self, dim: int, base_dir: Path, path: str) -> Interface:
        return super().make(dim, base_dir, path)


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
        return built(path, lambda: itf.Segment(self.a, self.b, self.normal))


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
        d = spec_dim(info)
        m = len(self.points) if self.closed else len(self.points) - 1

        def vec(v) -> bool:
            return isinstance(v, list) and len(v) == d and all(isinstance(c, (int, float)) and math.isfinite(c) for c in v)

        if vec(n) or (isinstance(n, list) and len(n) == m and all(vec(v) for v in n)):
            return
        raise ValueError(f"normal must be omitted, 'left', 'right', one {d}D vector or {m} of them (one per segment)")

    def _make(self, dim, base_dir, path):
        return built(path, lambda: itf.Polyline(self.points, self.closed, self.normal))


NormalDir = Literal["inward", "outward", "none"]


class CircleNode(InterfaceNode):
    """2D circle; normals ``inward`` (toward the centre: out of a shape around a hole), ``outward``, ``none``."""

    type: Literal["circle"]
    center: Point
    radius: Positive
    normals: NormalDir = "inward"
    dims_allowed: ClassVar[tuple[int, ...]] = (2,)

    def _make(self, dim, base_dir, path):
        return built(path, lambda: itf.Circle(self.center, self.radius, self.normals))


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
        return built(path, lambda: itf.CylinderWall(self.center, self.axis, self.radius, self.length, self.normals))


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
        return built(path, lambda: itf.Annulus(self.center, self.normal, self.r_inner, self.r_outer, self.normals))


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
        mesh = built(f"{path}.path", lambda: load_mesh(self.path, self.center, self.scale))
        return built(path, lambda: MeshInterface(mesh, self.normals))


class GroupNode(InterfaceNode):
    """Several interfaces forming ONE component (e.g. a bolt hole's wall and its top ring)."""

    type: Literal["group"]
    parts: list[InterfaceSpec]

    @field_validator("parts")
    @classmethod
    def _count(cls, v: list) -> list:
        if not v:
            raise ValueError("needs at least 1 part, got 0")
        return v

    def _make(self, dim, base_dir, path):
        parts = [p.make(dim, base_dir, f"{path}.parts[{i}]") for i, p in enumerate(self.parts)]
        return built(path, lambda: itf.InterfaceUnion(parts, merge=True))


InterfaceSpec = Annotated[
    Union[SegmentNode, PolylineNode, CircleNode, CylinderWallNode, AnnulusNode, MeshInterfaceNode, GroupNode],
    Field(discriminator="type"),
]
GroupNode.model_rebuild()

INTERFACE_TYPES = ("segment", "polyline", "circle", "cylinder_wall", "annulus", "mesh", "group")
