"""Structural problems (``physics:`` in a spec): the spec's refusals, the supports and loads on the
element grid, the volume-bound offset and its implicit gradient, the compliance report against a
bar's closed form, and a short training whose compliance falls."""

from types import SimpleNamespace

import numpy as np
import pytest
import torch
import yaml

from ginn import runs
from ginn.cli import main
from ginn.constraints import Verdict
from ginn.constraints.attachment import DEPTHS, Attachment, AttachmentVerdict
from ginn.constraints.base import Setting
from ginn.constraints.compliance import (
    START_PENALTY,
    START_WIDTH,
    Compliance,
    ComplianceReport,
    count_error,
    covered,
    solid_elements,
    volume_margin,
)
from ginn.constraints.volume import VolumeFraction
from ginn.errors import SpecError
from ginn.eval.feasibility import FeasibilityCheck
from ginn.physics import ElasticitySolver, ElementGrid
from ginn.problems import get_spec, validate_spec
from ginn.problems.derived import smallest_feature
from ginn.problems.structural import (
    VOID,
    couple,
    design_depth,
    design_on,
    design_shares,
    held_corners,
    held_elements,
    held_nodes,
    simp_reference,
    structural_grid,
    structural_solver,
    upsample,
    void_elements,
)

BAR = {
    "name": "bar",
    "geometry": {"dim": 2, "domain": {"lo": [0, 0], "hi": [4, 1]},
                 "interfaces": [{"type": "segment", "a": [0, 0], "b": [0, 1]}, {"type": "segment", "a": [4, 0], "b": [4, 1]}]},
    "tolerances": {"volume_fraction": {"max": 0.5}},
    "physics": {"material": {"youngs_modulus": 2.0, "poisson_ratio": 0.3},
                "supports": [{"interface": 0, "fix": ["x"]},
                             {"region": {"type": "rectangle", "lo": [-1, -1], "hi": [0.01, 0.01]}, "fix": ["y"]}],
                "loads": [{"interface": 1, "force": [1.0, 0.0]}]},
}


def _spec(**physics):
    data = {**BAR, "physics": {**BAR["physics"], **physics}}
    return validate_spec(data)


_BAD = [
    ({"supports": []}, "physics.supports"),
    ({"material": {"youngs_modulus": -1.0}}, "physics.material.youngs_modulus"),
    ({"material": {"poisson_ratio": 0.5}}, "physics.material.poisson_ratio"),
    ({"material": {"poisson_ratio": -1.0}}, "physics.material.poisson_ratio"),
    ({"loads": [{"interface": 1, "force": [1.0]}]}, "physics.loads[0].force"),
    ({"loads": None}, "physics"),
    ({"loads": [{"interface": 1}]}, "physics.loads[0]"),  # neither force nor torque
    ({"loads": [{"interface": 1, "torque": [1.0, 0.0]}]}, "physics.loads[0]"),  # 2D: a number
    ({"loads": [{"interface": [], "force": [1.0, 0.0]}]}, "physics.loads[0].interface"),
    ({"supports": [{"region": {"type": "disk", "center": [0, 0], "radius": 0.1}, "fix": ["normal"]}]},
     "physics.supports[0].fix"),  # a region has no normal
]


def test_physics_needs_a_volume_bound():
    with pytest.raises(SpecError, match="spec field 'physics': a structural problem needs tolerances.volume_fraction.max"):
        validate_spec({**BAR, "tolerances": {}})


@pytest.mark.parametrize("change,field", _BAD)
def test_bad_physics_refused_in_one_line(change, field):
    with pytest.raises(SpecError) as e:
        _spec(**change)
    assert f"spec field '{field}" in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("change,text", [
    ({"loads": [{"interface": 5, "force": [1.0, 0.0]}]}, "'physics.loads[0].interface': no interface 5"),
    ({"loads": [{"interface": [1, 7], "force": [1.0, 0.0]}]}, "'physics.loads[0].interface': no interface 7"),
    ({"loads": [{"region": {"type": "disk", "center": [9, 9], "radius": 0.1}, "force": [1.0, 0.0]}]},
     "'physics.loads[0]': reaches no node"),
    ({"supports": [{"region": {"type": "disk", "center": [9, 9], "radius": 0.1}}]}, "'physics.supports[0]': reaches no node"),
])
def test_a_load_or_support_on_nothing_exits_2(change, text, tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({**BAR, "physics": {**BAR["physics"], **change}}))
    try:
        code = main(["train", str(path), "--iterations", "1", "--out", str(tmp_path / "run"), "--quiet"])
    except SystemExit as e:
        code = e.code
    err = capsys.readouterr().err.strip()
    assert code == 2 and text in err and len(err.splitlines()) == 1


def test_supports_and_loads_on_the_grid():
    p = _spec().build()
    grid = structural_grid(p, 40)
    solver, w = structural_solver(p, grid)
    assert grid.shape == (40, 10) and w.tolist() == [1.0]
    x = grid.nodes
    fixed = solver.fixed.reshape(-1, 2)
    assert np.array_equal(fixed[:, 0], np.isclose(x[:, 0], 0))  # the left edge on rollers along x
    assert np.flatnonzero(fixed[:, 1]).tolist() == [0]  # one node held along y: the corner
    F = solver.forces.reshape(-1, 2)
    assert F[:, 0].sum() == pytest.approx(1.0) and np.all(F[~np.isclose(x[:, 0], 4), 0] == 0)
    assert np.allclose(F[np.isclose(x[:, 0], 4), 0], 1.0 / 11)


def test_loads_and_supports_act_on_the_shapes_side_of_an_interface_with_normals():
    """A face with a prescribed normal between two node rows, 0.04 below the top row of a grid of
    0.1: the top row lies beyond it (where the shape must be void), the row below 0.06 from it, past
    half an element. The support holds the row below, and all of it. A pin hole whose rim has inward
    normals: the load acts only on nodes outside the hole, within one element of the rim, and
    carries the whole force; a hole without normals keeps the nodes within half an element on both
    sides."""
    spec = {"name": "lid", "geometry": {"dim": 2, "domain": {"lo": [0, 0], "hi": [4, 1]},
                                        "interfaces": [{"type": "segment", "a": [0, 0.96], "b": [4, 0.96], "normal": [0, 1]},
                                                       {"type": "circle", "center": [2.03, 0.42], "radius": 0.17,
                                                        "normals": "inward"}]},
            "tolerances": {"volume_fraction": {"max": 0.4}},
            "physics": {"supports": [{"interface": 0}], "loads": [{"interface": 1, "force": [0.0, -1.0]}]}}
    p = validate_spec(spec).build()
    grid = structural_grid(p, 40)
    solver, _ = structural_solver(p, grid)
    x = grid.nodes
    held = solver.fixed.reshape(-1, 2).all(axis=1)
    assert np.array_equal(held, np.isclose(x[:, 1], 0.9))
    F = solver.forces.reshape(-1, 2)
    loaded = np.abs(F).sum(axis=1) > 0
    r = np.linalg.norm(x[loaded] - np.array([2.03, 0.42]), axis=1)
    assert np.all(r >= 0.17) and np.all(r <= 0.17 + 0.1) and loaded.sum() >= 8
    assert F.sum(axis=0) == pytest.approx([0.0, -1.0])
    assert np.array_equal(held_nodes(p, grid), held | loaded)
    spec["geometry"]["interfaces"][1]["normals"] = "none"
    p = validate_spec(spec).build()
    loaded = np.abs(structural_solver(p, grid)[0].forces.reshape(-1, 2)).sum(axis=1) > 0
    r = np.linalg.norm(x - np.array([2.03, 0.42]), axis=1)
    assert np.array_equal(loaded, np.abs(r - 0.17) <= 0.05 + 1e-12) and (r[loaded] < 0.17).any()


