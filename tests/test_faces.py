"""Flat faces: the largest normal angle in a face's region on fields whose normals are known, a
region without boundary, the loss, the spec."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from _shapes import LineField
from ginn.constraints import Faces, FacesVerdict
from ginn.errors import SpecError
from ginn.extract.boundary import extract_boundary
from ginn.extract.grid import Grid
from ginn.fields import as_field
from ginn.problems import validate_spec
from ginn.tasks import make_task

TOP = {"type": "rectangle", "lo": [-0.3, 0.1], "hi": [0.3, 0.5]}  # holds the top face of the boxes below


def _box(tilt_deg):
    """The SDF of the rectangle [-0.5, 0.5] x [-0.3, 0.3] turned by ``tilt_deg`` about the origin."""
    c, s = math.cos(math.radians(tilt_deg)), math.sin(math.radians(tilt_deg))

    def f(x):
        u = torch.stack([c * x[:, 0] + s * x[:, 1], -s * x[:, 0] + c * x[:, 1]], dim=-1)
        q = u.abs() - torch.tensor([0.5, 0.3], dtype=x.dtype)
        return q.clamp_min(0).norm(dim=-1) + q.max(-1).values.clamp_max(0)
    return as_field(f)


SPEC = {"name": "mount", "geometry": {
    "dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
    "interfaces": [{"type": "segment", "a": [-0.95, -0.9], "b": [-0.9, -0.9], "normal": [0, -1]}]}}


def _spec(faces):
    return validate_spec({**SPEC, "tolerances": {"faces": faces}})


def _measure(field, faces):
    g = Grid(np.full(2, -1.0), np.full(2, 1.0), (400, 400))
    vals = field(torch.as_tensor(g.points(), dtype=torch.float64)).reshape(g.shape).numpy().astype(np.float32)
    v = FacesVerdict(_spec(faces).build())
    return v, v.measure(SimpleNamespace(boundary=extract_boundary(vals, g)), SimpleNamespace(grid=g), field, None)


@pytest.mark.parametrize("tilt, angle, feasible", [(0.0, 2.0, True), (5.0, 2.0, False), (5.0, 6.0, True)])
def test_the_largest_angle_in_the_region_is_the_tilt(tilt, angle, feasible):
    v, m = _measure(_box(tilt), [{"region": TOP, "normal": [0, 1], "angle": angle}])
    assert m["face_angles"][0] == pytest.approx(tilt, abs=0.05)
    assert m["face_deviation"] == pytest.approx(tilt / angle, abs=0.05 / angle)
    assert (v.violation(m) is None) == feasible


def test_a_region_without_boundary_is_a_missing_face():
    v, m = _measure(_box(0.0), [{"region": TOP, "normal": [0, 1]},
                                {"region": {"type": "disk", "center": [0.8, 0.8], "radius": 0.1}, "normal": [1, 0]}])
    assert m["face_angles"][0] == pytest.approx(0.0, abs=0.05) and m["face_angles"][1] is None
    assert math.isinf(m["face_deviation"]) and "no boundary" in FacesVerdict.describe(v.violation(m))


def test_spec_checks_the_normal_and_the_angle():
    f = _spec([{"region": TOP, "normal": [0, 2]}]).build().tolerances.faces[0]
    assert f.normal == (0.0, 1.0) and f.angle == 2.0
    for bad in ([{"region": TOP, "normal": [0, 0, 1]}], [{"region": TOP, "normal": [0, 1], "angle": 95}],
                [{"normal": [0, 1]}]):
        with pytest.raises(SpecError, match="tolerances.faces"):
            _spec(bad)


@pytest.mark.parametrize("beta", [90.0, 80.0, 60.0])
def test_loss_is_one_minus_the_cosine_to_the_face_normal(beta):
    spec = _spec([{"region": {"type": "rectangle", "lo": [-0.5, -0.5], "hi": [0.5, 0.5]}, "normal": [0, 1]}])
    task = make_task(spec, spec.config(None, {"sampling": {"n_domain": 2048, "n_boundary": 64}}))
    assert [c for c in task.constraints if isinstance(c, Faces)]
    terms = task.loss_terms(LineField(beta), 0, {"faces", "eikonal"}, torch.Generator().manual_seed(0))
    assert float(terms["faces"].detach()) == pytest.approx(1 - math.cos(math.radians(90 - beta)), abs=1e-6)


def test_loss_evaluates_the_field_at_every_surface_sample_whatever_the_faces_share():
    """One call of the field on all surface samples however many fall in each face's region: a
    compiled SIREN's kernels are made per shape of input."""
    class Recording(LineField):
        def forward(self, x, z=None):
            sizes.append(x.shape[0])
            return super().forward(x, z)

    seen = []
    for half in (0.1, 0.5):
        spec = _spec([{"region": {"type": "rectangle", "lo": [-half, -half], "hi": [half, half]}, "normal": [0, 1]},
                      {"region": EVERYWHERE, "normal": [0, 1]}])
        task = make_task(spec, spec.config(None, {"sampling": {"n_domain": 2048, "n_boundary": 64}}))
        sizes = []
        terms = task.loss_terms(Recording(30.0), 0, {"faces"}, torch.Generator().manual_seed(0))
        assert float(terms["faces"].detach()) == pytest.approx(2 * (1 - math.cos(math.radians(60))), abs=1e-6)
        seen.append(sorted(set(sizes)))
    assert seen[0] == seen[1] and 64 in seen[0]


def _disk(r):
    return as_field(lambda x: x.norm(dim=-1) - r)


EVERYWHERE = {"type": "rectangle", "lo": [-1, -1], "hi": [1, 1]}


