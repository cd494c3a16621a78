"""The parameters of shape problems: loss terms, point budgets, diversity, connectedness and hole targets.

They are groups at the top of the run configuration (``losses``, ``sampling``, ``diversity``,
``connectedness``, ``topology``), where specs and ``--set`` name them; ``params`` of a shape
problem holds nothing more (:class:`ShapeParams`).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import STRAIN_CLIP, LossTerm, Strict

__all__ = ["LossesConfig", "SamplingConfig", "DiversityConfig", "ConnectednessConfig", "TopologyConfig", "StructuralConfig", "ShapeParams"]


class LossesConfig(Strict):
    """All loss terms of a shape problem (Table 1, eikonal, obstacle, strain, connectedness, diversity)."""

    interface: LossTerm = LossTerm(weight=1.0)
    normal: LossTerm = LossTerm()
    design_region: LossTerm = LossTerm(weight=1.0)
    obstacle: LossTerm = LossTerm()
    eikonal: LossTerm = LossTerm()
    mean_curvature: LossTerm = LossTerm()
    strain: LossTerm = LossTerm()
    connectedness: LossTerm = LossTerm()
    topology: LossTerm = LossTerm()
    diversity: LossTerm = LossTerm()
    volume: LossTerm = LossTerm()
    area: LossTerm = LossTerm()
    thickness: LossTerm = LossTerm()
    gap: LossTerm = LossTerm()
    thickness_edges: LossTerm = LossTerm()
    gap_edges: LossTerm = LossTerm()
    overhang: LossTerm = LossTerm()
    fillet: LossTerm = LossTerm()
    faces: LossTerm = LossTerm()
    attachment: LossTerm = LossTerm()
    compliance: LossTerm = LossTerm()
    interface_distance: bool = Field(
        False,
        description="the interface term as the mean of (f / min(|grad f|, 1))^2: each interface sample's first-order "
        "distance to f = 0 (what CD1 measures) where the field is flatter than a distance and faces the "
        "prescribed normal within its tolerance, f elsewhere; false is the paper's mean of f^2, which a field "
        "flatter than a distance meets while its zero level stays short of the interface",
    )
    containment_power: Literal[1, 2] = Field(
        2,
        description="exponent of the design-region and obstacle penalties: 2 is the paper's mean of "
        "min(0, f)^2; 1 is the mean of |min(0, f)|, an exact penalty that keeps pushing on shallow violations",
    )
    containment_slope: float = Field(
        0.0,
        ge=0,
        description="penalise f below slope * (distance into X minus E, or into an obstacle) instead of below 0; "
        "0 is the paper's loss, 1 is exact for a signed distance field of any shape inside E; with a slope > 0 "
        "the shapes' surface samples outside E enter the design-region term too, each at its depth, and the samples "
        "within the interface tolerance of an interface leave it (the volume the verdict leaves out)",
    )


class SamplingConfig(Strict):
    """Monte Carlo point budgets per shape and iteration (per reported shape: a step that trains
    more codes than ``latents.n_shapes`` spreads the reported shapes' samples over its codes,
    :func:`ginn.tasks.shape.task.spread_sampling`)."""

    n_domain: int = Field(4096, gt=0, description="uniform points in X (eikonal)")
    n_outside: int = Field(2048, ge=0, description="points in X minus E (design-region loss)")
    n_obstacle: int = Field(512, ge=0, description="points inside obstacles")
    n_interface: int = Field(512, gt=0, description="points on the interfaces")
    n_band: int = Field(0, ge=0, description="extra points in a band around the interfaces")
    n_boundary: int = Field(512, ge=0, description="points projected onto f = 0 (curvature, strain, diversity)")
    projection_steps: int = Field(2, ge=0, description="Newton steps of the zero-level-set projection (after a free first step)")
    strain_interface_clearance: float = Field(0.0, ge=0, description="skip boundary points this close to an interface for the strain loss")
    strain_clip: float = Field(STRAIN_CLIP, gt=0, description="clip per-point surface strain at this value")
    interface_corner_weight: float = Field(
        1.0, ge=1, description="weight of the interfaces' corner samples: polyline vertices, end points included (Plateau)")


class DiversityConfig(Strict):
    """Diversity loss of Appendix E."""

    aggregation: Literal["min", "sum"] = Field(
        "min", description="min: each shape's distance to its nearest other shape (equation 11); sum: all pairs (equation 10)")
    p: float = Field(0.5, gt=0, description="exponent of the aggregation (paper: 0.5 with min)")
    eps: float = Field(0.0, ge=0, description="smooth the shape distance to sqrt(d^2 + eps^2), bounding the loss's gradient "
                       "when shapes coincide (0: the paper's distance, singular there)")


class ConnectednessConfig(Strict):
    """Connectedness loss (Appendix C); see docs/connectedness.md."""

    method: Literal["surface-network", "persistent-homology"] = Field(
        "surface-network", description="the paper's surface-network loss, or 0-dimensional cubical persistent homology (cripser)")
    every: int = Field(10, ge=1, description="full surface-network builds at every K-th step, of the shapes due: a shape "
        "every K steps while it has something to join, up to 4 K while nothing is penalised on it (warm updates between)")
    grid: int = Field(16, ge=2, description="seed grid resolution per axis (surface network) or PH grid resolution")
    restrict_to_design_region: bool = Field(True, description="count only the part of the shape inside the design region E")
    eps: float = Field(1e-2, gt=0, description="epsilon in p_k += 1/(d + eps)")
    margin: float = Field(0.0, ge=0, description="the loss sees the shape {f <= -margin}: connections thinner than "
                          "about 2 margin count as gaps and are pushed open (0: the paper's {f <= 0})")


class TopologyConfig(Strict):
    """The loss toward the spec's target Betti numbers (``topology:``; docs/problem-spec.md)."""

    grid: int = Field(64, ge=8, description="persistent-homology grid nodes along the longest axis of the domain; "
                      "the margin of the loss is one cell of it")
    every: int = Field(5, ge=1, description="recompute the persistence diagrams every K steps (the same cells between)")


class StructuralConfig(Strict):
    """The finite-element analysis of problems with a ``physics`` block (docs/structural.md)."""

    cells: int = Field(0, ge=0, description="elements along the domain's longest side (0: 90 in 2D, 36 in 3D, or more "
                       "where the smallest interface would span fewer than 4 elements)")
    method: Literal["auto", "direct", "cg", "cg-diagonal"] = Field(
        "auto", description="the linear solver: direct (factorisation: LAPACK band Cholesky in 2D; in 3D MKL PARDISO "
        "with the pardiso extra, SuperLU without), cg (batched matrix-free conjugate gradients preconditioned by "
        "geometric multigrid), cg-diagonal (the same preconditioned by the diagonal), auto (on the CPU direct for 2D, "
        "and for 3D with several load cases where PARDISO is installed; cg otherwise)")


class ShapeParams(Strict):
    """``params`` of a shape problem: none beyond the groups above."""

    kind: Literal["shape"] = Field("shape", description="the task kind this group belongs to")