LEVER = {
    "name": "lever",
    "geometry": {"dim": 2, "domain": {"lo": [-120.0, -70.0], "hi": [120.0, 70.0]},
                 "design_region": {"type": "difference", "children": [
                     {"type": "rectangle", "lo": [-110.0, -60.0], "hi": [110.0, 60.0]},
                     {"type": "disk", "center": [0.0, 0.0], "radius": 12.0}]},
                 "interfaces": [{"type": "circle", "center": [0.0, 0.0], "radius": 12.0, "normals": "inward"},
                                {"type": "circle", "center": [-90.0, 40.0], "radius": 8.0},
                                {"type": "circle", "center": [90.0, -40.0], "radius": 8.0}]},
    "tolerances": {"volume_fraction": {"max": 0.25}},
    "physics": {"material": {"youngs_modulus": 70e3, "poisson_ratio": 0.33},
                "supports": [{"interface": 0, "fix": ["normal"]}, {"interface": 2, "fix": ["y"]}],
                "loads": [{"interface": 1, "force": [-200.0, -400.0]}]},
}


def test_a_pin_support_lets_the_part_turn_so_the_link_takes_the_moment():
    """``fix: [normal]`` on a pivot's rim is a frictionless pin: its nodes are held along the rim's
    normal (radial, to the centre), their reactions have no moment about the pivot, and the link
    held along y balances the load's moment alone, whatever the part's stiffness."""
    p = validate_spec(LEVER).build()
    grid = structural_grid(p, 96)
    solver, _ = structural_solver(p, grid)
    x = grid.nodes
    pin = solver.frames.nodes
    assert pin.size > 20 and not solver.fixed.reshape(-1, 2)[pin].any()
    radial = x[pin] / np.linalg.norm(x[pin], axis=1, keepdims=True)
    assert np.allclose(np.abs((solver.frames.Q[:, :, 0] * radial).sum(axis=1)), 1.0, atol=1e-12)
    E = torch.where(torch.as_tensor(solver.active), 70e3, 70e3 * VOID).to(torch.float64)
    U = solver.solve(E)[0, 0].numpy()
    plain = ElasticitySolver(grid, 0.33, np.zeros(grid.n_dofs, bool), np.zeros((1, grid.n_dofs)), active=solver.active)
    R = np.zeros(grid.n_dofs)
    R[plain.free] = plain.stiffness(E.numpy()) @ U[plain.free] - solver.forces[0, plain.free]
    R = R.reshape(-1, 2)
    F = solver.forces[0].reshape(-1, 2)
    load_moment = (x[:, 0] * F[:, 1] - x[:, 1] * F[:, 0]).sum()
    link = solver.fixed.reshape(-1, 2)[:, 1]
    link_moment = (x[link, 0] * R[link, 1]).sum()
    pin_moment = (x[pin, 0] * R[pin, 1] - x[pin, 1] * R[pin, 0]).sum()
    assert abs(pin_moment) <= 1e-8 * abs(load_moment)
    assert link_moment == pytest.approx(-load_moment, rel=1e-8)
    assert np.abs((U.reshape(-1, 2)[pin] * radial).sum(axis=1)).max() <= 1e-12 * np.abs(U).max()
    clamped = validate_spec({**LEVER, "physics": {**LEVER["physics"], "supports": [
        {"interface": 0}, {"interface": 2, "fix": ["y"]}]}}).build()
    csolver, _ = structural_solver(clamped, grid)
    Uc = csolver.solve(E)[0, 0].numpy()
    # a support that holds less leaves the part more compliant (here 31.5 against 24.5)
    assert float(solver.work(torch.from_numpy(U[None, None]))) > 1.2 * float(csolver.work(torch.from_numpy(Uc[None, None])))


def _moment(x, F):
    """The moment of nodal forces ``F`` at ``x`` about the origin: ``(1,)`` in 2D, ``(3,)`` in 3D."""
    if x.shape[1] == 2:
        return np.array([(x[:, 0] * F[:, 1] - x[:, 1] * F[:, 0]).sum()])
    return np.cross(x, F).sum(axis=0)


def test_a_torque_is_a_couple_of_its_moment():
    """On the bar's two end edges together (one load on a list of interfaces): zero net force, the
    stated moment, and forces across the bar's axis (a couple about z)."""
    p = _spec(loads=[{"interface": [0, 1], "torque": 3.0}]).build()
    solver, _ = structural_solver(p, structural_grid(p, 40))
    x, F = solver.grid.nodes, solver.forces.reshape(-1, 2)
    loaded = np.abs(F).sum(axis=1) > 0
    assert np.allclose(F.sum(axis=0), 0, atol=1e-12) and _moment(x, F) == pytest.approx([3.0])
    assert set(np.unique(x[loaded, 0])) == {0.0, 4.0}


def test_a_3d_couple_and_the_points_that_cannot_carry_one():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(30, 3)) + 5.0
    M = (1.0, -2.0, 0.5)
    F = couple(x, M)
    assert np.allclose(F.sum(axis=0), 0, atol=1e-12) and np.allclose(_moment(x, F), M)
    line = np.stack([np.zeros(5), np.zeros(5), np.arange(5.0)], axis=1)  # on the z axis
    assert np.allclose(_moment(line, couple(line, (1.0, 0.0, 0.0))), (1.0, 0.0, 0.0))  # about x: carried
    with pytest.raises(ValueError, match="axis"):
        couple(line, (0.0, 0.0, 1.0))  # about its own line: no lever
    with pytest.raises(ValueError, match="one node"):
        couple(np.ones((1, 2)), (1.0,))


