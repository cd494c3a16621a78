"""The ``physics`` block of a problem spec: material, supports and load cases of a structural
problem (``docs/structural.md``), translated into :class:`~ginn.problems.problem.Physics`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from ..errors import SpecError
from ..geometry.base import Interface, Region
from .nodes import Finite, Node, Point, Positive, spec_dim
from .problem import Load, LoadCase, Physics, Support
from .regions import RegionSpec

__all__ = ["PhysicsSpec"]

AXES = {"x": 0, "y": 1, "z": 2}


Index = Annotated[int, Field(ge=0)]


class PlaceSpec(Node):
    """Where a support or a load acts: interfaces (indices in ``geometry.interfaces``) or a region."""

    interface: Index | Annotated[list[Index], Field(min_length=1)] | None = Field(
        None, description="an index in geometry.interfaces, or a list of them (acting as one)")
    region: RegionSpec | None = Field(None, description="a region of the problem's space")

    @model_validator(mode="after")
    def _one(self):
        if (self.interface is None) == (self.region is None):
            raise ValueError("state either interface (an index into geometry.interfaces) or region")
        return self

    def place(self, interfaces: tuple[Interface, ...], dim: int, base: Path, path: str) -> tuple[Interface | Region, ...]:
        if self.region is not None:
            return (self.region.make(dim, base, f"{path}.region"),)
        out = []
        for i in [self.interface] if isinstance(self.interface, int) else self.interface:
            if i >= len(interfaces):
                raise SpecError(f"spec field '{path}.interface': no interface {i} "
                                f"(geometry.interfaces has {len(interfaces)})")
            out.append(interfaces[i])
        return tuple(out)


class SupportSpec(PlaceSpec):
    """Held displacement components at an interface or in a region."""

    fix: list[Literal["x", "y", "z", "normal"]] | None = Field(
        None, description="the displacement components held at zero (default: all; [x] is a roller along x = const; "
                          "[normal]: along the interface's normal, so the part slides along it and turns in a round "
                          "hole's rim: a frictionless pin)")

    @field_validator("fix")
    @classmethod
    def _normal_on_interfaces(cls, fix, info: ValidationInfo):
        if fix is not None and "normal" in fix and info.data.get("region") is not None:
            raise ValueError("'normal' needs interfaces (a region has no normal)")
        return fix


class LoadSpec(PlaceSpec):
    """A force and/or a torque at interfaces or in a region."""

    force: Point | None = Field(None, description="the total force vector, shared equally by the nodes there")
    torque: Finite | list[Finite] | None = Field(
        None, description="the moment of a couple about the nodes' centroid: a number in 2D (about z), a vector in 3D")

    @model_validator(mode="after")
    def _some(self, info: ValidationInfo):
        if self.force is None and self.torque is None:
            raise ValueError("state a force, a torque or both")
        d = spec_dim(info)
        if self.torque is not None and d is not None:
            if d == 2 and not isinstance(self.torque, int | float):
                raise ValueError("torque: a 2D problem's torque is a number (the moment about z)")
            if d == 3 and (isinstance(self.torque, int | float) or len(self.torque) != 3):
                raise ValueError("torque: a 3D problem's torque is a vector of 3 components")
        return self

    def vectors(self, dim: int) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """``(force (dim,), torque)``: zeros for what is not stated; the torque ``(1,)`` in 2D, ``(3,)`` in 3D."""
        force = tuple(float(v) for v in self.force) if self.force is not None else (0.0,) * dim
        if self.torque is None:
            return force, ()
        return force, (float(self.torque),) if isinstance(self.torque, int | float) else tuple(map(float, self.torque))


class LoadCaseSpec(Node):
    """Loads acting together."""

    loads: Annotated[list[LoadSpec], Field(min_length=1)]
    weight: Positive = Field(1.0, description="the case's weight in the objective")


class MaterialSpec(Node):
    """An isotropic linear-elastic material."""

    youngs_modulus: Positive = Field(1.0, description="Young's modulus (force per area; 2D: unit thickness)")
    poisson_ratio: Annotated[float, Field(gt=-1.0, lt=0.5, allow_inf_nan=False)] = Field(
        0.3, description="Poisson's ratio, in (-1, 0.5)")


class PhysicsSpec(Node):
    """The structural problem: minimise the weighted compliance of the load cases."""

    material: MaterialSpec = Field(default_factory=MaterialSpec)
    supports: Annotated[list[SupportSpec], Field(min_length=1)] = Field(
        description="where the part is held (at least one support)")
    loads: list[LoadSpec] | None = Field(None, description="the loads of a single load case")
    load_cases: list[LoadCaseSpec] | None = Field(None, description="several load cases, each with its loads and weight")

    @model_validator(mode="after")
    def _cases(self):
        if (self.loads is None) == (self.load_cases is None):
            raise ValueError("state either loads (one load case) or load_cases")
        if self.loads is not None and not self.loads:
            raise ValueError("loads: state at least one load")
        if self.load_cases is not None and not self.load_cases:
            raise ValueError("load_cases: state at least one load case")
        return self

    def build(self, interfaces: tuple[Interface, ...], dim: int, base: Path) -> Physics:
        supports, labels = [], []
        for i, s in enumerate(self.supports):
            path = f"physics.supports[{i}]"
            axes = tuple(range(dim)) if s.fix is None else tuple(sorted({AXES[a] for a in s.fix if a != "normal"}))
            if any(a >= dim for a in axes):
                raise SpecError(f"spec field '{path}.fix': a {dim}D problem has no axis z")
            supports.append(Support(s.place(interfaces, dim, base, path), axes, s.fix is not None and "normal" in s.fix))
            labels.append(path)
        if self.loads is not None:
            cases_in = [(self.loads, 1.0, "physics.loads")]
        else:
            cases_in = [(c.loads, c.weight, f"physics.load_cases[{k}].loads") for k, c in enumerate(self.load_cases)]
        cases, case_labels = [], []
        for loads, weight, prefix in cases_in:
            built = tuple(Load(ld.place(interfaces, dim, base, f"{prefix}[{j}]"), *ld.vectors(dim))
                          for j, ld in enumerate(loads))
            cases.append(LoadCase(built, float(weight)))
            case_labels.append(tuple(f"{prefix}[{j}]" for j in range(len(loads))))
        m = self.material
        return Physics(float(m.youngs_modulus), float(m.poisson_ratio), tuple(supports), tuple(cases),
                       (tuple(labels), tuple(case_labels)))

