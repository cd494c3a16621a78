"""The overhang for additive manufacturing: the measured share against closed forms (sphere,
circle), the exemptions (build plate, interfaces, domain caps), the loss on fields whose normals
are known, the spec and the verdict."""

import math

import numpy as np
import pytest
import torch

from _shapes import LineField
from ginn.constraints import Overhang, OverhangVerdict
from ginn.constraints.overhang import tail_means
from ginn.errors import SpecError
from ginn.extract.boundary import extract_boundary
from ginn.extract.grid import Grid
from ginn.extract.overhang import element_normals, exempt_elements, overhang_share
from ginn.problems import validate_spec
from ginn.tasks import make_task


def _boundary(f, lo, hi, cells):
    g = Grid(np.array(lo, dtype=float), np.array(hi, dtype=float), cells)
    x = g.points().reshape(*g.shape, len(cells))
    return extract_boundary(f(x).astype(np.float32), g)


@pytest.mark.parametrize("angle", [30.0, 45.0, 60.0])
def test_a_sphere_overhangs_on_one_minus_sine_of_its_lower_half(angle):
    b = _boundary(lambda x: np.linalg.norm(x, axis=-1) - 0.6, [-1] * 3, [1] * 3, (96, 96, 96))
    assert overhang_share(b, [0, 0, 2.0], angle) == pytest.approx(1 - math.sin(math.radians(angle)), abs=0.01)


def test_a_circle_overhangs_on_one_minus_angle_over_ninety_of_its_lower_half():
    b = _boundary(lambda x: np.linalg.norm(x, axis=-1) - 0.6, [-1, -1], [1, 1], (512, 512))
    n, c = element_normals(b), b.vertices[b.elements].mean(axis=1)
    assert np.all(np.sum(n * c, axis=1) > 0)  # outward
    assert overhang_share(b, [0, 1], 45.0) == pytest.approx(0.5, abs=0.01)
    assert overhang_share(b, [1, 0], 30.0) == pytest.approx(1 - 30 / 90, abs=0.01)  # another build direction


def test_a_box_on_the_plate_is_exempt_underneath_and_a_floating_one_overhangs_there():
    box = lambda x: np.max(np.abs(x - np.array([0.0, 0.0, -0.2])) - np.array([0.3, 0.3, 0.3]), axis=-1)  # noqa: E731
    b = _boundary(box, [-1] * 3, [1] * 3, (160, 160, 160))
    up = np.array([0.0, 0.0, 1.0])
    # all it faces down with is its bottom, less the grid's bevel of the bottom edges (at 45
    # degrees, about 4.6 % of the down-facing area at this cell size, proportional to it)
    assert 0.94 < overhang_share(b, up, 45.0) < 1.0
    on_plate = exempt_elements(b, up, plate=-0.5, tol=2 / 160)
    assert overhang_share(b, up, 45.0, on_plate) is None  # nothing left that faces down
    assert overhang_share(b, up, 45.0, exempt_elements(b, up, plate=-0.9, tol=2 / 160)) > 0.94


def test_the_domain_cap_is_no_surface():
    """A bar cut by the domain's bottom face: the cap there is exempt, its sides are vertical."""
    b = _boundary(lambda x: np.maximum(np.abs(x[..., 0]) - 0.2, x[..., 1] - 0.5), [-1, -1], [1, 1], (256, 256))
    ex = exempt_elements(b, np.array([0.0, 1.0]), plate=-5.0, tol=0.01)
    assert ex.any() and overhang_share(b, [0, 1], 45.0, ex) is None


SPEC = {"name": "ramp", "geometry": {
    "dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
    "interfaces": [{"type": "segment", "a": [-0.9, 0.5], "b": [-0.9, 0.52], "normal": [-1, 0]}]}}


def _spec(overhang):
    return validate_spec({**SPEC, "tolerances": {"overhang": overhang}})


def test_spec_normalises_up_and_refuses_bad_angles():
    o = _spec({"angle": 45, "up": [0, 3]}).build().tolerances.overhang
    assert o.up == (0.0, 1.0) and o.share == 0.01 and o.plate is None
    for bad in ({"angle": 90, "up": [0, 1]}, {"angle": 45, "up": [0, 0, 1]}, {"angle": 45, "up": [0, 0]}, {"up": [0, 1]}):
        with pytest.raises(SpecError, match="tolerances.overhang"):
            _spec(bad)