def test_bracket_loads_is_the_bracket_under_the_challenge_loads():
    """The geometry is the `bracket` problem's; on a coarse grid each load case carries its stated
    force or torque (lbf, lbf x unit: 5000 lbf-in over the unit's 3.54669 in) through both pin
    holes, and the four bolt holes are held."""
    loads, plain = get_spec("bracket-loads"), get_spec("bracket")
    assert loads.geometry == plain.geometry
    p = loads.build()
    solver, w = structural_solver(p, structural_grid(p, 20))
    x, F = solver.grid.nodes, solver.forces.reshape(4, -1, 3)
    assert w.tolist() == [1.0] * 4
    s42, c42 = np.sin(np.radians(42)), np.cos(np.radians(42))
    for case, total in zip(F, ([0, 0, 8000], [-8500, 0, 0], [-9500 * s42, 0, 9500 * c42], [0, 0, 0])):
        assert np.allclose(case.sum(axis=0), total, atol=0.1)
    torsion = F[3]
    assert np.allclose(np.cross(x, torsion).sum(axis=0), [0, 0, 5000 / (90.0859 / 25.4)], atol=0.01)
    lugs = np.abs(torsion).sum(axis=1) > 0
    assert set(np.sign(x[lugs, 1]).astype(int)) == {-1, 1}  # both lugs, either side of y = 0
    held = solver.fixed.reshape(-1, 3).all(axis=1)
    assert np.all(x[held, 2] < -0.2)  # at the base plate's bolt holes
    bolts = p.physics.supports[0].where  # the four bolt holes: each holds nodes, and only those near one
    near = np.stack([b.distance(torch.as_tensor(x[held])).numpy() for b in bolts])  # (4, n_held)
    h = float(solver.grid.h.max())
    assert len(bolts) == 4 and np.all(near.min(axis=1) <= 0.5 * h) and np.all(near.min(axis=0) <= h)


def test_upsample_keeps_each_element_value():
    v = np.arange(6.0)
    up = upsample(v, (3, 2)).reshape(6, 4)
    assert np.array_equal(up[::2, ::2], v.reshape(3, 2)) and np.array_equal(up[1::2, 1::2], v.reshape(3, 2))


def test_report_of_a_solid_bar_against_its_closed_form():
    """E all solid: compliance F^2 L / (E A) = 4 / 2 = 2 (the end loads shared equally by the end
    nodes rather than as a uniform traction: within 1 %)."""
    rep = ComplianceReport(_spec().build())

    def solid(x, z=None):
        return -torch.ones(x.shape[0], dtype=x.dtype)

    m = rep.measure(None, None, solid, None)
    assert m["compliance"] == pytest.approx(2.0, rel=0.01)
    assert m["compliance_cases"] == [m["compliance"]]
    # the far corner moves by s L / E = 2 along x and nu s / E = 0.15 across: |u| = 2.0056, plus the
    # local strain of the equal end-node shares
    assert 2.0056 <= m["max_displacement"] <= 2.0056 * 1.03
    assert rep.violation(m) is None and rep.ratio(m) is None  # reported, never violated


def _setting(problem="mbb", spec=None, cells=30):
    spec_obj, cfg = runs.resolve(problem if spec is None else spec, None, {}, sets=[f"structural.cells={cells}"])
    return Setting(spec_obj.build(), cfg, torch.device("cpu"), torch.float64)


def test_volume_offset_meets_the_bound_with_its_implicit_gradient():
    c = Compliance(_setting())
    rng = np.random.default_rng(0)
    n = c.grid.n_elements
    f = torch.tensor(rng.normal(-0.2, 0.3, (2, n)), dtype=torch.float64, requires_grad=True)
    t = c.offset(f)
    assert torch.all(t < 0)  # both shapes are over the bound of 0.5 and move
    mass = c.density(f - t).sum(dim=1)
    margin = volume_margin(covered(f.detach(), c.grid), ~c.void)
    assert torch.all(margin > 0)
    assert torch.allclose(mass, (0.5 - margin) * n, rtol=1e-9)  # onto the bound less the margin
    g = torch.autograd.grad(t[0, 0], f)[0]
    for e in rng.choice(n, 5, replace=False):  # against central differences of the bisection
        d = torch.zeros_like(f)
        d[0, e] = 1e-6
        fd = (c.offset(f.detach() + d)[0, 0] - c.offset(f.detach() - d)[0, 0]) / 2e-6
        assert float(g[0, e]) == pytest.approx(float(fd), rel=1e-4, abs=1e-9)
    under = c.offset(torch.full((1, n), 1.0, dtype=torch.float64))  # an empty shape stays
    assert float(under) == 0.0


DECK = {"name": "deck",
        "geometry": {"dim": 2, "domain": {"lo": [0, 0], "hi": [4, 1]},
                     "interfaces": [{"type": "segment", "a": [0, 1], "b": [4, 1]},
                                    {"type": "segment", "a": [0, 0], "b": [0.3, 0]},
                                    {"type": "segment", "a": [3.7, 0], "b": [4, 0]}],
                     "obstacles": [{"type": "rectangle", "lo": [1, 0], "hi": [3, 0.25]}]},
        "tolerances": {"volume_fraction": {"max": 0.2}},
        "physics": {"supports": [{"interface": 1}, {"interface": 2, "fix": ["y"]}],
                    "loads": [{"interface": 0, "force": [0.0, -1.0]}]}}


def test_volume_fraction_of_e_counts_the_obstacles_in_e(tmp_path):
    """The spec bounds vol(shape ∩ E) / vol(E), E with the obstacles in it (as ``ginn eval``
    measures it): the element-grid estimate of a band of a quarter of the deck is 0.25, not the
    0.2857 of E less the obstacle (an eighth of it), and the compliance term's offset holds a shape
    at the bound's share of all of E."""
    path = tmp_path / "deck.yaml"
    path.write_text(yaml.safe_dump(DECK))
    setting = _setting(spec=str(path), cells=40)
    term = VolumeFraction(setting)
    band = SimpleNamespace(field_at=lambda key, x: (0.75 - x[:, 1])[None])  # solid for y >= 0.75
    v, _ = term.fractions(band)
    assert float(v) == pytest.approx(0.25, abs=1e-9)
    c = Compliance(setting)
    n = c.grid.n_elements
    assert int(c.design.sum()) == n and int(c.void.sum()) >= n // 8  # the obstacle's elements are void
    f = (0.5 - c.centres[:, 1])[None].to(torch.float64).neg()  # solid for y <= 0.5: over the bound
    t = c.offset(f)
    margin = volume_margin(covered(f, c.grid), c.design)
    assert float(c.density(f - t).sum()) == pytest.approx(float((0.2 - margin) * n), rel=1e-9)


