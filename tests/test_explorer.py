"""``ginn view``: the latent-space explorer is one self-contained HTML file with one slider position
per latent value; it renders in a real headless browser that cannot resolve any host (no network
needed), and moving the slider changes the picture."""

import base64
import json
import math
import re
import shutil
import subprocess

import numpy as np
import pytest
import torch

from ginn import runs
from ginn.viz.explorer import explorer_latents

TINY = ["latents.n_shapes=4", "model.hidden=[16,16]", "sampling.n_domain=128", "sampling.n_outside=64",
        "sampling.n_interface=32", "sampling.n_boundary=32", "training.threads=1", "training.feasibility_checks=0"]


@pytest.fixture(scope="module")
def run_2d(tmp_path_factory):
    out = tmp_path_factory.mktemp("view") / "run"
    spec, cfg = runs.resolve("obstacle", "demo", {"training": {"iterations": 30}}, sets=TINY)
    runs.train(spec, cfg, out, progress=False, results=False)
    return out


def test_latents_of_the_slider():
    lat = explorer_latents(torch.tensor([[1.0], [-1.0], [0.0]]), 5)
    np.testing.assert_allclose([float(z) for z in lat.codes], [-1, -0.5, 0, 0.5, 1])  # the ends coincide
    assert lat.trained == [True, False, True, False, True] and lat.grid is None
    assert lat.labels[0] == "-1 trained" and lat.labels[1] == "-0.5"
    assert explorer_latents(None, 64).codes == [None]
    # 2D latents: a 3 x 3 grid over the plane of three trained codes, whose corners hold them
    Z = torch.tensor([[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [0.0, 2.0, 1.0]])
    lat = explorer_latents(Z, 9)
    assert lat.grid == (3, 3) and len(lat.codes) == 9
    C = torch.stack(lat.codes)
    np.testing.assert_allclose(C[:, 2].numpy(), 1.0, atol=1e-12)  # in the plane z_2 = 1
    for z in Z.double():  # every trained code lies within the grid's span
        d = (C - z).norm(dim=1).min()
        assert float(d) < 1.5


def test_html_has_a_frame_per_latent_and_fetches_nothing(run_2d, tmp_path):
    path = runs.view(run_2d, tmp_path / "e.html", steps=6)
    html = path.read_text()
    # 4 trained latents (-1, -1/3, 1/3, 1) and 6 even ones (-1, -0.6, ..., 1): 8 positions
    assert html.count('"method":"animate"') == 8
    assert len(re.findall(r'"name":"\d+","traces":\[0\]', html)) == 8
    assert html.count("trained") >= 4 and "all 4 trained shapes" in html
    assert "feasible" in html or "interface" in html  # the verdict beside the picture
    assert not re.search(r"<script[^>]+src=|<link[^>]+href=", html)  # plotly.js is embedded
    assert 'id="explorer"' in html and 'id="extra0"' in html  # the superposition below
    data, layout = _figure(html)
    assert [t["name"] for t in data][:2] == ["shape", "obstacle"] and len(layout["sliders"][0]["steps"]) == 8


@pytest.mark.long
def test_single_3d_shape_has_one_frame_and_the_envelope(tmp_path):
    spec, cfg = runs.resolve("bracket", "demo", {"training": {"iterations": 2}},
                             sets=["model.hidden=[16,16]", "sampling.n_domain=256", "sampling.n_outside=128",
                                   "sampling.n_interface=128", "sampling.n_band=128", "sampling.n_boundary=64",
                                   "training.threads=1", "training.feasibility_checks=0"])
    runs.train(spec, cfg, tmp_path / "b", progress=False, results=False)
    html = runs.view(tmp_path / "b", steps=64).read_text()
    data, layout = _figure(html)
    assert [t["type"] for t in data] == ["mesh3d", "mesh3d", "scatter3d"]  # shape, design region, interfaces
    assert [t["name"] for t in data] == ["shape", "design region", "interfaces"]
    assert "sliders" not in layout and data[1]["opacity"] < 0.5


def _figure(html: str) -> tuple[list, dict]:
    """The data and layout of the explorer's plotly figure, decoded from the page."""
    start = html.index('Plotly.newPlot(') + len('Plotly.newPlot(')
    text = html[html.index("[", start):]
    dec = json.JSONDecoder()
    data, end = dec.raw_decode(text)
    layout, _ = dec.raw_decode(text[text.index("{", end):])
    return data, layout


def _browser() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")


def _shot(browser: str, url: str, out) -> np.ndarray:
    import matplotlib.image as mpimg

    # every host name resolves to nothing: a page that needed the network would not draw
    r = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        "--host-resolver-rules=MAP * ~NOTFOUND", "--window-size=1000,700",
                        "--virtual-time-budget=5000", f"--screenshot={out}", url],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and out.exists(), r.stderr[-1000:]
    return np.asarray(mpimg.imread(str(out)))[..., :3]


