"""Problem specs: built-in problems, the user example, and malformed specs -> one-line SpecError."""

import math
import textwrap
from pathlib import Path

import pytest
import torch
import trimesh

from ginn.config import RunConfig
from ginn.errors import ConfigError, SpecError
from ginn.geometry import Box, sample_band, sample_box, sample_inside, sample_interfaces, sample_outside
from ginn.problems import get_spec, list_problems, load_spec, parse_spec, problem_summaries, spec_text
from ginn.problems.spec import validate_spec

F64 = torch.float64
REPO = Path(__file__).resolve().parents[1]


def test_list_and_show_builtins():
    names = list_problems()
    for n in ("obstacle", "bracket", "plateau", "mirror", "gray-scott"):
        assert n in names
    assert "name: obstacle" in spec_text("obstacle")
    summ = {n: (k, d) for n, k, d in problem_summaries()}
    assert summ["obstacle"][0] == "shape" and "\n" not in summ["obstacle"][1] and summ["mirror"][0] == "mirror"
    for n in names:
        s = get_spec(n)
        assert s.name == n
        assert isinstance(s.config(), RunConfig)
        for p in s.presets:
            assert s.config(p).preset == p


def test_builtin_name_beside_a_directory_of_that_name(tmp_path, monkeypatch):
    """A directory is never a spec: in a folder holding a run directory named ``obstacle`` the name
    still means the built-in problem; a directory of any other name is refused in one line."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "obstacle").mkdir()
    (tmp_path / "runs").mkdir()
    assert load_spec("obstacle").name == "obstacle"
    assert spec_text("obstacle") == spec_text(REPO / "src" / "ginn" / "problems" / "presets" / "obstacle.yaml")
    with pytest.raises(SpecError, match="spec runs: is a directory"):
        load_spec("runs")
    with pytest.raises(SpecError, match="is a directory"):
        load_spec(tmp_path / "obstacle")  # a path, not a bare name


def test_obstacle_is_appendix_a4(gen):
    spec = load_spec("obstacle")
    p = spec.build()
    assert p.domain == Box((-1.0, -0.5), (1.0, 0.5))
    assert p.n_interface_components == 2 and len(p.obstacles) == 1
    # E = [-0.9, 0.9] x [-0.4, 0.4] minus the disk r = 0.1
    q = torch.tensor([[0.0, 0.0], [0.05, 0.05], [0.0, 0.11], [0.89, 0.39], [0.91, 0.0], [0.0, 0.41]], dtype=F64)
    assert p.design_region.contains(q).tolist() == [False, False, True, True, False, False]
    x, n = sample_interfaces(p.interfaces, 400, gen, dtype=F64)
    assert ((x[:, 0].abs() - 0.9).abs() < 1e-12).all() and (x[:, 1].abs() <= 0.4).all()
    torch.testing.assert_close(n, torch.stack([torch.sign(x[:, 0]), torch.zeros(400, dtype=F64)], -1))
    assert [i.component_of(x[:1]).item() for i in p.interfaces] == [0, 0]
    # the `paper` preset follows paper Table 2 (SIREN column)
    cfg = spec.config("paper")
    assert cfg.model.kind == "siren" and cfg.model.hidden == [64, 64, 64, 64] and cfg.model.w0_first == 1.0
    assert cfg.latents.n_shapes == 16 and (cfg.latents.low, cfg.latents.high) == (-1.0, 1.0)
    assert cfg.losses.normal.weight == 1e-2 and cfg.losses.eikonal.weight == 1e-5
    assert cfg.training.iterations == 3000 and cfg.training.lr_decay == 0.5
    # without a preset: the spec's 16 shapes, everything else derived as for a user's spec
    cfg = spec.config()
    assert cfg.latents.n_shapes == 16 and (cfg.latents.low, cfg.latents.high) == (-1.0, 1.0)
    assert cfg.model.w0_first == pytest.approx(math.sqrt(1 / 5e-3)) and cfg.model.frame == "domain"
    assert cfg.losses.interface.weight == 3000.0 and cfg.training.iterations == 2000
    # the tuned presets extend `paper`: what `paper` sets and they do not is the paper's
    quick = spec.config("quick")
    assert quick.model.frame == "raw" and quick.model.w0_first == 5.0 and quick.training.lr_decay == 0.5
    area = mc_area(p.design_region, p.domain, gen)
    assert area == pytest.approx(1.44 - math.pi * 0.01, rel=0.01)


def mc_area(region, box, gen, n=200_000):
    x = sample_box(box, n, gen, dtype=F64)
    return region.contains(x).double().mean().item() * box.volume()


def test_plateau_polygon_and_corners(gen):
    p = load_spec("plateau").build()
    assert p.design_region is None and p.dim == 3
    (g,) = p.interfaces
    assert not g.has_normals and g.n_components == 1
    corners = [[0, 0, 0], [1, 0, 0], [1, 0, 1], [1, 1, 1], [1, 1, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]]
    torch.testing.assert_close(g.corners, torch.tensor(corners, dtype=F64))
    x, n = sample_interfaces(p.interfaces, 800, gen, dtype=F64)
    assert g.distance(x).max() < 1e-12 and (n == 0).all() and p.domain.contains(x).all()
    assert load_spec("plateau").config().sampling.interface_corner_weight > 1


def test_bracket_builtin_is_self_contained(gen):
    p = load_spec("bracket").build()
    assert p.n_interface_components == 6 and len(p.interfaces) == 6
    x, n, comp = _with_comp(p, 3000, gen)
    assert comp.bincount(minlength=6).min() > 100
    torch.testing.assert_close(n.norm(dim=-1), torch.ones(3000, dtype=F64))
    assert p.domain.contains(x).all()
    # bolt holes (components 0-3): walls with horizontal normals, top rings with normal +z
    bolt = comp < 4
    nz = n[bolt, 2]
    assert ((nz.abs() < 1e-12) | ((nz - 1).abs() < 1e-12)).all()
    # pin holes (4, 5): normals perpendicular to the (tilted) y axis
    axis = torch.tensor([-0.030352, 0.999539, 0.0], dtype=F64)
    assert ((n[~bolt] @ axis).abs() < 1e-5).all()



def _pin_frame(pin):
    """Centre, unit axis and two unit radial directions of a clevis pin interface (float64)."""
    a = pin.axis.to(F64)
    u = torch.linalg.cross(a, torch.tensor([0.0, 0.0, 1.0], dtype=F64))
    u = u / u.norm()
    return pin.center.to(F64), a, u, torch.linalg.cross(a, u)


@pytest.mark.parametrize("k", [4, 5])
def test_bracket_clevis_lug_faces_are_perpendicular_to_the_pin_axis(k):
    """Each lug is 2 x 0.0423 thick along the pin axis, centred on the pin hole (the real envelope's
    faces, measured from 411_for_envelope.obj), so the pin interface (half length 0.035235) ends
    7.1e-3 inside both lug faces all round the hole: room for the surface to turn the corner.
    (Lugs extruded along y, off centre, let the interface reach past a face.)"""
    p = load_spec("bracket").build()
    c, a, u, w = _pin_frame(p.interfaces[k])
    th = torch.linspace(0, 2 * torch.pi, 37, dtype=F64)[:-1]
    for r in (0.11, 0.15, 0.19):
        ring = r * (torch.cos(th)[:, None] * u + torch.sin(th)[:, None] * w)
        for side in (1.0, -1.0):
            for t, inside in ((0.0353, True), (0.0418, True), (0.0428, False), (0.05, False)):
                q = c + side * t * a + ring
                assert (p.design_region.contains(q) == inside).all(), (r, side, t)
            # exact SDF on the face plane near the hole: zero up to rounding
            sd = p.design_region.sdf(c + side * 0.0423 * a + ring)
            assert sd.abs().max().item() < 1e-6
    # and the interface ends where the real one does: 0.035235 from the centre along the axis
    x, _, comp = _with_comp(p, 20000, torch.Generator().manual_seed(3))
    t = (x[comp == k] - c) @ a
    assert t.abs().max().item() == pytest.approx(0.035235, abs=2e-4)


def _with_comp(p, n, gen):
    from ginn.geometry import sample_interfaces_with_components

    return sample_interfaces_with_components(p.interfaces, n, gen, dtype=F64)


def test_user_example_plate_loads_builds_and_samples(gen):
    spec = load_spec(REPO / "docs" / "examples" / "plate.yaml")
    assert spec.name == "plate" and spec.config("quick").training.iterations == 200
    p = spec.build()
    assert p.n_interface_components == 3 and len(p.obstacles) == 2
    xi = sample_inside(p.design_region, p.domain, 1000, gen, dtype=F64)
    xo = sample_outside(p.design_region, p.domain, 1000, gen, dtype=F64)
    assert p.design_region.contains(xi).all() and not p.design_region.contains(xo).any()
    # obstacles were removed from E
    for o in p.obstacles:
        assert not o.contains(xi).any()
    x, n = sample_interfaces(p.interfaces, 900, gen, dtype=F64)
    d = torch.stack([i.distance(x) for i in p.interfaces], -1).min(-1).values
    assert d.max() < 1e-12
    torch.testing.assert_close(n.norm(dim=-1), torch.ones(900, dtype=F64))
    b = sample_band(p.interfaces, 500, p.interface_band, gen, dtype=F64, box=p.domain)
    assert b.shape == (500, 2)
    # the tilted slot: its centre is an obstacle point, a point 0.1 along its short axis is not
    th = math.radians(20)
    c = torch.tensor([[-0.4, -0.25]], dtype=F64)
    off = torch.tensor([[math.cos(th), math.sin(th)]], dtype=F64) * 0.06
    assert p.obstacles[1].contains(c).item() and not p.obstacles[1].contains(c + off).item()


def test_preset_and_override_errors():
    s = load_spec("obstacle")
    with pytest.raises(ConfigError, match="unknown preset"):
        s.config("nope")
    assert s.config(None, {"training": {"iterations": 7}}).training.iterations == 7
    with pytest.raises(SpecError, match="unknown problem"):
        load_spec("no-such-problem")


# --- malformed specs -------------------------------------------------------------------------------

GOOD_2D = """
name: t
kind: shape
geometry:
  dim: 2
  domain: {lo: [-1.0, -0.5], hi: [1.0, 0.5]}
  design_region:
    type: difference
    children:
      - {type: rectangle, lo: [-0.9, -0.4], hi: [0.9, 0.4]}
      - {type: disk, center: [0.0, 0.0], radius: 0.1}
  interfaces:
    - {type: segment, a: [-0.9, -0.4], b: [-0.9, 0.4], normal: [-1.0, 0.0]}
    - {type: circle, center: [0.5, 0.0], radius: 0.1}
  obstacles:
    - {type: disk, center: [0.0, 0.0], radius: 0.1}
