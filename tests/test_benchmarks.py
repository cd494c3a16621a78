"""Helpers of the benchmark scripts that a figure in docs/results.md depends on."""

import importlib.util
import json
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_seconds_per_iteration_reads_the_last_logged_iteration(tmp_path):
    ab = _load("against_commit")
    rows = [{"step": 0, "time": 0.3}, {"step": 10, "time": 1.5},
            {"step": 20, "event": "feasibility", "feasible": 3},  # events carry no clock
            {"step": 20, "time": 4.0}]
    (tmp_path / "metrics.jsonl").write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    assert ab.seconds_per_iteration(tmp_path) == 4.0 / 20
    # from the end of iteration 0 on: without what the run paid once at its start
    assert ab.seconds_per_iteration(tmp_path, after_first=True) == (4.0 - 0.3) / 20
    assert ab.seconds_per_iteration(tmp_path / "missing") is None


def test_scaling_shares_of_a_segment_a_circle_and_a_square():
    """Points on a segment: all the variance on one axis; evenly on a circle: half on each of two;
    the corners of a square: half on each of two; the shares sum to 1."""
    fa = _load("family_axes")

    def dist(P):
        return np.linalg.norm(P[:, None] - P[None], axis=-1)

    t = np.linspace(-1, 1, 16)
    seg = fa.scaling_shares(dist(np.c_[t, 2 * t, 0 * t]))
    assert abs(seg[0] - 1) < 1e-12
    a = np.linspace(0, 2 * np.pi, 17)[:-1]
    circle = fa.scaling_shares(dist(np.c_[np.cos(a), np.sin(a)]))
    assert np.allclose(circle[:3], [0.5, 0.5, 0.0], atol=1e-12)
    square = fa.scaling_shares(dist(np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])))
    assert np.allclose(square, [0.5, 0.5, 0, 0], atol=1e-12) and abs(square.sum() - 1) < 1e-12


def test_contour_mask_fills_outlines_and_leaves_holes():
    """A square with a square hole on a 20 x 20 grid of the unit box: the 100 centres in the outline
    less the 16 in the hole, whichever way each polyline runs; a disk the same elements as the
    circle's own centre test; the SIMP design's elements carried to a nested grid as ``upsample``
    does and to another grid by the element under each centre."""
    st = _load("structural")
    from ginn.physics import ElementGrid
    from ginn.problems.structural import resampled, upsample

    def square(a, b):
        return np.array([[a, a], [b, a], [b, b], [a, b], [a, a]])

    g = ElementGrid((0.0, 0.0), (1.0, 1.0), (20, 20))
    outline, hole = square(0.25, 0.75), square(0.4, 0.6)[::-1]
    m = st.contour_mask([outline, hole], g)
    assert m.sum() == 100 - 16
    assert np.array_equal(st.contour_mask([outline[::-1], hole[::-1]], g), m)
    c = g.centres
    inside = (np.abs(c - 0.5).max(axis=1) < 0.25) & ~(np.abs(c - 0.5).max(axis=1) < 0.1)
    assert np.array_equal(m, inside)
    t = np.linspace(0, 2 * np.pi, 400)
    disk = st.contour_mask([np.c_[0.5 + 0.3 * np.cos(t), 0.5 + 0.3 * np.sin(t)]], g)
    assert np.array_equal(disk, np.linalg.norm(c - 0.5, axis=1) < 0.3)  # the 400-gon is within 1e-5 of the circle

    coarse = ElementGrid((0.0, 0.0), (2.0, 1.0), (4, 2))
    values = np.arange(8) % 3 == 0
    assert np.array_equal(resampled(values, coarse, ElementGrid((0.0, 0.0), (2.0, 1.0), (8, 4))),
                          upsample(values, coarse.shape))
    other = ElementGrid((0.0, 0.0), (2.0, 1.0), (6, 3))
    ix = np.floor(other.centres[:, 0] / 0.5).astype(int) * 2 + np.floor(other.centres[:, 1] / 0.5).astype(int)
    assert np.array_equal(resampled(values, coarse, other), values[ix])