def test_design_shares_measure_e():
    """E's share of each element: exact for a rectangle whose faces cut the elements anywhere (where
    the count of centres in E is off by the faces' offsets), within 1e-3 for a disk (its curvature);
    ones without a design region."""
    rect = {"name": "r", "geometry": {"dim": 2, "domain": {"lo": [0, 0], "hi": [3, 2]},
                                      "design_region": {"type": "rectangle", "lo": [0.31, 0.17], "hi": [2.63, 1.58]},
                                      "interfaces": [{"type": "segment", "a": [0.31, 0.5], "b": [0.31, 1.0]},
                                                     {"type": "segment", "a": [2.63, 0.5], "b": [2.63, 1.0]}]},
            "tolerances": {"volume_fraction": {"max": 0.4}},
            "physics": {"supports": [{"interface": 0}], "loads": [{"interface": 1, "force": [0.0, -1.0]}]}}
    grid = ElementGrid((0.0, 0.0), (3.0, 2.0), (30, 20))
    area = float(np.prod(grid.h))
    p = validate_spec(rect).build()
    shares = design_shares(p, grid)
    # exact along the faces; the four corner elements (a distance, not a plane) off by under half each
    assert abs(shares.sum() - 2.32 * 1.41 / area) < 2.0
    inner = (grid.centres[:, 0] > 0.5) & (grid.centres[:, 0] < 2.5)  # away from the corners
    bottom = inner & (np.abs(grid.centres[:, 1] - 0.15) < 1e-9)
    assert np.allclose(shares[bottom], 0.3, atol=1e-9)  # the face y = 0.17 leaves 3 tenths of the row in E
    centres = grid.n_elements - void_elements(p, grid).sum()
    assert abs(centres - 2.32 * 1.41 / area) > 5  # counting the centres in E: off along the faces
    disk = {**rect, "geometry": {**rect["geometry"], "design_region": {"type": "disk", "center": [1.5, 1.0], "radius": 0.8}}}
    assert design_shares(validate_spec(disk).build(), grid).sum() * area == pytest.approx(np.pi * 0.64, rel=1e-3)
    assert np.array_equal(design_shares(validate_spec(BAR).build(), grid), np.ones(grid.n_elements))


def test_covered_share_of_the_elements():
    """Exact for a boundary along a grid axis wherever it cuts the elements; within 2e-4 of a
    tilted line's half-plane, where the centre count is off by 9e-4 to 2.1e-3; within the margin
    (the centre count's standard error) for disks, whose curvature the linear model misses."""
    grid = ElementGrid((0.0, 0.0), (1.0, 1.0), (20, 20))
    x = torch.as_tensor(grid.centres)
    for a in (0.3, 0.337, 0.5049):
        share = covered((x[:, 0] - a)[None], grid)
        assert float(share.sum()) * grid.element_volume == pytest.approx(a, rel=1e-12)
    n = torch.tensor([np.cos(0.3), np.sin(0.3)], dtype=torch.float64)
    xs = torch.as_tensor(ElementGrid((0.0, 0.0), (1.0, 1.0), (2000, 2000)).centres)
    for c in (0.6, 0.55, 0.43):
        f = (x @ n - c)[None]
        exact = float((xs @ n <= c).double().mean())
        assert abs(float(covered(f, grid).mean()) - exact) < 2e-4
        assert abs(float((f <= 0).double().mean()) - exact) > 8e-4
    everywhere = torch.ones(400, dtype=torch.bool)
    for c in (0.5, 0.513, 0.47):
        disk = covered(((x - c).norm(dim=1) - 0.3)[None], grid)
        m = volume_margin(disk, everywhere)
        crossed = int(((disk > 0) & (disk < 1)).sum())
        assert float(m) == pytest.approx(np.sqrt(crossed / 12) / 400) and 40 < crossed < 80
        assert abs(float(disk.mean()) - np.pi * 0.09) < float(m)


def test_design_depth():
    """Half the short side of a rectangle (the element centres': less half an element); the radius
    of a disk-shaped E, to within an element."""
    p = _spec().build()
    grid = structural_grid(p, 40)
    assert design_depth(p, grid) == pytest.approx(0.5 - 0.05, abs=1e-12)
    disk = {**BAR, "geometry": {**BAR["geometry"], "design_region": {"type": "disk", "center": [2, 0.5], "radius": 0.4}}}
    p = validate_spec(disk).build()
    grid = structural_grid(p, 160)
    assert abs(design_depth(p, grid) - 0.4) < 0.025


