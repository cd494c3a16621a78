"""Independent classical references for problems with known answers: discrete minimal surfaces
(Plateau) and a spectral Gray-Scott solver."""

from .gray_scott import GrayScottSolver, phase_randomised, relative_residual, residuals
from .minimal_surface import (
    PLATEAU_AREA_ESTIMATE,
    MinimalSurface,
    annulus_minimal_surface,
    catenoid_area,
    circle_curve,
    cotangent_laplacian,
    disk_minimal_surface,
    mesh_area,
    minimize_area,
    plateau_polygon,
    plateau_reference,
    polygon_curve,
    sample_surface,
)

__all__ = [
    "GrayScottSolver",
    "phase_randomised",
    "relative_residual",
    "residuals",
    "MinimalSurface",
    "PLATEAU_AREA_ESTIMATE",
    "annulus_minimal_surface",
    "catenoid_area",
    "circle_curve",
    "cotangent_laplacian",
    "disk_minimal_surface",
    "mesh_area",
    "minimize_area",
    "plateau_polygon",
    "plateau_reference",
    "polygon_curve",
    "sample_surface",
]
