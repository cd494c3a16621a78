"""Derivative engine vs. a torch.func baseline at equal work.

Work per step (SIREN 3 -> 4x256 -> 1, float32): value and gradient at N points, the Hessian at M
of them, a loss of all three (eikonal + value^2 + squared divergence of the normal), backward to
the weights, one Adam step.

* engine: ginn.fields.evaluate: value and gradient at the N - M other points by the SIREN's
  hand-written pass (ginn.models.siren_grad, in cache-sized blocks), f, grad f and the Hessian at
  the M points by eager autograd (one forward, 1 + d reverse passes).
* engine without the fast path (fast=False): autograd at every point (printed for comparison).
* baseline: torch.func as the authors' code does: vmap(jacrev(f)) for gradients at N points and
  vmap(jacrev(jacrev(f))) for Hessians at M points (values from a plain forward pass), on the
  same weights but with the SIREN's sine swapped for plain ``torch.sin`` (what the authors' code
  uses; our custom sine is an engine-side optimisation and would only slow vmap down).

* with ``--compile``: the engine with the SIREN's value-and-gradient pass and its backward as
  torch.compile kernels (``ginn.models.compile_derivatives``), timed in the same turns; the
  compiling happens before the timing.

The last line prints the speed ratio and the engine's achieved GFLOP/s (matmul FLOPs counted by
the torch profiler) as a share of this machine's measured float32 matmul peak.

Usage: python benchmarks/derivatives.py [--points 20000] [--hessian-points 2000] [--repeats 5]
       [--width 256] [--dim 3] [--compile]
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import time

import torch
from torch.func import functional_call, jacrev, vmap
from torch.profiler import ProfilerActivity, profile

from ginn import fields
from ginn.models import Siren, compile_derivatives
from ginn.models import siren as siren_module


def matmul_peak(n: int = 2048, repeats: int = 5) -> float:
    a, b = torch.randn(n, n), torch.randn(n, n)
    a @ b
    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        a @ b
        best = min(best, time.perf_counter() - t)
    return 2 * n**3 / best / 1e9


@contextlib.contextmanager
def plain_sine():
    """Run SIRENs with ``torch.sin`` instead of the engine's saved-sin/cos sine."""
    saved = siren_module.sine
    siren_module.sine = torch.sin
    try:
        yield
    finally:
        siren_module.sine = saved


def engine_loss(model, x, hidx, fast=True):
    v = fields.evaluate(model, x, None, grad=True, hessian_at=hidx, create_graph=True, fast=fast)
    div = fields.divergence_of_normal(v.hessian_grad, v.hessian)
    return (v.grad.norm(dim=-1) - 1).pow(2).mean() + v.f.pow(2).mean() + div.pow(2).mean()


def engine_compiled_loss(model, x, hidx):
    compile_derivatives(model, True)
    try:
        return engine_loss(model, x, hidx)
    finally:
        compile_derivatives(model, False)


def engine_autograd_loss(model, x, hidx):
    return engine_loss(model, x, hidx, fast=False)


def baseline_loss(model, x, hidx):
    params = dict(model.named_parameters())

    def f_single(p):
        return functional_call(model, params, (p[None, :],))[0]

    f = model(x)
    g = vmap(jacrev(f_single))(x)
    H = vmap(jacrev(jacrev(f_single)))(x[hidx])
    gh = g[hidx]
    div = fields.divergence_of_normal(gh, H)
    return (g.norm(dim=-1) - 1).pow(2).mean() + f.pow(2).mean() + div.pow(2).mean()


def time_steps(loss_fns, model, x, hidx, repeats):
    """Median seconds per optimisation step of each loss function; the functions take turns
    step by step, so that a change in the machine's speed during the run hits all alike."""
    opt = torch.optim.Adam(model.parameters(), lr=1e-4)
    times = [[] for _ in loss_fns]
    for i in range(repeats + 1):
        for k, loss_fn in enumerate(loss_fns):
            t = time.perf_counter()
            opt.zero_grad()
            loss = loss_fn(model, x, hidx)
            loss.backward()  # the compiled backward runs here: its kernels were chosen in the forward
            opt.step()
            if i > 0:  # the first round warms up
                times[k].append(time.perf_counter() - t)
    return [statistics.median(ts) for ts in times]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=20000)
    ap.add_argument("--hessian-points", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--width", type=int, default=256, help="SIREN width (4 hidden layers)")
    ap.add_argument("--dim", type=int, default=3, help="point dimension")
    ap.add_argument("--compile", action="store_true", help="also time the engine with compiled SIREN kernels")
    a = ap.parse_args()
    if a.threads:
        torch.set_num_threads(a.threads)
    torch.manual_seed(0)
    model = Siren(a.dim, [a.width] * 4, w0_first=8.0)
    x = torch.rand(a.points, a.dim) * 2 - 1
    hidx = torch.randperm(a.points)[: a.hessian_points]

    # same numbers from both (sanity)
    le = engine_loss(model, x[:500], torch.arange(100))
    with plain_sine():
        lb = baseline_loss(model, x[:500], torch.arange(100))
    assert torch.allclose(le, lb, rtol=1e-4), (float(le), float(lb))

    peak = matmul_peak()
    with profile(activities=[ProfilerActivity.CPU], with_flops=True) as prof:
        loss = engine_loss(model, x, hidx)
        loss.backward()
    flops = sum(e.flops for e in prof.key_averages() if e.flops)
    model.zero_grad()

    def baseline_plain_sine(model, x, hidx):
        with plain_sine():
            return baseline_loss(model, x, hidx)

    fns = [engine_loss, engine_autograd_loss, baseline_plain_sine]
    if a.compile:
        engine_compiled_loss(model, x, hidx).backward()  # compile before timing
        model.zero_grad()
        fns.append(engine_compiled_loss)
    t_engine, t_autograd, t_base, *t_compiled = time_steps(fns, model, x, hidx, a.repeats)
    gflops = flops / t_engine / 1e9
    print(f"threads: {torch.get_num_threads()}  matmul peak: {peak:.1f} GFLOP/s")
    print(f"engine   : {t_engine:.3f} s/step  ({flops / 1e9:.1f} GFLOP counted, {gflops:.1f} GFLOP/s)")
    print(f"engine without the SIREN fast path (autograd only): {t_autograd:.3f} s/step")
    print(f"torch.func baseline: {t_base:.3f} s/step")
    print(f"speedup engine vs torch.func: {t_base / t_engine:.2f}x; "
          f"engine at {gflops:.1f} GFLOP/s = {100 * gflops / peak:.0f}% of measured matmul peak")
    if t_compiled:
        print(f"engine with compiled SIREN kernels: {t_compiled[0]:.3f} s/step, "
              f"{t_compiled[0] / t_engine:.2f} of the eager engine's")


if __name__ == "__main__":
    main()