def test_verdict_reads_the_share_and_the_plate_defaults_to_the_domain_bottom():
    p = _spec({"angle": 45, "up": [0, 1], "share": 0.02}).build()
    v = OverhangVerdict(p)
    assert v.plate == -1.0 and v.violation({"overhang_share": 0.01}) is None
    bad = v.violation({"overhang_share": 0.05})
    assert (bad.value, bad.bound) == (0.05, 0.02) and v.ratio({"overhang_share": 0.05}) == pytest.approx(2.5)
    assert OverhangVerdict(_spec({"angle": 45, "up": [0, -1]}).build()).plate == -1.0  # lowest along -y: y = 1


@pytest.mark.parametrize("beta, expected", [(-60.0, math.sin(math.radians(60)) - math.sin(math.radians(45))),
                                            (-30.0, 0.0), (60.0, 0.0)])
def test_loss_is_how_far_each_normal_points_down_beyond_the_limit(beta, expected):
    """Every normal of the line points down alike: the mean over the down-facing samples and the
    mean over their worst share are the same number, and the loss is their sum."""
    spec = _spec({"angle": 45, "up": [0, 1]})
    task = make_task(spec, spec.config(None, {"sampling": {"n_domain": 2048, "n_boundary": 64}}))
    assert [c for c in task.constraints if isinstance(c, Overhang)]
    terms = task.loss_terms(LineField(beta), 0, {"overhang", "eikonal"}, torch.Generator().manual_seed(0))
    assert float(terms["overhang"].detach()) == pytest.approx(2 * expected, abs=1e-5)
    if expected > 0:
        terms["overhang"].backward()  # differentiable w.r.t. the parameters through the normals


class _Slab(torch.nn.Module):
    """The slab |y - 0.2| <= 0.1: its top faces up, its underside straight down."""

    def __init__(self):
        super().__init__()
        self.p = torch.nn.Parameter(torch.zeros(()))

    def forward(self, x, z=None):
        return (x[:, 1] - 0.2).abs() - 0.1 + 0 * self.p


def test_loss_is_per_unit_of_down_facing_boundary():
    """Half of the slab's boundary faces down, straight: 1 - sin 45 per down-facing sample, as much
    as a shape that faces only down (twice: the mean and the tail's mean)."""
    spec = _spec({"angle": 45, "up": [0, 1]})
    task = make_task(spec, spec.config(None, {"sampling": {"n_domain": 2048, "n_boundary": 128}}))
    terms = task.loss_terms(_Slab(), 0, {"overhang", "eikonal"}, torch.Generator().manual_seed(0))
    assert float(terms["overhang"].detach()) == pytest.approx(2 * (1 - math.sin(math.radians(45))), abs=1e-5)


class _PlateWithHole(torch.nn.Module):
    """The plate |y| <= 0.8 with a round hole of radius ``radius`` at the origin, an exact distance
    near the hole's top and the plate's underside: both face straight down."""

    def __init__(self, radius):
        super().__init__()
        self.radius = radius
        self.p = torch.nn.Parameter(torch.zeros(()))

    def forward(self, x, z=None):
        return torch.maximum(x[:, 1].abs() - 0.8, self.radius - x.norm(dim=-1)) + 0 * self.p


@pytest.mark.parametrize("radius", [0.3, 0.33])
def test_loss_leaves_the_boundary_that_an_interface_is_still_pulling_in(radius):
    """The hole's interface is the circle of radius 0.3. A hole of 0.33 lies 0.03 (six tolerances)
    beyond it, the nearest its boundary comes to the interface: its ceiling is the interface's still
    to place, not overhang to turn, so the loss is the underside's alone (1 - sin 45 per sample, in the
    mean and in the tail's mean), as when the hole sits on the interface; the underside, 0.5 from the interface, stays counted."""
    spec = validate_spec({"name": "hole", "geometry": {
        "dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
        "interfaces": [{"type": "circle", "center": [0, 0], "radius": 0.3}]},
        "tolerances": {"interface": 0.005, "overhang": {"angle": 45, "up": [0, 1]}}})
    task = make_task(spec, spec.config(None, {"sampling": {"n_domain": 4096, "n_boundary": 128}}))
    c = next(c for c in task.constraints if isinstance(c, Overhang))
    terms = task.loss_terms(_PlateWithHole(radius), 0, {"overhang", "eikonal"}, torch.Generator().manual_seed(0))
    assert float(terms["overhang"].detach()) == pytest.approx(2 * (1 - math.sin(math.radians(45))), abs=1e-5)
    x = torch.tensor([[0.0, radius], [0.0, -0.8]])
    assert c._realising(_PlateWithHole(radius), x, None).tolist() == [True, False]


