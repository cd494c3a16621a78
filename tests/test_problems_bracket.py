"""The built-in bracket against the real SimJEB meshes (skipped when the shared data is absent).

The data lives next to the repository (``<repo>/../shared/data/simjeb``) and is never copied in.
"""

from pathlib import Path

import numpy as np
import pytest
import torch

from ginn.geometry import MeshInterface, MeshRegion, load_mesh, sample_box, sample_interfaces, sample_interfaces_with_components
from ginn.problems import load_spec

F64 = torch.float64
REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "simjeb"

pytestmark = pytest.mark.skipif(not (DATA / "411_for_envelope.obj").is_file(), reason="SimJEB reference data absent")


@pytest.fixture(scope="module")
def norm():
    return np.load(DATA / "center_for_translation.npy"), float(np.load(DATA / "scale_factor.npy"))


@pytest.fixture(scope="module")
def real_interfaces(norm):
    return MeshInterface(load_mesh(DATA / "interfaces.stl", *norm))


def test_domain_matches_the_paper_bounds():
    b = np.load(DATA / "bounds.npy")
    p = load_spec("bracket").build()
    np.testing.assert_allclose(p.domain.lo, b[:, 0], atol=1e-6)
    np.testing.assert_allclose(p.domain.hi, b[:, 1], atol=1e-6)


def test_csg_envelope_volume_iou(norm):
    """Volume IoU >= 0.93 between the CSG envelope and 411_for_envelope.obj (measured 0.954; lugs
    extruded along y instead gave 0.948 overall and 0.85 around the lugs)."""
    p = load_spec("bracket").build()
    real = MeshRegion(load_mesh(DATA / "411_for_envelope.obj", *norm))
    gen = torch.Generator().manual_seed(0)
    x = sample_box(p.domain, 30_000, gen, dtype=F64)
    a, b = p.design_region.contains(x), real.contains(x)
    iou = (a & b).sum().item() / (a | b).sum().item()
    assert iou >= 0.93, iou
    # the mesh's own volume (normalised) agrees with the Monte Carlo estimate of the real envelope
    assert b.double().mean().item() * p.domain.volume() == pytest.approx(real.volume(), rel=0.03)


def test_interface_samples_lie_on_the_real_interfaces(real_interfaces):
    p = load_spec("bracket").build()
    gen = torch.Generator().manual_seed(1)
    x, n, comp = sample_interfaces_with_components(p.interfaces, 6000, gen, dtype=F64)
    d = real_interfaces.distance(x)
    assert d.max().item() <= 2e-3, d.max().item()
    # the same six components, one to one
    real_comp = real_interfaces.component_of(x)
    pairs = set(zip(comp.tolist(), real_comp.tolist()))
    assert len(pairs) == 6 and len({a for a, _ in pairs}) == 6 and len({b for _, b in pairs}) == 6
    # prescribed normals agree with the real face normals away from the rims (toward the axes, +z on rings)
    _, face = real_interfaces._dist.query(x.numpy())
    real_n = real_interfaces._normals[face]
    agree = (real_n * n).sum(-1)
    assert (agree > 0.9).double().mean().item() > 0.97


def test_bracket_from_the_real_meshes_by_path():
    spec = load_spec(REPO / "docs" / "examples" / "bracket-mesh.yaml")
    p = spec.build()
    assert isinstance(p.design_region, MeshRegion)
    assert p.n_interface_components == 6
    gen = torch.Generator().manual_seed(2)
    x, n = sample_interfaces(p.interfaces, 500, gen, dtype=F64)
    assert p.domain.contains(x).all()
    torch.testing.assert_close(n.norm(dim=-1), torch.ones(500, dtype=F64))
    # the mesh design region has the envelope's volume (463,447 mm^3 / 90.0859^3 = 0.6339)
    inside = p.design_region.contains(sample_box(p.domain, 5000, gen, dtype=F64))
    assert inside.double().mean().item() * p.domain.volume() == pytest.approx(0.6339, rel=0.08)


def test_csg_lug_faces_lie_on_the_real_lug_faces(norm):
    """The real envelope's clevis-lug faces (triangles whose normal is within 6 degrees of the pin
    axis) lie on the CSG envelope's boundary: |SDF| below 1e-3 (0.09 mm) at their centres, on both
    lugs and both faces, over the whole lug."""
    p = load_spec("bracket").build()
    real = load_mesh(DATA / "411_for_envelope.obj", *norm)
    c = np.asarray(real.triangles_center)
    counted = 0
    for pin in p.interfaces[4:]:  # the two clevis pin holes
        axis, centre = pin.axis.numpy(), pin.center.numpy()
        cos = np.asarray(real.face_normals) @ axis
        t = (c - centre) @ axis
        for side in (1, -1):
            faces = (side * cos > 0.995) & (np.abs(t - side * 0.0423) < 0.01)
            assert faces.sum() > 500
            sd = p.design_region.sdf(torch.as_tensor(c[faces], dtype=F64))
            assert sd.abs().max().item() < 1e-3, sd.abs().max().item()
            counted += int(faces.sum())
    assert counted > 2000