"""


def _fail(text: str, where: str, base_dir=None) -> str:
    with pytest.raises(SpecError) as ei:
        parse_spec(textwrap.dedent(text), base_dir=base_dir, source="t.yaml").build()
    msg = str(ei.value)
    assert "\n" not in msg, msg
    assert where in msg, msg
    return msg


def test_good_spec_is_good():
    p = parse_spec(GOOD_2D).build()
    assert p.n_interface_components == 2


MALFORMED = [
    # (description, replace-this, with-this, expected text in the message)
    ("missing field", "  domain: {lo: [-1.0, -0.5], hi: [1.0, 0.5]}\n", "", "'geometry.domain': required field is missing"),
    ("negative radius", "{type: circle, center: [0.5, 0.0], radius: 0.1}", "{type: circle, center: [0.5, 0.0], radius: -0.1}",
     "spec field 'geometry.interfaces[1].radius': must be > 0"),
    ("empty CSG", "    type: difference\n    children:\n      - {type: rectangle, lo: [-0.9, -0.4], hi: [0.9, 0.4]}\n      - {type: disk, center: [0.0, 0.0], radius: 0.1}\n",
     "    type: union\n    children: []\n", "'geometry.design_region.children'"),
    ("unknown primitive", "{type: rectangle, lo: [-0.9, -0.4], hi: [0.9, 0.4]}", "{type: hexagon, lo: [-0.9, -0.4], hi: [0.9, 0.4]}",
     "'geometry.design_region.children[0]': unknown type 'hexagon'"),
    ("nan", "radius: 0.1}\n  obstacles", "radius: .nan}\n  obstacles", "'geometry.interfaces[1].radius': must be a finite number"),
    ("inf", "hi: [1.0, 0.5]}", "hi: [.inf, 0.5]}", "'geometry.domain.hi[0]': must be a finite number"),
    ("interface outside the domain", "{type: segment, a: [-0.9, -0.4], b: [-0.9, 0.4]", "{type: segment, a: [-0.9, -0.4], b: [-0.9, 0.7]",
     "'geometry.interfaces[0]': lies outside the domain"),
    ("bound lo >= hi", "domain: {lo: [-1.0, -0.5], hi: [1.0, 0.5]}", "domain: {lo: [-1.0, 0.5], hi: [1.0, 0.5]}",
     "'geometry.domain': lo[1] = 0.5 must be below hi[1] = 0.5"),
    ("wrong point dimension", "  obstacles:\n    - {type: disk, center: [0.0, 0.0]", "  obstacles:\n    - {type: disk, center: [0.0, 0.0, 0.0]",
     "'geometry.obstacles[0].center': must have 2 coordinates"),
    ("3D primitive in 2D", "{type: disk, center: [0.0, 0.0], radius: 0.1}\n  interfaces", "{type: sphere, center: [0.0, 0.0], radius: 0.1}\n  interfaces",
     "'geometry.design_region.children[1]': type 'sphere' needs a 3D geometry"),
    ("difference of one child", "      - {type: disk, center: [0.0, 0.0], radius: 0.1}\n  interfaces", "  interfaces",
     "'geometry.design_region.children': needs at least 2 children"),
    ("zero normal", "normal: [-1.0, 0.0]", "normal: [0.0, 0.0]", "'geometry.interfaces[0].normal': must be a non-zero vector"),
    ("unknown key", "kind: shape\n", "kind: shape\ncolour: red\n", "spec field 'colour': unknown key"),
    ("unknown kind", "kind: shape\n", "kind: volume\n", "spec field 'kind': must be"),
    ("bad dim", "  dim: 2\n", "  dim: 4\n", "'geometry.dim'"),
    ("wrong type of value", "radius: 0.1}\n  obstacles", "radius: big}\n  obstacles", "'geometry.interfaces[1].radius': must be a number"),
    ("bad defaults", "kind: shape\n", "kind: shape\ndefaults: {model: {hidden: []}}\n", "spec field 'defaults.model.hidden'"),
    ("bad preset", "kind: shape\n", "kind: shape\npresets: {fast: {training: {lr: -1}}}\n", "spec field 'presets.fast.training.lr'"),
    ("unknown config key", "kind: shape\n", "kind: shape\ndefaults: {trainig: {}}\n", "spec field 'defaults.trainig': unknown key"),
    ("shape without geometry", None, "name: t\nkind: shape\n", "'geometry'"),
]


@pytest.mark.parametrize("desc,old,new,expected", MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_spec_one_line_error(desc, old, new, expected):
    if old is None:
        text = new
    else:
        assert old in GOOD_2D, desc
        text = GOOD_2D.replace(old, new, 1)
    _fail(text, expected)


def test_yaml_syntax_error():
    msg = _fail("name: t\ngeometry: {dim: 2\n  domain: [\n", "YAML syntax error at line")
    assert "t.yaml" in msg


def test_top_level_not_a_mapping():
    _fail("- a\n- b\n", "top level must be a mapping")


MESH_SPEC = """
name: m
geometry:
  dim: 3
  domain: {lo: [-1, -1, -1], hi: [1, 1, 1]}
  design_region: {type: mesh, path: PATH}