def test_the_verdict_leaves_the_boundary_that_realises_an_interface_to_it():
    """The plate with a hole of radius 0.33 round an interface circle of 0.3: the hole's ceiling is
    the nearest the boundary comes to the interface, so it is the interface's, not overhang; what
    faces down beyond 45 degrees is the underside alone, all of it. Exempting by the distance alone
    counted the ceiling's 90-degree arc too: (2 + 0.33 pi / 2) / (2 + 0.33 pi) of the down-facing
    boundary."""
    from ginn.extract.overhang import realising_elements
    from ginn.geometry import Circle

    b = _boundary(lambda x: np.maximum(np.abs(x[..., 1]) - 0.8, 0.33 - np.linalg.norm(x, axis=-1)), [-1, -1], [1, 1], (512, 512))
    up, hole = np.array([0.0, 1.0]), [Circle([0.0, 0.0], 0.3)]
    by_distance = exempt_elements(b, up, plate=-1.0, tol=0.005, interfaces=hole)
    r = 0.33
    assert overhang_share(b, up, 45.0, by_distance) == pytest.approx((2 + r * math.pi / 2) / (2 + r * math.pi), rel=0.01)
    realising = realising_elements(b, hole, 0.005)
    c = b.vertices[b.elements].mean(axis=1)
    assert np.array_equal(realising, np.abs(np.linalg.norm(c, axis=1) - r) < 0.01)  # the hole, not the plate
    assert overhang_share(b, up, 45.0, by_distance | realising) == pytest.approx(1.0, abs=1e-9)


def test_tail_means_are_each_shapes_worst_share():
    """Three shapes: the first's five facing samples 0.9, 0.1, 0.8, 0.2, 0.3 (a sixth, 1.0, not
    facing), the second's two 0.4, 0.6; the third has none. At the share 0.4 the first keeps its
    ceil(2.0) = 2 worst, (0.9 + 0.8) / 2, the second ceil(0.8) = 1, 0.6; at 0 each keeps its worst."""
    down = torch.tensor([[0.9, 0.1, 1.0, 0.8, 0.2, 0.3],
                         [0.4, 0.6, 0.7, 0.0, 0.0, 0.0],
                         [0.5, 0.5, 0.5, 0.5, 0.5, 0.5]], requires_grad=True)
    facing = torch.tensor([[True, True, False, True, True, True],
                           [True, True, False, False, False, False],
                           [False] * 6])
    t = tail_means(down, facing, 0.4)
    assert t.tolist() == pytest.approx([0.85, 0.6])
    t.sum().backward()  # the gradient reaches the kept samples alone, 1 / k each
    assert down.grad.flatten().tolist() == pytest.approx([0.5, 0, 0, 0.5, 0, 0] + [0, 1, 0, 0, 0, 0] + [0] * 6)
    assert tail_means(down, facing, 0.0).tolist() == pytest.approx([0.9, 0.6])
    assert tail_means(down, facing, 1.0).tolist() == pytest.approx([0.46, 0.5])


def test_loss_acts_on_a_small_overhanging_share_at_full_strength():
    """The slab's underside tilted by 60 degrees on a tenth of its width beyond x = 0.8: the mean over
    the down-facing samples dilutes that tenth, the tail's mean at the share 0.01 sees it whole."""
    spec = _spec({"angle": 45, "up": [0, 1]})
    task = make_task(spec, spec.config(None, {"sampling": {"n_domain": 4096, "n_boundary": 256}}))
    terms = task.loss_terms(_Wedge(), 0, {"overhang", "eikonal"}, torch.Generator().manual_seed(0))
    beyond = math.sin(math.radians(60)) - math.sin(math.radians(45))
    # the steep face is 0.35 / (1.85 + 0.35) = 16 % of the boundary: the mean is 0.16 * beyond, the tail's beyond
    assert float(terms["overhang"].detach()) == pytest.approx((1 + 0.346 / (1.848 + 0.346)) * beyond, rel=0.02)


class _Wedge(torch.nn.Module):
    """The wedge above (0.7, -0.6) between a face whose normal points 30 degrees below the
    horizontal (1.85 long to the domain's top) and one at 60 degrees (0.35 long to its right side)."""

    def __init__(self):
        super().__init__()
        self.p = torch.nn.Parameter(torch.zeros(()))
        c30, s30 = math.cos(math.radians(30)), math.sin(math.radians(30))
        self.register_buffer("n", torch.tensor([[-c30, -s30], [s30, -c30]]))  # (2, 2) the outward normals

    def forward(self, x, z=None):
        h = (x - torch.tensor([0.7, -0.6])) @ self.n.T  # (n, 2); at a tie the gradient is one face's
        return torch.where(h[:, 0] >= h[:, 1], h[:, 0], h[:, 1]) + 0 * self.p
