"""Figures: files a person can open, the right latents for the interpolation figure."""

import json

import matplotlib
import numpy as np
import torch

from _shapes import Disk, Rect, VerticalSegments
from ginn.geometry.base import Box
from ginn.problems.problem import Problem
from ginn.viz.plot import interpolation_latents, plot_loss_curves, plot_run, plot_superposition

P2 = Problem(
    "obstacle-like",
    Box((-1.0, -0.5), (1.0, 0.5)),
    design_region=Rect((-0.9, -0.4), (0.9, 0.4)),
    interfaces=(VerticalSegments([-0.9, 0.9], 0.4),),
    obstacles=(Disk((0.0, 0.0), 0.1),),
)
P3 = Problem("ball", Box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)), design_region=Rect((-0.9,) * 3, (0.9,) * 3))


def balls(x, z):
    return x.norm(dim=-1) - (0.2 + 0.3 * z[:, 0])


def is_png(p):
    return p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_loss_curve_panels_group_families_in_order():
    from ginn.viz.curves import loss_curve_panels

    records = [
        {"step": 0, "eikonal": 0.5, "total": 2.0, "interface": 1.5, "lr": 1e-3, "grad_norm": 3.0, "time": 9.0,
         "_boundary_converged": 1.0, "multipliers": {"interface": 1.0, "eikonal": 0.1}},
        {"step": 1, "eikonal": 0.4, "total": 1.0, "interface": float("nan"), "lr": 1e-3, "grad_norm": 2.0,
         "multipliers": {"interface": 2.0, "eikonal": 0.1}},
        {"event": "feasibility", "step": 2, "feasible": 0.0, "shapes": 4, "ratios": {"interface": 3.0},
         "worst": {"interface_cd1": 0.2}, "mean": {"ratios": {"interface": 1.5}}, "ok": True},
        {"step": 2, "total": 0.5},
    ]
    panels = loss_curve_panels(records)
    assert list(panels) == ["losses", "multipliers", "lr", "grad_norm", "diagnostics", "feasibility",
                            "feasibility: mean.ratios", "feasibility: ratios", "feasibility: worst"]
    assert list(panels["losses"]) == ["total", "eikonal", "interface"]  # total first, then by name
    assert panels["losses"]["total"] == ([0.0, 1.0, 2.0], [2.0, 1.0, 0.5])
    assert panels["losses"]["interface"] == ([0.0], [1.5])  # the NaN left out
    assert panels["multipliers"]["interface"] == ([0.0, 1.0], [1.0, 2.0])
    assert panels["feasibility"] == {"feasible": ([2.0], [0.0]), "shapes": ([2.0], [4.0])}  # no bool, no time
    assert panels["feasibility: mean.ratios"] == {"interface": ([2.0], [1.5])}
    assert panels["diagnostics"] == {"boundary_converged": ([0.0], [1.0])}
    assert list(loss_curve_panels(records, keys=["lr"])) == ["lr"]


def test_interpolation_latents_sorted_with_midpoints():
    Z = torch.tensor([[1.0], [0.0], [0.5]])
    lat, trained = interpolation_latents(Z)
    np.testing.assert_allclose(lat[:, 0].numpy(), [0.0, 0.25, 0.5, 0.75, 1.0])
    assert trained == [True, False, True, False, True]
    Z2 = torch.tensor([[0.0, 1.0], [1.0, 0.0]])  # k > 1: given order
    lat, trained = interpolation_latents(Z2)
    np.testing.assert_allclose(lat.numpy(), [[0, 1], [0.5, 0.5], [1, 0]])


def test_loss_curves_from_nested_jsonl(tmp_path):
    log = tmp_path / "metrics.jsonl"
    with log.open("w") as fh:
        for i in range(30):
            fh.write(json.dumps({"step": i, "loss": 1.0 / (i + 1), "terms": {"eikonal": 0.5, "interface": 2.0**-i}}) + "\n")
        fh.write(json.dumps({"step": 30, "event": "rollback", "lr_scale": 0.5}) + "\n")
        fh.write("not json\n")
    p = plot_loss_curves(log, tmp_path / "loss.png")
    assert is_png(p)


def test_plot_run_2d_files_and_superposition_pixels(tmp_path):
    Z = torch.tensor([[0.0], [0.5], [1.0]], dtype=torch.float64)
    paths = plot_run(balls, Z, P2, tmp_path, resolution=64)
    assert sorted(p.name for p in paths) == ["interpolation.png", "shapes.png", "superposition.png"]
    assert all(is_png(p) for p in paths)
    # more ink with three disks of radius >= 0.2 than with one of radius 0.05
    small = plot_superposition(balls, torch.tensor([[-0.5]], dtype=torch.float64), P2, tmp_path / "small.png", 64)
    ink = lambda p: 1.0 - matplotlib.image.imread(p)[..., :3].mean()
    assert ink(tmp_path / "superposition.png") > ink(small) + 0.02


def test_plot_run_3d_views(tmp_path):
    Z = torch.tensor([[0.0], [1.0]], dtype=torch.float64)
    paths = plot_run(balls, Z, P3, tmp_path, resolution=24, views=((20.0, 30.0), (60.0, 120.0)))
    names = sorted(p.name for p in paths)
    assert names == ["interpolation.png", "shape_000_views.png", "shape_001_views.png", "shapes.png"]
    assert all(is_png(p) for p in paths)
    # a title (the shape's verdict) puts ink above the views: compare the top strip with and without
    top = lambda p: 1.0 - matplotlib.image.imread(p)[:40, :, :3].mean()
    plot_run(balls, Z, P3, tmp_path / "t", resolution=24, views=((20.0, 30.0),), view_titles=["shape 0: feasible", ""])
    assert top(tmp_path / "t" / "shape_000_views.png") > top(tmp_path / "t" / "shape_001_views.png") + 1e-3
