"""Benchmark: every Appendix B.1 metric of one 3D shape at resolution 256 (target: <= 60 s).

The shape is a random SIREN 3 -> [256] * 3 -> 1 (w0_first small, shifted so that about 30 % of
the domain is inside), evaluated on a jet-engine-bracket-like problem: a box design region with
a cylindrical hole, and two cylindrical interfaces.

Run:  .venv/bin/python benchmarks/metrics.py [--resolution 256] [--w0 2.0] [--threads 2] [--dense]
Prints the per-stage and per-metric seconds, the number of field evaluations and the metrics.

Measured (2026-11-23, the shared 2-core machine at load average 13-14, i.e. a small fraction of
the CPU): 57.2 s in total. Adaptive sampling evaluates the network at 464k of the 17.0M nodes
(2.7 %); a dense evaluation would take about 310 s even on an idle machine (54k points/s).
Breakdown: prepare (adaptive design-region grid, dE and interface samples) 17.7 s, field sampling
21.9 s, marching cubes 1.0 s, labelling 2.5 s, b0 2.0 s, b0 in E 0.3 s, disconnected volume in
E 0.8 s, connected interfaces 0.8 s, interface CD1 7.6 s (the interfaces of a random shape are far
from it; KD-tree queries from far away are the slow case), surface strain 2.5 s, the rest < 0.2 s.
Earlier, at load 6-8: 52-59 s with the previous (wider) last refinement level.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import skimage.measure  # noqa: F401  (imported up front: the timings measure the metrics, not imports)
import torch

from ginn.eval.shapes import evaluate_shapes
from ginn.geometry.base import Box, Interface, Region
from ginn.models import Siren
from ginn.problems.problem import Problem


class BoxMinusCylinder(Region):
    """[-0.9, 0.9]^3 minus the z-cylinder of radius 0.2 through the origin."""

    dim = 3

    def sdf(self, x):
        q = x.abs() - 0.9
        box = q.clamp_min(0).norm(dim=-1) + q.max(dim=-1).values.clamp_max(0)
        cyl = 0.2 - x[:, :2].norm(dim=-1)
        return torch.maximum(box, cyl)


class Rings(Interface):
    """Circles of radius 0.15 in the planes x = +-0.6 (one component each): cylindrical bolt holes."""

    dim = 3

    def sample(self, n, generator=None, device=None, dtype=torch.float32):
        t = torch.rand(n, generator=generator, dtype=torch.float64) * 2 * math.pi
        side = torch.where(torch.arange(n) % 2 == 0, -0.6, 0.6).double()
        x = torch.stack([side, 0.15 * t.cos(), 0.15 * t.sin()], dim=1)
        nrm = torch.stack([torch.zeros_like(t), t.cos(), t.sin()], dim=1)
        return x.to(dtype), nrm.to(dtype)

    def measure(self):
        return 2 * 2 * math.pi * 0.15

    @property
    def n_components(self):
        return 2

    def component_of(self, x):
        return (x[:, 0] > 0).long()


class Counting(torch.nn.Module):
    """The SIREN minus a constant, counting the points it is evaluated at."""

    def __init__(self, net, shift):
        super().__init__()
        self.net, self.shift, self.points = net, shift, 0

    def forward(self, x, z=None):
        self.points += x.shape[0]
        return self.net(x, z) - self.shift


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--w0", type=float, default=2.0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--dense", action="store_true", help="evaluate every grid node (no adaptive sampling)")
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    torch.manual_seed(0)
    net = Siren(3, [256] * 3, w0_first=a.w0).eval()
    with torch.no_grad():
        probe = torch.rand(20000, 3, generator=torch.Generator().manual_seed(1)) * 2 - 1
        shift = float(torch.quantile(net(probe, None), 0.3))
    field = Counting(net, shift)
    problem = Problem("bench", Box((-1.0,) * 3, (1.0,) * 3), design_region=BoxMinusCylinder(), interfaces=(Rings(),))
    tm: dict = {}
    t = time.perf_counter()
    res = evaluate_shapes(field, None, problem, a.resolution, adaptive=not a.dense, timings=tm)
    total = time.perf_counter() - t
    n = a.resolution + 1
    print(f"resolution {a.resolution} ({n}^3 = {n ** 3:,} nodes), SIREN 3->[256]*3->1, w0_first {a.w0}, threads {a.threads}")
    print(f"field evaluated at {field.points:,} points ({100 * field.points / n ** 3:.1f} % of the nodes)")
    print(f"total {total:.1f} s")
    for k, v in tm.items():
        print(f"  {k:40s} {v:7.2f} s")
    print(json.dumps(res["shapes"][0], indent=1))


if __name__ == "__main__":
    main()
