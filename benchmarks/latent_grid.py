"""The verdict of a run with a latent space of two or more dimensions on an n x n grid over its first
two latent axes (the others at the centre of Z), judged as ``ginn eval`` judges any code.

    python benchmarks/latent_grid.py RUN                 # a 16 x 16 grid
    python benchmarks/latent_grid.py RUN --n 8 --threads 2

Prints the feasible share of the grid, its worst code and a map of the grid (``.`` feasible, ``x``
not; rows along the first axis from low to high), the picture the explorer's two sliders walk.
"""

from __future__ import annotations

import argparse
import sys
import time

import torch

from ginn import runs
from ginn.errors import GinnError
from ginn.models.latents import grid_latents


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--n", type=int, default=16, help="codes along each of the two axes")
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: the default)")
    args = p.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    try:
        run = runs.load_run(args.run_dir)
    except GinnError as e:
        print(e, file=sys.stderr)
        return 2
    lat = run.task.cfg.latents
    if run.task.kind != "shape" or run.task.latents() is None or lat.dim < 2:
        print(f"{args.run_dir}: not a shape run with a latent space of two or more dimensions", file=sys.stderr)
        return 2
    if not 2 <= args.n <= 256:
        print(f"--n {args.n}: must be between 2 and 256", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    Z = grid_latents(lat, args.n, run.task.device, run.task.dtype)
    summary = run.task.results.judge().latents(run.model, Z)
    ok = [not v for v in summary.violations]
    print(f"{args.run_dir}: {summary.feasible} of {summary.shapes} codes of a {args.n} x {args.n} grid over "
          f"[{lat.low:g}, {lat.high:g}]^2 feasible ({100 * summary.share:.1f} %), {time.perf_counter() - t0:.0f} s")
    worst = summary.worst_latent()
    if worst is not None and worst[2]:
        print(f"worst code ({', '.join(f'{v:.3g}' for v in worst[0])}): {', '.join(worst[2])}")
    for i in range(args.n):
        print("".join("." if ok[i * args.n + j] else "x" for j in range(args.n)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