@pytest.mark.long
def test_renders_in_a_browser_and_the_slider_changes_the_picture(run_2d, tmp_path):
    browser = _browser()
    if browser is None:
        pytest.skip("no headless browser: install chromium (the Debian package; .ci/run installs it when it can)")
    path = runs.view(run_2d, tmp_path / "e.html", steps=6)
    first = _shot(browser, path.as_uri() + "#step=0", tmp_path / "a.png")
    last = _shot(browser, path.as_uri() + "#step=7", tmp_path / "b.png")
    assert first.std() > 0.05 and last.std() > 0.05  # not blank
    assert np.abs(first - last).mean() > 2e-3  # another shape, another verdict


def test_views_of_the_gray_scott_patterns_and_the_mirror(tmp_path):
    """Gray-Scott: a heatmap of v per slider position with the relative residual and std(v) of that
    pattern; the mirror: its profile against x^2 / 4F with the largest deviation."""
    from ginn.tasks.gray_scott.checks import sample_fields
    from ginn.tasks.gray_scott.solver import relative_residual

    spec, cfg = runs.resolve("gray-scott", "quick", {"training": {"iterations": 2}},
                             sets=["training.threads=1", "latents.n_shapes=2"])
    out = runs.train(spec, cfg, tmp_path / "gs", progress=False, results=False)
    html = runs.view(tmp_path / "gs", steps=3).read_text()
    data, layout = _figure(html)
    assert data[0]["type"] == "heatmap"
    run = runs.load_run(tmp_path / "gs")
    lat = explorer_latents(run.task.Z, 3)
    assert len(layout["sliders"][0]["steps"]) == len(lat.codes)
    W = sample_fields(run.model, lat.codes[0].reshape(1, -1), 96)[0]
    rel = relative_residual(W[0], W[1], run.task.params.gs)["rel"]
    assert f"residual {rel:.3g}" in layout["annotations"][0]["text"]
    assert out.status == "completed"
    spec, cfg = runs.resolve("mirror", "demo", {"training": {"iterations": 3}}, sets=["training.threads=1"])
    runs.train(spec, cfg, tmp_path / "m", progress=False, results=False)
    data, layout = _figure(runs.view(tmp_path / "m").read_text())
    assert [t["name"] for t in data] == ["GINN mirror", "exact x^2 / 4F", "focus"]
    assert "max |h - exact|" in layout["annotations"][0]["text"] and "sliders" not in layout


def test_plateau_view_shows_the_reference_surface(tmp_path):
    spec, cfg = runs.resolve("plateau", "demo", {"training": {"iterations": 2}},
                             sets=["model.hidden=[16,16]", "sampling.n_domain=256", "sampling.n_boundary=64",
                                   "training.threads=1"])
    runs.train(spec, cfg, tmp_path / "p", progress=False, results=False)
    data, _ = _figure(runs.view(tmp_path / "p").read_text())
    ref = [t for t in data if t["name"] == "reference minimal surface"]
    assert len(ref) == 1 and ref[0]["type"] == "mesh3d" and ref[0]["opacity"] < 1


