"""The ``physics`` block of a problem spec: material, supports and load cases of a structural
problem (``docs/structural.md``), translated into :class:`~ginn.problems.problem.Physics`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, model_validator

from ..errors import SpecError
from ..geometry.base import Interface, Region
from .nodes import Node, Point, Positive
from .problem import Load, LoadCase, Physics, Support
from .regions import RegionSpec

__all__ = ["PhysicsSpec"]

AXES = {"x": 0, "y": 1, "z": 2}


class PlaceSpec(Node):
    """Where a support or a load acts: an interface (its index in ``geometry.interfaces``) or a region."""

    interface: Annotated[int, Field(ge=0)] | None = Field(None, description="index in geometry.interfaces")
    region: RegionSpec | None = Field(None, description="a region of the problem's space")

    @model_validator(mode="after")
    def _one(self):
        if (self.interface is None) == (self.region is None):
            raise ValueError("state either interface (an index into geometry.interfaces) or region")
        return self

    def place(self, interfaces: tuple[Interface, ...], dim: int, base: Path, path: str) -> Interface | Region:
        if self.region is not None:
            return self.region.make(dim, base, f"{path}.region")
        if self.interface >= len(interfaces):
            raise SpecError(f"spec field '{path}.interface': no interface {self.interface} "
                            f"(geometry.interfaces has {len(interfaces)})")
        return interfaces[self.interface]


class SupportSpec(PlaceSpec):
    """Held displacement components at an interface or in a region."""

    fix: list[Literal["x", "y", "z"]] | None = Field(
        None, description="the displacement components held at zero (default: all; [x] is a roller along x = const)")


class LoadSpec(PlaceSpec):
    """A force at an interface or in a region (the total, shared by the nodes there)."""

    force: Point = Field(description="the total force vector, in the problem's force unit")


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
            axes = tuple(range(dim)) if s.fix is None else tuple(sorted({AXES[a] for a in s.fix}))
            if any(a >= dim for a in axes):
                raise SpecError(f"spec field '{path}.fix': a {dim}D problem has no axis z")
            supports.append(Support(s.place(interfaces, dim, base, path), axes))
            labels.append(path)
        if self.loads is not None:
            cases_in = [(self.loads, 1.0, "physics.loads")]
        else:
            cases_in = [(c.loads, c.weight, f"physics.load_cases[{k}].loads") for k, c in enumerate(self.load_cases)]
        cases, case_labels = [], []
        for loads, weight, prefix in cases_in:
            built = tuple(Load(ld.place(interfaces, dim, base, f"{prefix}[{j}]"), tuple(float(v) for v in ld.force))
                          for j, ld in enumerate(loads))
            cases.append(LoadCase(built, float(weight)))
            case_labels.append(tuple(f"{prefix}[{j}]" for j in range(len(loads))))
        m = self.material
        return Physics(float(m.youngs_modulus), float(m.poisson_ratio), tuple(supports), tuple(cases),
                       (tuple(labels), tuple(case_labels)))