def test_continuation_from_a_wide_step_and_penalty_one():
    """Width START_WIDTH x the beam's depth (half its height, less half an element: the element
    centres' depth) and penalty 1 at the start, the geometric and linear midpoints a quarter into
    the run, half an element and 3 from halfway on; the moduli follow the current penalty."""
    c = Compliance(_setting())
    n = c.setting.cfg.training.iterations
    h = float(c.grid.h.min())
    assert c.grid.shape == (30, 10)
    w0 = START_WIDTH * (0.5 - h / 2)
    assert c.schedule(0) == pytest.approx((w0, START_PENALTY))
    assert c.schedule(n // 4) == pytest.approx((np.sqrt(w0 * h / 2), (START_PENALTY + 3) / 2), rel=1e-9)
    assert c.schedule(n // 2) == pytest.approx((h / 2, 3.0)) and c.schedule(n) == c.schedule(n // 2)
    c.width, c.penalty = c.schedule(0)
    rho = torch.tensor([[0.5]], dtype=torch.float64)
    assert float(c.moduli(rho)) == pytest.approx(VOID + (1 - VOID) * 0.5)


def test_elements_around_each_node():
    grid = ElementGrid((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (3, 2, 4))
    around = grid.node_elements
    assert around.shape == (grid.n_nodes, 8)
    k = np.nonzero(around >= 0)
    assert np.array_equal(grid.element_nodes[around[k], k[1]], k[0])  # the node is that corner of the element
    assert np.bincount(around[around >= 0]).tolist() == [8] * grid.n_elements
    count = (around >= 0).sum(axis=1).reshape(grid.node_shape)
    assert count[0, 0, 0] == 1 and count[1, 0, 0] == 2 and count[1, 1, 0] == 4 and count[1, 1, 1] == 8


class _Field:
    """A stand-in for a step's batch: the given field values at the element centres."""

    def __init__(self, f, step=10**9):
        self.f, self.step = f, step

    def field_at(self, key, x):
        return self.f


def test_attachment_holds_the_load_pads_not_the_clamped_wall():
    """The cantilever's pads at x = 1.5, y in [0.1, 0.2] and [0.8, 0.9]: 7 nodes each on the
    90 x 60 grid (spacing 1/60, reach half of it), each with 2 elements in E; the clamped wall (a
    region) is not held. The term reads the report's grid (twice as fine: 13 nodes a pad) as its
    verdict does, at the centres of the node's report elements and at the centres of the elements
    of the default grid's size and of grids 2 and 4 times as fine as the report's with a corner at
    the node (``h / 2``, ``h``, ``h / 4`` and ``h / 8`` from the pad, ``h`` the report's side).
    Loss ``relu(m + a w/2) / w`` over the four (``a`` 1, 1, 1/2, 1/4), ``w`` from START_WIDTH
    times the depth (the report grid's: 0.5 less half its element) to ``h / 2``; the verdict's
    share of nodes off the thresholded shape at any depth."""
    setting = _setting("cantilever", cells=0)
    p = setting.problem
    grid = structural_grid(p)
    held = held_nodes(p, grid)
    x = grid.nodes[held]
    assert held.sum() == 14 and np.allclose(x[:, 0], 1.5)
    ys = np.sort(x[:, 1]) * 60
    assert np.allclose(ys, [6, 7, 8, 9, 10, 11, 12, 48, 49, 50, 51, 52, 53, 54])
    around = held_elements(p, grid)
    assert around.shape == (14, 4) and (around >= 0).sum() == 28
    assert np.allclose(grid.centres[around[around >= 0], 0], 1.5 - 1 / 120)
    term = Attachment(setting)
    h = 1 / 120
    n = setting.cfg.training.iterations  # the step width follows the compliance's continuation
    assert term.width(0) == pytest.approx(START_WIDTH * (0.5 - h / 2)) and term.width(n // 2) == pytest.approx(h / 2)
    assert term.width(n // 4) == pytest.approx(np.sqrt(term.width(0) * h / 2), rel=1e-9)
    # 28 report centres, then at each of three depths 4 corners a node, 2 of them in the domain
    assert term.elements.shape == (4, 26, 4) and int(term.present.sum()) == 208 and term.points.shape == (28 + 3 * 104, 2)
    assert np.allclose(term.points[:28, 0], 1.5 - h / 2)  # the report grid's centres by the pads
    for k, depth in enumerate((h, h / 4, h / 8)):
        corners = term.points[term.elements[k + 1][term.present[k + 1]]]
        assert np.allclose(corners[:, 0], 1.5 - depth) and int(term.present[k + 1].sum()) == 52
    xc = term.points
    # solid up to one report element short: m = h / 2, 0, 3 h / 4, 7 h / 8 at the four depths
    loss = term.loss(_Field((xc[:, 0] - 1.5 + h)[None]))
    margins = (h / 2 + h / 4) + (0 + h / 4) + (3 * h / 4 + h / 8) + (7 * h / 8 + h / 16)
    assert float(loss) == pytest.approx(margins / 4 / (h / 2), rel=1e-9)
    assert float(term.loss(_Field((xc[:, 0] - 1.6)[None]))) == 0.0
    low = term.loss(_Field(torch.where(xc[:, 1] < 0.5, xc[:, 0] - 1.6, xc[:, 0] - 1.5 + h)[None]))
    assert float(low) == pytest.approx(0.5 * float(loss), rel=1e-9)  # one pad held of two
    w0 = term.width(0)  # at the start the margins are w0 / 2, w0 / 2, w0 / 4 and w0 / 8
    early = term.loss(_Field((xc[:, 0] - 1.5 + h)[None], step=0))
    assert float(early) == pytest.approx((h / 2 + 3 * h / 4 + 7 * h / 8 + w0 * (1 + 1 / 4 + 1 / 8)) / 4 / w0, rel=1e-9)
    # a shape that stops a quarter of a pad short of its lower end (y < 0.125): 3 of its 13 nodes
    # (y = 0.1, 0.1083, 0.1167) short at the report's centres and the two finer depths, 2 at the
    # default's corners (y -+ h: the third node's upper corner lies at 0.125, in the solid)
    short = term.loss(_Field(torch.where(xc[:, 1] < 0.125, xc[:, 0] - 1.5 + h, xc[:, 0] - 1.6)[None]))
    margins = 3 * (h / 2 + h / 4) + 2 * (0 + h / 4) + 3 * (3 * h / 4 + h / 8) + 3 * (7 * h / 8 + h / 16)
    assert float(short) == pytest.approx(margins / 104 / (h / 2), rel=1e-9)
    v = AttachmentVerdict(p)
    m = v.measure(None, None, lambda x, z=None: x[:, 0] - 1.6, None)
    assert m == {"unheld_nodes": 0.0} and v.violation(m) is None and v.ratio(m) == 0.0
    m = v.measure(None, None, lambda x, z=None: torch.where(x[:, 1] < 0.5, x[:, 0] - 1.6, x[:, 0] - 1.4), None)
    assert m["unheld_nodes"] == pytest.approx(0.5) and v.ratio(m) == pytest.approx(1.5)
    assert v.violation(m).value == pytest.approx(0.5) and "0.5 of the load" in v.describe(v.violation(m))
    m = v.measure(None, None, lambda x, z=None: torch.where(x[:, 1] < 0.125, x[:, 0] - 1.4, x[:, 0] - 1.6), None)
    assert m["unheld_nodes"] == pytest.approx(3 / 26)


def test_attachment_sees_a_pad_held_by_a_wall_thinner_than_a_default_element():
    """A hole behind the upper pad leaves it a wall 0.006 thick, a third of a default element
    (1/60): the report grid's centres by the pad (h / 2 = 1/240 from it) lie in the wall, the
    centres of a default grid (1/120 from it) in the hole, where a solver of the default grid's
    resolution that fills elements by their centres leaves the pad's 7 nodes on void. The
    verdict counts the pad's 13 report nodes unheld; the term's value is that of the corners'
    depth alone."""
    p = _setting("cantilever", cells=0).problem

    def walled(x, z=None):  # solid everywhere but a hole 0.006 to 0.03 behind the upper pad
        hole = (x[:, 0] > 1.47) & (x[:, 0] < 1.494) & (x[:, 1] > 0.78) & (x[:, 1] < 0.92)
        return torch.where(hole, torch.ones_like(x[:, 0]), -torch.ones_like(x[:, 0]))

    coarse = structural_grid(p)
    solid = solid_elements(walled, None, coarse, np.zeros(coarse.n_elements, bool))
    on_void = ~np.append(solid, False)[coarse.node_elements[held_nodes(p, coarse)]].any(axis=1)
    assert int(on_void.sum()) == 7
    fine = coarse.refined(2)
    solid = solid_elements(walled, None, fine, np.zeros(fine.n_elements, bool))
    assert np.append(solid, False)[held_elements(p, fine)].any(axis=1).all()  # the report grid alone holds it
    m = AttachmentVerdict(p).measure(None, None, walled, None)
    assert m["unheld_nodes"] == pytest.approx(13 / 26)


def test_attachment_sees_a_pad_end_rounded_off_within_a_report_element():
    """A notch a third of a report element deep (h / 3, ``h`` = 1/120) cut from the lower pad's
    end node (1.5, 0.2): the report's centres (h / 2 from the node) and the default's (h) lie in
    the solid beyond it, those of grids 2 and 4 times as fine (h / 4, h / 8) in the notch, where a
    solver of that resolution leaves the node on void. The verdict counts that one node of 26."""
    p = _setting("cantilever", cells=0).problem
    h = 1 / 120

    def notched(x, z=None):
        notch = (x[:, 0] > 1.5 - h / 3) & (torch.abs(x[:, 1] - 0.2) < h / 3)
        return torch.where(notch, torch.ones_like(x[:, 0]), -torch.ones_like(x[:, 0]))

    m = AttachmentVerdict(p).measure(None, None, notched, None)
    assert m["unheld_nodes"] == pytest.approx(1 / 26)
    fine = structural_grid(p).refined(4)  # a grid twice as fine as the report's: the node on void
    solid = np.append(solid_elements(notched, None, fine, np.zeros(fine.n_elements, bool)), False)
    on_void = ~solid[held_elements(p, fine)].any(axis=1)
    assert int(on_void.sum()) == 1 and np.allclose(fine.nodes[np.flatnonzero(held_nodes(p, fine))[on_void]], [[1.5, 0.2]])


def test_attachment_asks_nothing_inside_a_bolt_hole_that_e_does_not_cut_out():
    """A torque on a bore whose rim is an interface with inward normals, in a disk E that does not
    cut the bore out: the rim's nodes inside the bore are held through their report elements
    across the rim, and the finer depths' points inside the bore (where the shape must be void)
    are not asked for. A ring that fills E from the rim out, exactly, holds every node."""
    hub = {"name": "hub", "geometry": {"dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
                                       "design_region": {"type": "disk", "center": [0, 0], "radius": 1.0},
                                       "interfaces": [{"type": "circle", "center": [0, 0], "radius": 0.2},
                                                      {"type": "circle", "center": [0.75, 0], "radius": 0.08}]},
           "tolerances": {"volume_fraction": {"max": 0.35}},
           "physics": {"supports": [{"interface": 1}], "loads": [{"interface": 0, "torque": 1.0}]}}
    p = validate_spec(hub).build()
    grid = ComplianceReport(p).fine()[0]
    for side, _ in DEPTHS:
        points, present = held_corners(p, grid, side * grid.h)
        r0 = np.linalg.norm(points, axis=-1)
        r1 = np.linalg.norm(points - np.array([0.75, 0.0]), axis=-1)
        assert not (present & ((r0 < 0.2 - 1e-9) | (r1 < 0.08 - 1e-9))).any()  # nothing inside a hole
        assert present.any(axis=1).sum() > 0.4 * present.shape[0]

    def ring(x, z=None):  # solid outside both holes: the rims exactly on the boundary
        return torch.maximum(0.2 - x.norm(dim=1), 0.08 - (x - torch.tensor([0.75, 0.0], dtype=x.dtype)).norm(dim=1))

    assert AttachmentVerdict(p).measure(None, None, ring, None)["unheld_nodes"] == 0.0


def test_feasibility_checks_leave_the_compliance_report_to_eval():
    """The checks during training, at held-out codes and in the explorer judge; the report's solve
    on the fine grid is ginn eval's alone. The attachment is judged."""
    p = _spec().build()
    check = FeasibilityCheck(p, 64)
    m, _ = check.shape(lambda x, z=None: x[:, 1] - 2.0, None)  # all of the domain
    assert "compliance" not in m.extra and m.extra["unheld_nodes"] == 0.0
    m, _ = check.shape(lambda x, z=None: x[:, 1] - 0.6, None)  # the end nodes above y = 0.6 + h off it
    assert abs(m.extra["unheld_nodes"] - 0.4) < 1 / 44
    m, _ = check.shape(lambda x, z=None: x[:, 0] - 3.0, None)  # the supported end held, the loaded one not
    assert m.extra["unheld_nodes"] == 0.5
    assert [v.name for v in check.verdicts if not v.judges] == ["compliance"]


def test_simp_reference_of_the_mbb_problem():
    p = get_spec("mbb").build()
    ref = simp_reference(p)
    assert ref.solid.mean() == pytest.approx(0.5, abs=1e-3)
    assert ref.result.density.mean() == pytest.approx(0.5, abs=1e-3)  # the held elements' count in the bound
    assert ref.compliance < 0.25 * ComplianceReport(p).measure(None, None, lambda x, z=None: x[:, 0] - 1.5, None)["compliance"]


def test_simp_reference_holds_a_distributed_load():
    """A deck loaded along its whole top edge, on two bearings: the thresholded reference keeps every
    loaded node on solid (the held elements), so that its compliance re-solved on the fine grid is
    that of SIMP's design (its grey compliance, relative modulus 1, within 30 %), not that of a
    load left on the void's ersatz modulus."""
    deck = {"name": "deck",
            "geometry": {"dim": 2, "domain": {"lo": [0, 0], "hi": [4, 1]},
                         "interfaces": [{"type": "segment", "a": [0, 1], "b": [4, 1]},
                                        {"type": "segment", "a": [0, 0], "b": [0.3, 0]},
                                        {"type": "segment", "a": [3.7, 0], "b": [4, 0]}]},
            "tolerances": {"volume_fraction": {"max": 0.3}},
            "physics": {"supports": [{"interface": 1}, {"interface": 2, "fix": ["y"]}],
                        "loads": [{"interface": 0, "force": [0.0, -1.0]}]}}
    p = validate_spec(deck).build()
    ref = simp_reference(p)
    grid = structural_grid(p, 0, smallest_feature(p))
    around = held_elements(p, grid)
    assert ref.solid[around[around >= 0]].all()
    assert ref.solid.sum() == round(0.3 * grid.n_elements)
    assert ref.compliance == pytest.approx(ref.result.compliance, rel=0.3)


def test_simp_reference_holds_a_pin_hole_on_the_fine_grid():
    """A load on a hole's rim without prescribed normals (so on the nodes on both sides of it): the
    fine grid's load nodes in the hole's coarse elements are held by :func:`design_on` (solid only
    in E), so the reference re-solved on the fine grid stays near the coarse design's compliance
    (within 25 %: 41.4 against 40.2) instead of carrying loads on void (1579 without the rule)."""
    lug = {"name": "lug",
           "geometry": {"dim": 2, "domain": {"lo": [0, 0], "hi": [2, 1]},
                        "design_region": {"type": "difference", "children": [
                            {"type": "rectangle", "lo": [0, 0], "hi": [2, 1]},
                            {"type": "disk", "center": [1.6, 0.5], "radius": 0.12}]},
                        "interfaces": [{"type": "segment", "a": [0, 0], "b": [0, 1]},
                                       {"type": "circle", "center": [1.6, 0.5], "radius": 0.12, "normals": "none"}]},
           "tolerances": {"volume_fraction": {"max": 0.4}},
           "physics": {"supports": [{"interface": 0}], "loads": [{"interface": 1, "force": [0.0, -1.0]}]}}
    p = validate_spec(lug).build()
    ref = simp_reference(p)
    grid = structural_grid(p, 0, smallest_feature(p))
    fine = grid.refined(2)
    solid = design_on(p, ref.solid, grid, fine)
    assert not (solid & void_elements(p, fine)).any()
    around = held_elements(p, fine)
    assert np.append(solid, False)[around].any(axis=1).all()
    solver, w = structural_solver(p, grid)
    coarse = float(w @ solver.work(solver.solve(torch.as_tensor(np.where(ref.solid, 1.0, VOID))))[0].numpy())
    assert ref.compliance == pytest.approx(coarse, rel=0.25)


def test_strain_energy_density_of_a_bar_and_its_figure(tmp_path):
    """A bar in uniform tension: energy density s^2 / (2 E) = 1 / 4 in the elements away from its
    loaded end; the figure is written."""
    from ginn.viz.structural import plot_strain_energy

    p = _spec().build()
    rep = ComplianceReport(p)

    def solid(x, z=None):
        return -torch.ones(x.shape[0], dtype=x.dtype)

    is_solid, U, density = rep.analyse(solid, None)
    grid = rep.fine()[0]
    inner = (grid.centres[:, 0] > 1.0) & (grid.centres[:, 0] < 3.0)
    assert is_solid.all() and np.allclose(density[0].numpy()[inner], 0.25, rtol=0.02)
    path = plot_strain_energy(solid, None, p, tmp_path / "se.png", rep)
    assert path.stat().st_size > 1000


def test_shapes_solved_together_as_each_alone(monkeypatch):
    """Three bands of different widths: :meth:`ComplianceReport.analyse_all` gives each the
    solution :meth:`analyse` gives it alone, bit for bit, on two threads; after :meth:`prepare`
    the report measures each shape without solving again, to the same numbers, until
    :meth:`release`."""
    p = _spec().build()

    def band(x, z=None):
        return (x[:, 1] - 0.5).abs() - 0.2 - 0.1 * z[:, 0]

    Z = torch.tensor([[-1.0], [0.0], [1.0]], dtype=torch.float64)
    alone = [ComplianceReport(p).analyse(band, Z[i]) for i in range(3)]
    rep = ComplianceReport(p)
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        together = rep.analyse_all(band, Z)
    finally:
        torch.set_num_threads(threads)
    assert len({int(s.sum()) for s, _, _ in together}) == 3
    for (s1, U1, d1), (s2, U2, d2) in zip(alone, together):
        assert np.array_equal(s1, s2) and torch.equal(U1, U2) and torch.equal(d1, d2)
    before = [rep.measure(None, None, band, Z[i]) for i in range(3)]
    rep.prepare(band, Z)
    solver = rep.fine()[1]

    def solve(moduli):
        raise RuntimeError("solved")

    monkeypatch.setattr(solver, "solve", solve)
    assert [rep.measure(None, None, band, Z[i]) for i in range(3)] == before
    rep.release()
    with pytest.raises(RuntimeError, match="solved"):
        rep.measure(None, None, band, Z[0])


BAR_IN_TENSION = """
name: tension-bar
geometry:
  dim: 2
  domain: {lo: [0.0, 0.0], hi: [2.0, 1.0]}
  interfaces:
    - {type: segment, a: [0.0, 0.4], b: [0.0, 0.6]}
    - {type: segment, a: [2.0, 0.4], b: [2.0, 0.6]}
tolerances:
  volume_fraction: {max: 0.2}
physics:
  supports:
    - {interface: 0}
  loads:
    - {interface: 1, force: [1.0, 0.0]}
"""


def test_objective_of_straight_bars_is_their_compliance_and_volume():
    """Straight bars 0.2 to 0.24 thick between the support and the load of the tension bar:
    compliance F^2 L / (E A) = 2 / a and volume fraction a (each within 2 % and 3 %: the load
    spreads from 0.2 of the end into the bar); ``objective_of`` gives the means over the shapes of
    what ``measure`` reports and of the volume of the solved elements."""
    p = validate_spec(yaml.safe_load(BAR_IN_TENSION)).build()
    rep = ComplianceReport(p)

    def bar(x, z=None):
        return (x[:, 1] - 0.5).abs() - z[:, 0]

    Z = torch.tensor([[0.1], [0.11], [0.12]], dtype=torch.float64)
    shares = design_shares(p, rep.fine()[0])
    cs, vs = [], []
    for z in Z:
        cs.append(rep.measure(None, None, bar, z)["compliance"])
        vs.append(float(rep.solid(bar, z) @ shares / shares.sum()))
    a = 2 * Z[:, 0].numpy()
    assert cs == pytest.approx(2 / a, rel=0.02) and vs == pytest.approx(a, rel=0.03)
    c, v, inside = rep.objective_of(bar, Z)
    assert c == pytest.approx(np.mean(cs), rel=1e-12) and v == pytest.approx(np.mean(vs), rel=1e-12)
    assert not inside  # 0.2 to 0.244 against a bound of 0.2
    assert rep.objective and not Verdict.objective

    def clear(bound, codes):
        spec = validate_spec(yaml.safe_load(BAR_IN_TENSION.replace("max: 0.2", f"max: {bound}")))
        return ComplianceReport(spec.build()).objective_of(bar, codes)[2]

    # the thickest bar, 0.2444 counted, is within 0.245 but not by twice its count's error (3.4e-4)
    assert clear(0.3, Z) and clear(0.245, Z[:2]) and not clear(0.245, Z)


def test_count_error_of_a_block_of_elements():
    """A 4 x 3 block of solid elements in a 10 x 10 grid: 10 of its elements have a void face
    neighbour, so the standard error of its count is sqrt(10 / 12) / 100; a block against the
    grid's edge counts only the faces it shares with void."""
    grid = ElementGrid((0.0, 0.0), (1.0, 1.0), (10, 10))
    shares = np.ones(100)
    solid = np.zeros((2, 10, 10), dtype=bool)
    solid[0, 2:6, 3:6] = True
    solid[1, 0:4, 0:3] = True  # in the corner: 6 elements face void
    err = count_error(solid.reshape(2, -1), grid, shares)
    assert err == pytest.approx([np.sqrt(10 / 12) / 100, np.sqrt(6 / 12) / 100])


@pytest.mark.slow
def test_a_bar_in_tension_trains_to_the_straight_bar(tmp_path):
    """A support and an axial load on the middles of the short sides of a 2 x 1 box, volume at most
    0.2: the stiffest shape is the straight bar 0.2 high between them, compliance F^2 L / (E A) = 10.
    With the derived settings (2000 iterations, about 2 minutes on one thread) the shape is one
    piece, holds its volume within 0.01 of the bound, stays within 0.15 of the axis and its
    compliance is within 5 % of the bar's. This run (seed 0, the tests' eager kernels) measured
    volume 0.1956, compliance 10.31 (a straight bar of that volume: 10.23) and the farthest solid
    element 0.117 from the axis. ``ginn train`` compiles its kernels, which round differently and
    so take another path: seeds 0 to 2 ended at 10.79, 10.47 and 10.22 (the compliance grows with
    the square of a ripple in the bar's section, so the last ripples go slowly; seed 0's bar keeps
    some along its length)."""
    path = tmp_path / "bar.yaml"
    path.write_text(BAR_IN_TENSION)
    s, cfg = runs.resolve(str(path), None, {}, sets=["training.threads=1"])
    runs.train(s, cfg, tmp_path / "run", progress=False, results=False)
    shape = runs.evaluate(tmp_path / "run")["shapes"][0]
    assert abs(shape["volume_fraction"] - 0.2) <= 0.01
    assert shape["compliance"] <= 1.05 * 10.0
    run = runs.load_run(tmp_path / "run")
    rep = ComplianceReport(s.build())
    solid, _, _ = rep.analyse(run.model, None)
    off_axis = np.abs(rep.fine()[0].centres[solid, 1] - 0.5)
    assert off_axis.max() <= 0.15


def test_load_cases_weighted_and_quadratic_in_the_force():
    """Two load cases, the second pulling twice as hard: its compliance is 4 times the first's
    (compliance is quadratic in the load) and the report weighs them as the spec says."""
    cases = [{"loads": [{"interface": 1, "force": [1.0, 0.0]}], "weight": 1.0},
             {"loads": [{"interface": 1, "force": [2.0, 0.0]}], "weight": 0.5}]
    p = _spec(loads=None, load_cases=cases).build()
    assert [c.weight for c in p.physics.load_cases] == [1.0, 0.5]
    m = ComplianceReport(p).measure(None, None, lambda x, z=None: -torch.ones(x.shape[0], dtype=x.dtype), None)
    c1, c2 = m["compliance_cases"]
    assert c2 == pytest.approx(4 * c1, rel=1e-9)
    assert m["compliance"] == pytest.approx(c1 + 0.5 * c2, rel=1e-12)


def test_coloured_meshes_of_a_3d_bar_in_tension(tmp_path):
    """An 8 x 1 x 1 bar all solid, pulled by a unit force on its free end: stress 1, strain-energy
    density s^2 / (2 E) = 0.25 (E = 2) away from the ends, compliance F^2 L / (E A) = 4. The PLY
    carries a colour per vertex; the vertices' densities have the uniform value as their median."""
    import trimesh

    from ginn.fields import as_field
    from ginn.viz.structural import strain_energy_meshes, vertex_energy

    spec = {"name": "bar3", "tolerances": {"volume_fraction": {"max": 0.5}},
            "geometry": {"dim": 3, "domain": {"lo": [0, 0, 0], "hi": [8, 1, 1]}},
            "physics": {"material": {"youngs_modulus": 2.0, "poisson_ratio": 0.3},
                        "supports": [{"region": {"type": "box", "lo": [-1, -1, -1], "hi": [0, 2, 2]}, "fix": ["x"]},
                                     {"region": {"type": "box", "lo": [-1, -1, -1], "hi": [0.01, 0.01, 0.01]},
                                      "fix": ["y", "z"]},
                                     {"region": {"type": "box", "lo": [-1, 0.99, -1], "hi": [0.01, 2, 0.01]}, "fix": ["z"]}],
                        "loads": [{"region": {"type": "box", "lo": [8, -1, -1], "hi": [9, 2, 2]}, "force": [1.0, 0.0, 0.0]}]}}
    p = validate_spec(spec).build()
    field = as_field(lambda x: x[:, 1] - 2.0)
    rep = ComplianceReport(p)
    paths = strain_energy_meshes(field, None, p, tmp_path, 48, report=rep)
    assert [q.name for q in paths] == ["strain_energy.ply", "strain_energy.png"]
    mesh = trimesh.load(paths[0], process=False)
    colours = np.asarray(mesh.visual.vertex_colors)
    assert colours.shape == (len(mesh.vertices), 4) and len(np.unique(colours[:, :3], axis=0)) > 1
    solid, U, density = rep.analyse(field, None)

    e = vertex_energy(rep, solid, density[0].numpy(), np.asarray(mesh.vertices))
    assert np.isfinite(e).all() and float(np.median(e)) == pytest.approx(0.25, rel=0.02)
    assert float(rep.fine()[1].work(U[None])[0, 0]) == pytest.approx(4.0, rel=0.02)


def test_checks_resolve_a_structural_element_with_three_cells():
    """A problem with physics is checked on a grid with 3 cells per element of its structural
    grid (members an element thick stay in one piece there), up to ``ginn eval``'s grid."""
    from ginn.config import CELLS_PER_LENGTH, RESOLUTION
    from ginn.eval.feasibility import check_resolution
    from ginn.problems.derived import structural_cells

    bar = _spec().build()
    cells = structural_cells(bar, smallest_feature(bar))
    res = check_resolution(bar)
    assert res % 8 == 0 and CELLS_PER_LENGTH * cells <= res < CELLS_PER_LENGTH * cells + 8
    assert RESOLUTION["check"][2] < res <= RESOLUTION["eval"][2]
    assert check_resolution(get_spec("cantilever-3d").build()) == 112  # 36 elements along its longest side
    assert check_resolution(get_spec("bracket-loads").build()) == RESOLUTION["eval"][3]  # 46: capped
    no_physics = validate_spec({k: v for k, v in BAR.items() if k != "physics"}).build()
    assert check_resolution(no_physics) == RESOLUTION["check"][2]
