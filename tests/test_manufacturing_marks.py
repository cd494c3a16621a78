"""The marks a 2D shape figure draws for the manufacturing tolerances: the thin solid, the narrow
void and the overhanging boundary, on shapes whose answer is known; and the figure is written."""

import math

import numpy as np
import pytest
import torch

from ginn.extract.boundary import extract_boundary
from ginn.extract.grid import Grid
from ginn.fields import as_field
from ginn.problems import validate_spec
from ginn.viz.manufacturing import has_marks, violation_marks
from ginn.viz.plot import plot_shapes

SPEC = {"name": "marks", "geometry": {
    "dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
    "interfaces": [{"type": "segment", "a": [-0.95, 0.9], "b": [-0.9, 0.9], "normal": [0, 1]}]}}


def _problem(**tol):
    return validate_spec({**SPEC, "tolerances": tol}).build()


def _shape(fn):
    g = Grid(np.full(2, -1.0), np.full(2, 1.0), (256, 256))
    v = fn(g.points()).reshape(g.shape)
    return g, v <= 0, extract_boundary(v.astype(np.float32), g)


def test_a_thin_bar_is_marked_whole_and_a_disk_overhangs_on_its_lower_quarter():
    p = _problem(min_thickness=0.1, overhang={"angle": 45, "up": [0, 1]})
    assert has_marks(p) and not has_marks(_problem())
    # a bar 0.05 thick beside a disk of radius 0.3
    fn = lambda x: np.minimum(np.maximum(np.abs(x[:, 0] + 0.6) - 0.025, np.abs(x[:, 1]) - 0.5),  # noqa: E731
                              np.hypot(x[:, 0] - 0.3, x[:, 1]) - 0.3)
    g, inside, b = _shape(fn)
    m = violation_marks(p, inside, g, b)
    bar = inside & (g.points()[:, 0].reshape(g.shape) < -0.2)
    assert np.array_equal(m["thin"] & bar, bar)  # the whole bar, and of the disk only its grid's fringe
    assert (m["thin"] & ~bar).sum() < 0.01 * inside.sum()
    seg = m["overhang"]  # (m, 2, 2): the disk's arc within 45 degrees of its lowest point, the bar's end
    mid = seg.mean(axis=1)
    on_disk = np.abs(np.hypot(mid[:, 0] - 0.3, mid[:, 1]) - 0.3) < 0.02
    length = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)
    assert abs(length[on_disk].sum() - 0.3 * math.pi / 2) < 0.02  # a quarter of the circle
    assert abs(length[~on_disk].sum() - 0.05) < 2 * 2 / 256  # the bar's lower end, less its bevelled corners
    assert "narrow" not in m


def test_the_closing_marks_a_slot():
    p = _problem(min_gap=0.1)
    fn = lambda x: np.maximum(np.hypot(x[:, 0], x[:, 1]) - 0.5, -(np.abs(x[:, 1]) - 0.02))  # noqa: E731
    g, inside, b = _shape(lambda x: np.where((x[:, 0] > 0), fn(x), np.hypot(x[:, 0], x[:, 1]) - 0.5))
    m = violation_marks(p, inside, g, b)
    slot = ~inside & (np.hypot(*g.points().T).reshape(g.shape) < 0.45)
    assert m["narrow"][slot].all() and "thin" not in m


def test_the_shapes_figure_is_drawn_with_marks(tmp_path):
    p = _problem(min_thickness=0.1, min_gap=0.1, overhang={"angle": 45, "up": [0, 1]})
    field = as_field(lambda x: torch.maximum((x[:, 0] + 0.2).abs() - 0.03, x[:, 1].abs() - 0.5))
    out = plot_shapes(field, None, p, tmp_path / "shapes.png", resolution=128)
    assert out.exists() and out.stat().st_size > 1000


SPEC_3D = {"name": "marks3", "geometry": {
    "dim": 3, "domain": {"lo": [-1, -1, -1], "hi": [1, 1, 1]},
    "interfaces": [{"type": "annulus", "center": [0.9, 0.9, 0.9], "normal": [0, 0, 1], "r_inner": 0.01, "r_outer": 0.02}]}}


def _mesh(fn, cells=64):
    g = Grid(np.full(3, -1.0), np.full(3, 1.0), (cells,) * 3)
    v = fn(g.points()).reshape(g.shape)
    return g, v <= 0, extract_boundary(v.astype(np.float32), g)


def test_a_floating_box_overhangs_on_its_underside_and_a_thin_plate_is_marked_thin():
    """A box 0.656 x 0.656 x 0.4 above the plate (z up, 45 degrees; its sides half a cell off the
    grid's nodes): its underside, and nothing facing up or sideways, is code 3, the 20 x 20 cells
    (0.625 x 0.625) in which the mesh is flat; a plate 0.05 thick under a least thickness of 0.1 is code 1 on its
    faces but for its underside (overhang wins)."""
    from ginn.extract.overhang import element_normals
    from ginn.viz.manufacturing import face_marks

    p = validate_spec({**SPEC_3D, "tolerances": {"overhang": {"angle": 45, "up": [0, 0, 1]}}}).build()
    box = lambda x: np.max(np.abs(x - [0.0, 0.0, 0.2]) - [0.328125, 0.328125, 0.2], axis=1)  # noqa: E731
    g, inside, b = _mesh(box)
    codes = face_marks(p, inside, g, b)
    nz = element_normals(b)[:, 2]
    assert set(np.unique(codes)) == {0, 3}
    assert (codes[nz < -0.99] == 3).all() and (codes[nz > -0.7] == 0).all()
    area = 0.5 * np.linalg.norm(np.cross(*(b.vertices[b.elements[:, 1:]] - b.vertices[b.elements[:, :1]]).transpose(1, 0, 2)), axis=1)
    assert area[codes == 3].sum() == pytest.approx(0.625 ** 2, rel=1e-6)  # the rim's bevels at 45 degrees are not over it

    q = validate_spec({**SPEC_3D, "tolerances": {"min_thickness": 0.1, "overhang": {"angle": 45, "up": [0, 0, 1]}}}).build()
    plate = lambda x: np.max(np.abs(x) - [0.5, 0.5, 0.025], axis=1)  # noqa: E731
    g, inside, b = _mesh(plate, 128)
    codes = face_marks(q, inside, g, b)
    nz = element_normals(b)[:, 2]
    assert (codes[nz > 0.99] == 1).all() and (codes[nz < -0.99] == 3).all()


def test_the_3d_figures_colour_the_marked_faces(tmp_path):
    from ginn.viz.plot import plot_views

    p = validate_spec({**SPEC_3D, "tolerances": {"overhang": {"angle": 45, "up": [0, 0, 1]}}}).build()
    g, inside, b = _mesh(lambda x: np.linalg.norm(x, axis=1) - 0.5, 32)
    from ginn.viz.manufacturing import face_marks

    out = plot_views(b, p, tmp_path / "v.png", marks=face_marks(p, inside, g, b))
    assert out.exists() and out.stat().st_size > 1000
    field = as_field(lambda x: x.norm(dim=-1) - 0.5)
    out = plot_shapes(field, None, p, tmp_path / "shapes.png", resolution=32)
    assert out.exists() and out.stat().st_size > 1000