def test_a_problem_with_manufacturing_tolerances_marks_them_in_every_frame(tmp_path):
    """A field whose shape is a thin bar (0.04 thick) under a min_thickness of 0.1: each frame
    carries a second trace outlining it, but for the neighbourhood of the interface's end points
    (its rims, within 0.005 + 0.05: |x| > 0.449 on the bar), as the verdict counts it; without the
    tolerance there is none."""
    from ginn.fields import as_field
    from ginn.problems import validate_spec
    from ginn.viz.explorer import write_explorer

    spec = {"name": "bar", "geometry": {"dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
            "interfaces": [{"type": "segment", "a": [-0.5, 0.0], "b": [0.5, 0.0], "normal": [0, 1]}]},
            "tolerances": {"min_thickness": 0.1}}
    field = as_field(lambda x: torch.maximum(x[:, 0].abs() - 0.5, x[:, 1].abs() - 0.02))
    html = write_explorer(field, None, validate_spec(spec).build(), tmp_path / "m.html", resolution=128).read_text()
    data, _ = _figure(html)
    marks = [t for t in data if t.get("name") == "thin, narrow or overhanging"]
    assert len(marks) == 1
    x = marks[0]["x"]  # plotly writes arrays as base64 typed arrays
    xs = np.frombuffer(base64.b64decode(x["bdata"]), dtype=x["dtype"]) if isinstance(x, dict) else np.asarray(x, float)
    xs = xs[np.isfinite(xs)]
    assert -0.47 < xs.min() < -0.43 and 0.43 < xs.max() < 0.47  # the bar less its rims, within a cell
    plain = write_explorer(field, None, validate_spec({**spec, "tolerances": {}}).build(), tmp_path / "p.html",
                           resolution=128).read_text()
    assert all(t.get("name") != "thin, narrow or overhanging" for t in _figure(plain)[0])


def test_a_3d_shape_colours_its_overhanging_faces(tmp_path):
    """A ball of radius 0.5 printed along +z at 45 degrees: the faces coded 3 (overhanging) are the
    cap below the height -0.5 sin 45, within a cell, and the others are 0."""
    from ginn.fields import as_field
    from ginn.problems import validate_spec
    from ginn.viz.explorer import write_explorer

    spec = {"name": "ball", "geometry": {"dim": 3, "domain": {"lo": [-1, -1, -1], "hi": [1, 1, 1]},
            "interfaces": [{"type": "annulus", "center": [0.9, 0.9, 0.9], "normal": [0, 0, 1], "r_inner": 0.01,
                            "r_outer": 0.02}]},
            "tolerances": {"overhang": {"angle": 45, "up": [0, 0, 1]}}}
    field = as_field(lambda x: x.norm(dim=-1) - 0.5)
    data, _ = _figure(write_explorer(field, None, validate_spec(spec).build(), tmp_path / "b.html", resolution=48).read_text())
    mesh = data[0]

    def arr(v):
        return np.frombuffer(base64.b64decode(v["bdata"]), dtype=v["dtype"]) if isinstance(v, dict) else np.asarray(v)

    code = arr(mesh["intensity"])
    z = arr(mesh["z"])[np.stack([arr(mesh[k]) for k in "ijk"], axis=1)].mean(axis=1)  # the faces' centroids' heights
    assert mesh["intensitymode"] == "cell" and set(np.unique(code)) == {0, 3}
    edge = -0.5 * math.sin(math.radians(45))
    assert z[code == 3].max() < edge + 2 / 48 and z[code == 0].min() > edge - 2 / 48