"""


def test_mesh_path_missing(tmp_path):
    _fail(MESH_SPEC.replace("PATH", "nothing.stl"), "'geometry.design_region.path': mesh file not found", base_dir=tmp_path)


def test_file_that_is_not_a_mesh(tmp_path):
    (tmp_path / "notes.stl").write_text("hello, I am not a mesh\n")
    _fail(MESH_SPEC.replace("PATH", "notes.stl"), "'geometry.design_region.path'", base_dir=tmp_path)
    (tmp_path / "empty.obj").write_text("# nothing\n")
    _fail(MESH_SPEC.replace("PATH", "empty.obj"), "'geometry.design_region.path'", base_dir=tmp_path)


def test_non_watertight_mesh_region(tmp_path):
    m = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    open_box = trimesh.Trimesh(vertices=m.vertices, faces=m.faces[:-2])
    open_box.export(tmp_path / "open.stl")
    _fail(MESH_SPEC.replace("PATH", "open.stl"), "'geometry.design_region': mesh is not watertight", base_dir=tmp_path)


def test_relative_mesh_paths_resolve_against_the_spec_file(tmp_path, gen):
    sub = tmp_path / "meshes"
    sub.mkdir()
    trimesh.creation.icosphere(subdivisions=2, radius=0.5).export(sub / "ball.stl")
    m = trimesh.creation.box(extents=[0.2, 0.2, 0.2])
    m.export(sub / "pad.stl")
    spec_file = tmp_path / "spec.yaml"
    spec_file.write_text(textwrap.dedent("""
        name: meshy
        geometry:
          dim: 3
          domain: {lo: [-1, -1, -1], hi: [1, 1, 1]}
          design_region: {type: mesh, path: meshes/ball.stl}
          interfaces:
            - {type: mesh, path: meshes/pad.stl, normals: flipped}
        """))
    p = load_spec(spec_file).build()
    x = sample_inside(p.design_region, p.domain, 200, gen, dtype=F64)
    assert (x.norm(dim=-1) <= 0.5 + 1e-9).all()
    xs, n = sample_interfaces(p.interfaces, 100, gen, dtype=F64)
    assert (xs.abs().max(-1).values - 0.1).abs().max() < 1e-7  # STL stores float32
    # flipped normals point into the pad
    assert ((xs * n).sum(-1) < 0).all()


def test_docs_embed_the_example_verbatim():
    """docs/problem-spec.md shows docs/examples/plate.yaml (minus its leading comment) verbatim."""
    doc = (REPO / "docs" / "problem-spec.md").read_text()
    example = (REPO / "docs" / "examples" / "plate.yaml").read_text()
    body = "".join(line for line in example.splitlines(keepends=True) if not line.startswith("# A user-defined") and not line.startswith("# on a bottom edge"))
    assert body.strip() in doc


def test_nested_error_paths():
    text = """
    name: g
    geometry:
      dim: 3
      domain: {lo: [-1, -1, -1], hi: [1, 1, 1]}
      interfaces:
        - type: group
          parts:
            - {type: annulus, center: [0, 0, 0], normal: [0, 0, 1], r_inner: 0.1, r_outer: 0.2}
            - {type: polyline, points: [[0, 0, 0], [0, 0, 0]]}
    """
    _fail(text, "spec field 'geometry.interfaces[0].parts[1]': polyline has a zero-length segment")
    _fail(text.replace("r_inner: 0.1", "r_inner: 0.3"), "spec field 'geometry.interfaces[0].parts[0]': r_inner = 0.3 must be below r_outer = 0.2")


def test_preset_extends(tmp_path):
    """``extends`` layers a preset on another (outermost first); an unknown or cyclic one is one
    line naming the field."""
    base = {"name": "ext", "geometry": {"dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
                                        "interfaces": [{"type": "segment", "a": [-0.5, 0], "b": [0.5, 0]}]}}
    spec = validate_spec({**base, "presets": {
        "a": {"training": {"iterations": 7, "lr": 2e-3}},
        "b": {"extends": "a", "training": {"iterations": 9}},
        "c": {"extends": "b", "model": {"w0_first": 3.0}}}})
    cfg = spec.config("c")
    assert (cfg.training.iterations, cfg.training.lr, cfg.model.w0_first) == (9, 2e-3, 3.0)
    assert [list(layer) for layer in spec.preset_layers("c")] == [["training"], ["training"], ["model"]]
    with pytest.raises(SpecError, match=r"spec field 'presets.b.extends': unknown preset 'z'"):
        validate_spec({**base, "presets": {"b": {"extends": "z"}}})
    with pytest.raises(SpecError, match=r"spec field 'presets.a.extends': a cycle \(a -> b -> a\)"):
        validate_spec({**base, "presets": {"a": {"extends": "b"}, "b": {"extends": "a"}}})
