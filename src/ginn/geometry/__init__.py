"""Geometry: regions with signed distances, interfaces with normals, CSG, meshes and samplers."""

from .base import Box, Interface, Region
from .csg import Difference, Intersection, Transformed, Union, rotation_matrix
from .interfaces import Annulus, Circle, CylinderWall, InterfaceUnion, Polyline, Segment, TransformedInterface
from .mesh import MeshInterface, MeshRegion, load_mesh
from .primitives import AABox, Ball, Cuboid, Cylinder, Disk, Extrusion, HalfSpace, Polygon, Rectangle, Sphere
from .sampling import (
    interface_corners,
    sample_band,
    sample_box,
    sample_inside,
    sample_interfaces,
    sample_interfaces_with_components,
    sample_outside,
)
from .symmetry import Mirror, Rotation, Symmetry

__all__ = [
    "Box", "Region", "Interface",
    "AABox", "Rectangle", "Cuboid", "Ball", "Disk", "Sphere", "HalfSpace", "Polygon", "Cylinder", "Extrusion",
    "Union", "Intersection", "Difference", "Transformed", "rotation_matrix",
    "Segment", "Polyline", "Circle", "CylinderWall", "Annulus", "InterfaceUnion", "TransformedInterface",
    "MeshRegion", "MeshInterface", "load_mesh",
    "sample_box", "sample_inside", "sample_outside", "sample_interfaces", "sample_interfaces_with_components",
    "sample_band", "interface_corners",
    "Mirror", "Rotation", "Symmetry",
]
