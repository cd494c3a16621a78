"""Export: watertight meshes in STL/PLY/OBJ and 2D contour files for any latent value."""

import csv
import json
import math

import numpy as np
import pytest
import torch
import trimesh

from _shapes import Disk
from ginn.extract.export import export_contours, export_mesh, export_shapes, latent_label, shape_boundary
from ginn.fields import as_field
from ginn.geometry.base import Box

BOX2 = Box((-1.0, -0.5), (1.0, 0.5))
BOX3 = Box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))


def ball_family(x, z):
    """Balls of radius 0.2 + 0.3 z centred at the origin (any dimension)."""
    return x.norm(dim=-1) - (0.2 + 0.3 * z[:, 0])


@pytest.mark.parametrize("fmt", ["stl", "ply", "obj"])
def test_mesh_formats_roundtrip_watertight(tmp_path, fmt):
    b, _, _ = shape_boundary(as_field(Disk((0.8, 0.0, 0.0), 0.4).sdf), None, BOX3, 48)  # cut by x = 1
    p = export_mesh(b, tmp_path / "cut", fmt)
    assert p.suffix == "." + fmt and p.exists()
    m = trimesh.load(p, force="mesh")
    assert m.is_watertight
    h = 0.8 + 0.4 - 1.0
    exact = 4 / 3 * math.pi * 0.4**3 - math.pi * h * h * (3 * 0.4 - h) / 3
    assert abs(m.volume - exact) / exact < 0.02


def test_export_shapes_any_latent_3d(tmp_path):
    Z = torch.tensor([[0.0], [0.37], [1.0]], dtype=torch.float64)  # 0.37 was never "trained"
    paths = export_shapes(ball_family, Z, BOX3, tmp_path, 64, mesh_format="ply")
    assert [p.name for p in paths] == ["shape_000_z0.ply", "shape_001_z0.37.ply", "shape_002_z1.ply"]
    for p, z in zip(paths, Z[:, 0].tolist()):
        r = 0.2 + 0.3 * z
        m = trimesh.load(p, force="mesh")
        assert m.is_watertight
        assert m.volume == pytest.approx(4 / 3 * math.pi * r**3, rel=0.03)


def test_export_contours_2d_files(tmp_path):
    Z = torch.tensor([[1.0 / 3.0]], dtype=torch.float64)  # radius 0.3
    paths = export_shapes(ball_family, Z, BOX2, tmp_path, 128)
    names = sorted(p.suffix for p in paths)
    assert names == [".csv", ".json", ".npz", ".png", ".svg"]
    by = {p.suffix: p for p in paths}
    assert by[".json"].name == "shape_000_z0.3333.json"
    data = json.loads(by[".json"].read_text())
    assert data["domain"] == {"lo": [-1.0, -0.5], "hi": [1.0, 0.5]}
    (c,) = [np.asarray(c) for c in data["contours"]]
    np.testing.assert_allclose(c[0], c[-1])  # closed
    np.testing.assert_allclose(np.linalg.norm(c, axis=1), 0.3, atol=1e-3)
    area = 0.5 * np.sum(c[:-1, 0] * c[1:, 1] - c[1:, 0] * c[:-1, 1])
    assert area == pytest.approx(math.pi * 0.09, rel=2e-3)  # counter-clockwise outer contour
    with by[".csv"].open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["contour", "x", "y"] and len(rows) == 1 + len(c)
    npz = np.load(by[".npz"])
    np.testing.assert_allclose(npz["contour_0"], c)
    svg = by[".svg"].read_text()
    assert svg.startswith("<svg") and svg.count(" Z") == 1
    assert by[".png"].read_bytes()[:4] == b"\x89PNG"


def test_contours_with_a_hole_and_a_cut(tmp_path):
    # an annulus cut by the box face y = 0.5: one contour (outer part closed along the face)
    # plus the hole, oriented clockwise
    f = lambda x, z=None: torch.maximum(x.norm(dim=-1) - 0.6, 0.2 - x.norm(dim=-1))
    b, _, _ = shape_boundary(f, None, BOX2, 256)
    lines = b.polylines()
    assert len(lines) == 2
    areas = sorted(0.5 * np.sum(p[:-1, 0] * p[1:, 1] - p[1:, 0] * p[:-1, 1]) for p in lines)
    assert areas[0] == pytest.approx(-math.pi * 0.04, rel=5e-3)
    # the outer contour encloses the disk of radius 0.6 minus two caps of height 0.1 (cut at |y| = 0.5)
    seg = 0.36 * math.acos(0.5 / 0.6) - 0.5 * math.sqrt(0.36 - 0.25)
    assert areas[1] == pytest.approx(math.pi * 0.36 - 2 * seg, rel=5e-3)
    ps = export_contours(b, tmp_path / "annulus", BOX2, ["json"])
    assert len(json.loads(ps[0].read_text())["contours"]) == 2


def test_bad_formats(tmp_path):
    b, _, _ = shape_boundary(as_field(Disk((0.0, 0.0), 0.3).sdf), None, BOX2, 32)
    with pytest.raises(ValueError):
        export_contours(b, tmp_path / "x", BOX2, ["dxf"])
    with pytest.raises(ValueError):
        export_mesh(b, tmp_path / "x.stl")
    assert latent_label(None) == "shape" and latent_label(torch.tensor([0.5, -1.0])) == "z0.5_-1"
