"""Independent classical references for shape problems with known answers: discrete minimal
surfaces (Plateau). The Gray-Scott kind's spectral solver is :mod:`ginn.tasks.gray_scott.solver`."""

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