@pytest.mark.parametrize("surface", [
    {"type": "disk", "center": [0.04, 0.0], "radius": 0.5},
    # the same circle as the boundary of the region outside it: the normal reversed, the same face
    {"type": "difference", "children": [{"type": "rectangle", "lo": [-3, -3], "hi": [3, 3]},
                                     {"type": "disk", "center": [0.04, 0.0], "radius": 0.5}]},
])
def test_a_disk_on_a_shifted_circle(surface):
    """The circle |x| = 0.5 against the circle of the same radius about (0.04, 0): the largest
    distance is the shift, 0.04 (at theta = 0 and pi); the largest angle between the radii is
    asin(0.04 / 0.5) (law of sines, where the radius from the shifted centre is perpendicular to
    the shift)."""
    tight, loose, near = ({"region": EVERYWHERE, "surface": surface, **k} for k in (
        {"angle": 2, "distance": 0.05}, {"angle": 5, "distance": 0.05}, {"angle": 5, "distance": 0.03}))
    v, m = _measure(_disk(0.5), [tight])
    assert m["face_distances"][0] == pytest.approx(0.04, abs=2e-4)
    assert m["face_angles"][0] == pytest.approx(math.degrees(math.asin(0.04 / 0.5)), abs=0.02)
    assert m["face_deviation"] == pytest.approx(m["face_angles"][0] / 2, rel=1e-9) and v.violation(m) is not None
    v, m = _measure(_disk(0.5), [loose])
    assert m["face_deviation"] == pytest.approx(math.degrees(math.asin(0.08)) / 5, abs=0.01) and v.violation(m) is None
    v, m = _measure(_disk(0.5), [near])
    assert m["face_deviation"] == pytest.approx(0.04 / 0.03, abs=0.01) and v.violation(m) is not None


def test_a_face_on_its_own_circle_and_the_default_distance():
    v, m = _measure(_disk(0.5), [{"region": TOP, "surface": {"type": "disk", "center": [0, 0], "radius": 0.5}}])
    assert m["face_distances"][0] < 1e-4 and m["face_angles"][0] < 0.05 and v.violation(m) is None
    assert v.faces[0].distance == pytest.approx(0.005)  # the interface tolerance times the unit scale (1)


def test_spec_asks_for_one_kind_of_face():
    disk = {"type": "disk", "center": [0, 0], "radius": 0.5}
    for bad, words in (([{"region": TOP, "normal": [0, 1], "surface": disk}], "give one of normal"),
                       ([{"region": TOP}], "give one of normal"),
                       ([{"region": TOP, "normal": [0, 1], "distance": 0.01}], "distance needs surface"),
                       ([{"region": TOP, "surface": disk, "distance": -1}], "distance")):
        with pytest.raises(SpecError, match=f"tolerances.faces.*{words}"):
            _spec(bad)


class _Level(torch.nn.Module):
    """``f = y - b``, the offset ``b`` a parameter: its zero set is the line y = b."""

    def __init__(self, b):
        super().__init__()
        self.b = torch.nn.Parameter(torch.tensor(b))

    def forward(self, x, z=None):
        return x[:, 1] - self.b


def test_loss_of_a_face_on_a_surface_moves_the_boundary_onto_it():
    """The line y = b against the surface y = 0.01 (a half-plane's boundary): the normals agree, so
    the loss is (1 - cos 2 deg) ((b - 0.01) / 0.005)^2 and its derivative in b is the derivative of
    that (the boundary moves with b)."""
    surface = {"type": "halfspace", "point": [0, 0.01], "normal": [0, 1]}
    spec = _spec([{"region": {"type": "rectangle", "lo": [-0.5, -0.5], "hi": [0.5, 0.5]}, "surface": surface}])
    task = make_task(spec, spec.config(None, {"sampling": {"n_domain": 2048, "n_boundary": 64}}))
    field = _Level(-0.02)
    terms = task.loss_terms(field, 0, {"faces", "eikonal"}, torch.Generator().manual_seed(0))
    k = 1 - math.cos(math.radians(2.0))
    assert float(terms["faces"].detach()) == pytest.approx(k * (0.03 / 0.005) ** 2, rel=1e-4)
    (db,) = torch.autograd.grad(terms["faces"], field.b)
    assert float(db) == pytest.approx(2 * k * (-0.03) / 0.005**2, rel=1e-4)


def test_a_ball_on_a_larger_concentric_sphere_3d():
    """3D: the sphere |x| = 0.5 against the concentric sphere of radius 0.52, in the upper half:
    every normal along the radius (angle 0), every point 0.02 from it."""
    spec = validate_spec({"name": "ball", "geometry": {
        "dim": 3, "domain": {"lo": [-1, -1, -1], "hi": [1, 1, 1]},
        "interfaces": [{"type": "annulus", "center": [0, 0, -0.9], "normal": [0, 0, -1], "r_inner": 0.02, "r_outer": 0.05}]},
        "tolerances": {"faces": [{"region": {"type": "box", "lo": [-1, -1, 0.1], "hi": [1, 1, 1]},
                                  "surface": {"type": "ball", "center": [0, 0, 0], "radius": 0.52}, "distance": 0.03}]}})
    g = Grid(np.full(3, -1.0), np.full(3, 1.0), (96, 96, 96))
    field = _disk(0.5)
    vals = field(torch.as_tensor(g.points(), dtype=torch.float64)).reshape(g.shape).numpy().astype(np.float32)
    v = FacesVerdict(spec.build())
    m = v.measure(SimpleNamespace(boundary=extract_boundary(vals, g)), SimpleNamespace(grid=g), field, None)
    assert m["face_distances"][0] == pytest.approx(0.02, abs=1e-4)
    assert m["face_angles"][0] < 0.05
    assert m["face_deviation"] == pytest.approx(0.02 / 0.03, abs=5e-3) and v.violation(m) is None
