"""Structural physics on a structured grid: linear elasticity with bilinear (2D, plane stress) and
trilinear (3D) elements, compliance with its adjoint gradient as an autograd function, and the
classic SIMP optimiser used as the reference of the structural results.

Modules: :mod:`~ginn.physics.elements` (element matrices), :mod:`~ginn.physics.grid` (the element
grid), :mod:`~ginn.physics.solve` (the solver: sparse direct, batched matrix-free CG),
:mod:`~ginn.physics.band` (its 2D factoriser: LAPACK's band Cholesky without the interpreter lock),
:mod:`~ginn.physics.pardiso` (its 3D factoriser where MKL is installed),
:mod:`~ginn.physics.multigrid` (CG's geometric multigrid preconditioner),
:mod:`~ginn.physics.floating` (the rigid motions of floating pieces, which balance its cycle),
:mod:`~ginn.physics.compliance` (the differentiable compliance), :mod:`~ginn.physics.simp` (the
reference optimiser). ``docs/structural.md`` describes the method and its checks.
"""

from .compliance import Solution, compliance
from .elements import corner_offsets, elasticity_matrix, element_stiffness, strain_matrix
from .floating import FloatingModes
from .grid import ElementGrid
from .multigrid import Multigrid
from .simp import DensityFilter, SimpResult, simp
from .solve import METHODS, ElasticitySolver

__all__ = [
    "Solution", "compliance", "corner_offsets", "element_stiffness", "elasticity_matrix", "strain_matrix", "ElementGrid",
    "FloatingModes", "Multigrid", "DensityFilter", "SimpResult", "simp", "METHODS", "ElasticitySolver",
]
