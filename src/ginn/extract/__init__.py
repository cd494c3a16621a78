"""From a field to geometry: grids, a field sampled on a grid, boundaries (contours and meshes), and
the files they are exported to."""

from .boundary import Boundary, extract_boundary
from .export import CONTOUR_FORMATS, MESH_FORMATS, export_contours, export_mesh, export_shape, export_shapes, shape_boundary
from .grid import Grid, grid_volume, interpolate, label_components, make_grid, node_grid, periodic_points
from .sampling import field_dtype_device, sample_field

__all__ = [
    "Grid", "make_grid", "node_grid", "periodic_points", "label_components", "interpolate", "grid_volume",
    "sample_field", "field_dtype_device", "Boundary", "extract_boundary",
    "MESH_FORMATS", "CONTOUR_FORMATS", "shape_boundary", "export_mesh", "export_contours", "export_shape", "export_shapes",
]