def test_a_structural_problem_shows_the_strain_energy_and_the_compliance(tmp_path):
    """The bar of tests/test_structural.py all solid: stress 1 along it (unit force over unit height),
    strain-energy density s^2 / (2 E) = 0.25 (E = 2) and compliance F^2 L / (E A) = 2, within the
    concentrations at the end nodes."""
    from ginn.fields import as_field
    from ginn.problems import validate_spec
    from ginn.viz.explorer import write_explorer

    bar = {"name": "bar", "tolerances": {"volume_fraction": {"max": 0.5}},
           "geometry": {"dim": 2, "domain": {"lo": [0, 0], "hi": [4, 1]},
                        "interfaces": [{"type": "segment", "a": [0, 0], "b": [0, 1]}, {"type": "segment", "a": [4, 0], "b": [4, 1]}]},
           "physics": {"material": {"youngs_modulus": 2.0, "poisson_ratio": 0.3},
                       "supports": [{"interface": 0, "fix": ["x"]},
                                    {"region": {"type": "rectangle", "lo": [-1, -1], "hi": [0.01, 0.01]}, "fix": ["y"]}],
                       "loads": [{"interface": 1, "force": [1.0, 0.0]}]}}
    field = as_field(lambda x: x[:, 1] - 2.0)
    html = write_explorer(field, None, validate_spec(bar).build(), tmp_path / "s.html", resolution=64).read_text()
    data, layout = _figure(html)
    heat = [t for t in data if t.get("name") == "strain-energy density"]
    assert len(heat) == 1 and heat[0]["type"] == "heatmap"
    z = heat[0]["z"]
    zs = np.frombuffer(base64.b64decode(z["bdata"]), dtype=z["dtype"]) if isinstance(z, dict) else np.asarray(z, float)
    assert zs.size == 90 * 22 and np.isfinite(zs).all()  # the default 90 x 22 grid, all solid
    assert abs(float(np.median(zs)) - np.log10(0.25)) < 0.01
    c = float(re.search(r"compliance ([0-9.]+)", layout["annotations"][0]["text"]).group(1))
    assert c == pytest.approx(2.0, rel=0.01)


def test_the_verdict_beside_the_picture_lists_every_bound_it_judges():
    """Besides CD1, the volume outside E, the pieces and the volume fraction, each other verdict of
    the problem shows how much of its bound the shape uses."""
    from ginn.problems import validate_spec
    from ginn.viz.explorer import _verdict

    spec = {"name": "bar", "geometry": {"dim": 2, "domain": {"lo": [-1, -1], "hi": [1, 1]},
            "interfaces": [{"type": "segment", "a": [-0.5, 0.0], "b": [0.5, 0.0], "normal": [0, 1]}]},
            "tolerances": {"min_thickness": {"size": 0.1, "removed": 0.02}}}
    problem = validate_spec(spec).build()
    text = _verdict({"interface_cd1": 1e-3, "b0_in_design_region": 1, "thickness_removed": 0.005}, problem)
    assert "min_thickness: 25 % of its bound" in text.split("<br>") and "CD1 1.00e-03" in text
    text = _verdict({"interface_cd1": 1e-3, "b0_in_design_region": 1, "thickness_removed": 0.03}, problem)
    assert "min_thickness: 150 % of its bound" in text.split("<br>")
    # a hole target is a count, not a share of a bound: only its violation is shown
    holes = validate_spec({**spec, "topology": {"holes": 1}}).build()
    met = {"interface_cd1": 1e-3, "b0_in_design_region": 1, "thickness_removed": 0.0, "b1_in_design_region": 1}
    assert "topology" not in _verdict(met, holes)
    assert "topology" in _verdict({**met, "b1_in_design_region": 2}, holes)


def test_the_text_beside_the_picture_is_wrapped_to_the_margin():
    """Every line fits the box's width, no word is lost or split, a bold or italic line stays so on
    each piece, and wrapping again changes nothing."""
    from ginn.viz.explorer import NOTE_WIDTH, note, wrap_note

    text = ("<b>latent 0.25</b><br>feasible<br>volume outside E off the interfaces 1.23e-03 (bound 1.00e-03)<br>"
            "<i>estimate on the picture's grid of 256 cells (ginn eval judges finer)</i>")
    wrapped = note(text)["text"]
    lines = wrapped.split("<br>")
    assert all(len(re.sub(r"</?[bi]>", "", t)) <= NOTE_WIDTH for t in lines)
    assert lines[:4] == ["<b>latent 0.25</b>", "feasible", "volume outside E off the interfaces",
                         "1.23e-03 (bound 1.00e-03)"]
    assert all(t.startswith("<i>") and t.endswith("</i>") for t in lines[4:]) and len(lines) == 6
    assert re.sub(r"</?[bi]>", "", wrapped).replace("<br>", " ").split() == \
        re.sub(r"</?[bi]>", "", text).replace("<br>", " ").split()
    assert wrap_note(wrapped) == wrapped
