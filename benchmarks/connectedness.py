"""Cost of the connectedness loss in the obstacle setting (one CPU thread).

16 shapes of a 2D SIREN 4x64 (``w0_first = 1``) conditioned on 16 latents in [-1, 1], domain
[-1, 1] x [-0.5, 0.5], design region [-0.9, 0.9] x [-0.4, 0.4] minus a disk of radius 0.1.

Measures (median over repeats):

* a full surface-network build (seeds, Newton, DBSCAN, classification, path tracing, penalties,
  loss);
* a warm update (re-converge the stored critical points after an optimiser step, loss);
* one training step of a stand-in loss (eikonal on 16 x 4096 points + an interface-like term,
  Adam) without and with the connectedness loss, the latter rebuilding every ``--every`` steps;
* the same for the persistent-homology loss.

The last line is the share of a training step spent in connectedness.

Usage: ``python benchmarks/connectedness.py [--every 10] [--steps 30] [--grid 16]``

``--compare two-disks,three-disks,two-spheres`` instead compares the two methods on analytic
cases: a SIREN fitted to disjoint balls, then an interface loss on their outer caps plus
``--weight`` times the connectedness loss (and a control with weight 0), reporting the steps
until b0 = 1, the time per step and the final interface RMS.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time
from dataclasses import dataclass

import torch

from ginn.config import ConnectednessConfig
from ginn.fields import evaluate
from ginn.geometry.base import Box, Region
from ginn.models import Siren
from ginn.topology import b0, make_connectedness_loss


@dataclass(frozen=True)
class Clock:
    """Wall-clock and process CPU seconds. With one thread the CPU time is the compute time even
    when other processes compete for the cores (the wall time then includes waiting)."""

    wall: float
    cpu: float

    def __sub__(self, other: Clock) -> Clock:
        return Clock(self.wall - other.wall, self.cpu - other.cpu)

    def __str__(self) -> str:
        return f"{self.cpu:.4f} s cpu ({self.wall:.4f} s wall)"


def _now() -> Clock:
    return Clock(time.perf_counter(), time.process_time())


def _median(xs: list[Clock]) -> Clock:
    return Clock(statistics.median(x.wall for x in xs), statistics.median(x.cpu for x in xs))


def _mean(xs: list[Clock]) -> Clock:
    return Clock(statistics.mean(x.wall for x in xs), statistics.mean(x.cpu for x in xs))


class _ObstacleRegion(Region):
    """[-0.9, 0.9] x [-0.4, 0.4] minus the disk of radius 0.1 (approximate SDF)."""

    dim = 2

    def sdf(self, x):
        q = x.abs() - torch.tensor([0.9, 0.4], dtype=x.dtype)
        box = q.clamp_min(0).norm(dim=-1) + q.max(dim=-1).values.clamp_max(0)
        return torch.maximum(box, 0.1 - x.norm(dim=-1))


def fit_to_blobs(model, Z, box, steps: int):
    """Fit the model (values only, Adam) to three disjoint disks per shape that move smoothly
    with the latent, so that every shape starts disconnected, as early in the obstacle training
    (Fig. 8a of the paper). Returns the fitting loss as a closure (for small perturbing steps)."""
    g = torch.Generator().manual_seed(2)
    S = Z.shape[0]
    z = Z[:, 0]
    cx = torch.tensor([-0.6, 0.0, 0.6]).expand(S, 3)
    cy = 0.2 * torch.sin(torch.pi * z[:, None] + torch.tensor([0.0, 2.0, 4.0]))
    centres = torch.stack([cx, cy], -1)  # (S, 3, 2)
    radius = 0.17 + 0.03 * z[:, None]
    lo, hi = box.tensors()

    def blob_loss():
        x = lo + (hi - lo) * torch.rand(S, 512, 2, generator=g)
        d = (x[:, :, None, :] - centres[:, None]).norm(dim=-1) - radius[:, None]
        target = d.min(dim=-1).values
        f = model(x.reshape(-1, 2), Z.repeat_interleave(512, 0))
        return ((f - target.reshape(-1)) ** 2).mean()

    opt = torch.optim.Adam(model.parameters(), lr=5e-3)
    for _ in range(steps):
        loss = blob_loss()
        opt.zero_grad()
        loss.backward()
        opt.step()
    return blob_loss


def _analytic_case(name: str):
    """Domain, centres and radius of the analytic comparison cases."""
    if name == "two-disks":
        return Box((-1.0, -1.0), (1.0, 1.0)), torch.tensor([[-0.5, 0.0], [0.5, 0.0]]), 0.25
    if name == "three-disks":
        return Box((-1.0, -1.0), (1.0, 1.0)), torch.tensor([[-0.65, 0.0], [0.0, 0.05], [0.7, 0.0]]), 0.13
    if name == "two-spheres":
        return Box((-1.0,) * 3, (1.0,) * 3), torch.tensor([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0]]), 0.25
    raise ValueError(name)


def compare(name: str, method: str, weight: float, steps: int, seed: int = 0) -> str:
    """Fit a SIREN to disjoint balls, then train interface loss + weight * connectedness until
    b0 = 1 (checked on a grid after every step). Returns one line of results."""
    box, C, R = _analytic_case(name)
    d = C.shape[1]
    torch.manual_seed(seed)

    def target(x):
        return ((x[:, None, :] - C[None]).norm(dim=-1) - R).min(dim=1).values

    model = Siren(d, [32] * 3 if d == 2 else [64] * 3, w0_first=6.0)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    sched = torch.optim.lr_scheduler.StepLR(opt, 400, 0.3)
    g = torch.Generator().manual_seed(seed)
    for _ in range(1200):
        x = torch.rand(2048, d, generator=g) * 2 - 1
        loss = ((model(x) - target(x)) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
    res = 128 if d == 2 else 48
    b_start = int(b0(model, None, box, res)[0])
    # interface: boundary points facing away from the centroid (the outer caps)
    u = torch.randn(4000, d, generator=g)
    u = u / u.norm(dim=1, keepdim=True)
    pts = (C[:, None, :] + R * u[None]).reshape(-1, d)
    away = ((pts - C.mean(0)) * u.repeat(C.shape[0], 1)).sum(1) > 0.3 * R
    xi = pts[away & (target(pts).abs() < 1e-6)][:512]
    grid = (16 if d == 2 else 10) if method == "surface-network" else (64 if d == 2 else 32)
    conn = make_connectedness_loss(box, None, ConnectednessConfig(method=method, every=10, grid=grid))
    opt = torch.optim.Adam(model.parameters(), lr=1e-4)
    t_conn = t_all = 0.0
    hit = None
    i = 0
    for i in range(steps):
        t = time.process_time()
        lc = conn(model, None)
        t_conn += time.process_time() - t
        loss = (model(xi) ** 2).mean() + weight * lc
        opt.zero_grad()
        loss.backward()
        opt.step()
        t_all += time.process_time() - t
        if int(b0(model, None, box, res)[0]) == 1:
            hit = i + 1
            break
    n = i + 1
    rms = (model(xi) ** 2).mean().sqrt().item()
    return (
        f"{name:12s} {method:20s} w={weight:<4} b0 {b_start}->{int(b0(model, None, box, res)[0])} "
        f"steps to b0=1: {hit} | connectedness {1000 * t_conn / n:.1f} ms/step, step {1000 * t_all / n:.1f} ms (cpu) "
        f"| interface RMS {rms:.4f}"
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--grid", type=int, default=16)
    ap.add_argument("--ph-grid", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--fit-steps", type=int, default=400, help="pre-fit to disjoint disks (0: initial SIREN)")
    ap.add_argument("--compare", default="", help="comma-separated analytic cases (two-disks,three-disks,"
                    "two-spheres): compare the two methods instead of timing the obstacle setting")
    ap.add_argument("--weight", type=float, default=0.1)
    args = ap.parse_args()
    torch.set_num_threads(1)
    if args.compare:
        for name in args.compare.split(","):
            for method, w in (("surface-network", 0.0), ("surface-network", args.weight), ("persistent-homology", args.weight)):
                print(compare(name, method, w, 300), flush=True)
        return
    t0 = time.perf_counter()
    torch.manual_seed(0)
    box = Box((-1.0, -0.5), (1.0, 0.5))
    region = _ObstacleRegion()
    model = Siren(2, [64] * 4, latent_dim=1, w0_first=1.0)
    S = 16
    Z = torch.linspace(-1, 1, S)[:, None]
    blob_loss = fit_to_blobs(model, Z, box, args.fit_steps)
    fitted = copy.deepcopy(model.state_dict())
    print(f"set-up {time.perf_counter() - t0:.1f} s; b0 (grid 128, in E) per shape: {b0(model, Z, box, 128, region).tolist()}")
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    gen = torch.Generator().manual_seed(1)
    n_dom, n_if = 4096, 256

    def base_loss() -> torch.Tensor:
        lo, hi = box.tensors()
        x = lo + (hi - lo) * torch.rand(S * n_dom, 2, generator=gen)
        z = Z.repeat_interleave(n_dom, 0)
        v = evaluate(model, x, z, grad=True, create_graph=True)
        eik = ((v.grad.norm(dim=-1) - 1) ** 2).mean()
        y = -0.4 + 0.8 * torch.rand(S * n_if, 1, generator=gen)
        xi = torch.cat([torch.where(torch.rand(S * n_if, 1, generator=gen) < 0.5, -0.9, 0.9), y], dim=1)
        fi = model(xi, Z.repeat_interleave(n_if, 0))
        return eik + (fi**2).mean()

    def step(conn=None) -> tuple[Clock, Clock, dict]:
        t0 = _now()
        opt.zero_grad()
        loss = base_loss()
        tc = Clock(0.0, 0.0)
        info: dict = {}
        if conn is not None:
            t1 = _now()
            lc = conn(model, Z)
            tc = _now() - t1
            info = conn.last_info
            loss = loss + 1e-2 * lc
        loss.backward()
        opt.step()
        return _now() - t0, tc, info

    cfg = ConnectednessConfig(method="surface-network", every=10**9, grid=args.grid)
    # full builds on the initial model (fresh object each time)
    full = []
    for _ in range(args.repeats):
        conn = make_connectedness_loss(box, region, cfg)
        t = _now()
        conn(model, Z)
        full.append(_now() - t)
    info = conn.last_info
    print(
        f"full build: {_median(full)} (median of {args.repeats}); "
        f"critical points {info['n_critical']} (min {info['n_minima']}, saddles {info['n_saddles']}, "
        f"max {info['n_maxima']}), paths {info['n_paths']}, edges {info['n_edges']}, "
        f"components per shape {info['n_components']}"
    )
    # warm updates, each after an Adam step (lr 1e-4) on the fitting loss, so the topology stays
    conn = make_connectedness_loss(box, region, cfg)
    conn(model, Z)
    small = torch.optim.Adam(model.parameters(), lr=1e-4)
    warm, kinds, pen = [], [], []
    for _ in range(args.steps):
        small.zero_grad()
        blob_loss().backward()
        small.step()
        t = _now()
        conn(model, Z)
        warm.append(_now() - t)
        kinds.append(conn.last_info["update"])
        pen.append(conn.last_info["n_penalised"])
    ok = [w for w, k in zip(warm, kinds) if k == "warm"]
    print(
        f"warm update: {_median(ok) if ok else 'n/a'} (median of {len(ok)} warm, "
        f"{statistics.median(pen):.0f} penalised saddles; {len(kinds) - len(ok)} of {len(kinds)} fell back "
        "to a full build of some shapes)"
    )
    # training steps, each phase from the fitted (disconnected) state with a fresh optimiser

    def reset():
        nonlocal opt
        model.load_state_dict(fitted)
        opt = torch.optim.Adam(model.parameters(), lr=1e-3)

    reset()
    plain = [step()[0] for _ in range(args.steps)]
    print(f"step without connectedness: {_mean(plain)} mean")
    results = {}
    for method, grid in (("surface-network", args.grid), ("persistent-homology", args.ph_grid)):
        c = ConnectednessConfig(method=method, every=args.every, grid=grid)
        conn = make_connectedness_loss(box, region, c)
        reset()
        tot, tcs, fulls = [], [], 0
        for _ in range(args.steps):
            ts, tc, inf = step(conn)
            tot.append(ts)
            tcs.append(tc)
            fulls += inf.get("update") != "warm"
        results[method] = (_mean(tot), _mean(tcs))
        print(
            f"step with {method} (every={args.every if method == 'surface-network' else 1}, grid={grid}): "
            f"{_mean(tot)} mean, of which connectedness {_mean(tcs)} mean "
            f"({fulls} full builds in {args.steps} steps), components now {conn.last_info['n_components']}"
        )
    tot, tc = results["persistent-homology"]
    print(f"persistent-homology share of a step: {100 * tc.cpu / tot.cpu:.1f}% cpu ({100 * tc.wall / tot.wall:.1f}% wall)")
    tot, tc = results["surface-network"]
    print(
        f"surface-network connectedness share of a training step: {100 * tc.cpu / tot.cpu:.1f}% cpu "
        f"({100 * tc.wall / tot.wall:.1f}% wall)"
    )


if __name__ == "__main__":
    main()
