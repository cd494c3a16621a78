"""Building blocks of the spec schema: scalar and vector field types, node base classes, transforms.

Every node is a frozen pydantic model that forbids unknown keys; a node validates against the
spec's dimension (passed in the validation context as ``dim``) and makes its geometry object with
errors that name its field path (:func:`built`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, ClassVar

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, ValidationInfo, model_validator

from ..errors import SpecError
from ..geometry import csg

#: The largest magnitude of a number in a spec: squares of lengths (the derived loss weights
#: divide by ``s^2``, distances are squared in the losses) stay finite in float32 (3.4e38).
MAX_MAGNITUDE = 1e15



def _not_a_boolean(v):
    # YAML reads yes, no, on, off, true as booleans, which pydantic would take for 1 and 0
    if isinstance(v, bool):
        raise ValueError(f"must be a number; YAML read it as {v}")
    return v


Finite = Annotated[float, Field(ge=-MAX_MAGNITUDE, le=MAX_MAGNITUDE, allow_inf_nan=False), BeforeValidator(_not_a_boolean)]
Positive = Annotated[float, Field(gt=0, le=MAX_MAGNITUDE, allow_inf_nan=False), BeforeValidator(_not_a_boolean)]
NonNegative = Annotated[float, Field(ge=0, le=MAX_MAGNITUDE, allow_inf_nan=False), BeforeValidator(_not_a_boolean)]
Fraction = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False), BeforeValidator(_not_a_boolean)]


def spec_dim(info: ValidationInfo) -> int | None:
    ctx = info.context or {}
    return ctx.get("dim")


def _check_point(v: list[float], info: ValidationInfo) -> list[float]:
    d = spec_dim(info)
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


class Node(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Transform(Node):
    """A rigid motion applied to a node: rotate (degrees; about ``axis`` in 3D), then translate."""

    rotate: Finite = 0.0
    axis: Dir3 | None = None
    translate: Point | None = None

    @model_validator(mode="after")
    def _axis(self, info: ValidationInfo):
        d = spec_dim(info)
        if d == 3 and self.rotate != 0.0 and self.axis is None:
            raise ValueError("a 3D rotation needs 'axis'")
        if d == 2 and self.axis is not None:
            raise ValueError("'axis' is only used in 3D")
        return self

    def matrices(self, dim: int):
        R = None if self.rotate == 0.0 else csg.rotation_matrix(dim, self.rotate, self.axis)
        return R, self.translate


class ShapeNode(Node):
    """Common to every node: an optional rigid ``transform`` and the dimensions it is valid in."""

    transform: Transform | None = None
    dims_allowed: ClassVar[tuple[int, ...]] = (2, 3)

    @model_validator(mode="after")
    def _check_dim(self, info: ValidationInfo):
        d = spec_dim(info)
        if d is not None and d not in self.dims_allowed:
            kind = getattr(self, "type", type(self).__name__)
            need = " or ".join(f"{x}D" for x in self.dims_allowed)
            raise ValueError(f"type '{kind}' needs a {need} geometry (geometry.dim = {d})")
        self._check(info)
        return self

    def _check(self, info: ValidationInfo) -> None:
        pass

    def make(self, dim: int, base_dir: Path, path: str):
        """The geometry object, with this node's ``transform`` applied; errors are SpecErrors naming
        ``path`` (this node's field path)."""
        obj = self._make(dim, base_dir, path)
        if self.transform is not None:
            R, t = self.transform.matrices(dim)
            obj = built(f"{path}.transform", lambda: self.wrap(obj, R, t))
        return obj

    def _make(self, dim: int, base_dir: Path, path: str):  # pragma: no cover - abstract
        raise NotImplementedError

    #: ``(object, R, t) -> the object moved by the rigid motion`` (a region or an interface wrapper)
    wrap: ClassVar[Callable]


def built(path: str, fn):
    """Run a constructor; a ValueError becomes a one-line SpecError naming ``path``."""
    try:
        return fn()
    except ValueError as e:
        raise SpecError(f"spec field '{path}': {e}") from None


def check_lo_hi(lo: list[float], hi: list[float]) -> None:
    for i, (a, b) in enumerate(zip(lo, hi)):
        if not a < b:
            raise ValueError(f"lo[{i}] = {a} must be below hi[{i}] = {b}")


def _resolve(path: str, info: ValidationInfo) -> str:
    base = (info.context or {}).get("base_dir")
    p = Path(path).expanduser()
    if not p.is_absolute() and base is not None:
        p = Path(base) / p
    if not p.is_file():
        raise ValueError(f"mesh file not found: {p}")
    return str(p)


MeshPath = Annotated[str, Field(min_length=1), AfterValidator(_resolve)]
