"""How the shapes of a generative run lie in shape space: the chamfer distance between the reported
shapes by their index gap along Z, and the share of the set's variance on each axis of classical
(Torgerson) scaling of the distance matrix.

    python benchmarks/family_axes.py RUN

A family that runs along one direction has distances that grow in proportion to the gap and one
axis holding nearly all the variance; its end codes lie farthest from the rest (``docs/structural.md``,
"Sixteen shapes").
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import torch

from ginn import runs
from ginn.errors import GinnError
from ginn.eval.metrics import chamfer_matrix, diversity_from_matrix, extract_shape


def scaling_shares(D: np.ndarray) -> np.ndarray:
    """The share of the variance on each axis of classical scaling of a distance matrix ``(S, S)``
    -> ``(S,)``, largest first (the positive eigenvalues of the doubly centred ``-D^2 / 2``)."""
    S = D.shape[0]
    J = np.eye(S) - 1.0 / S
    ev = np.sort(np.linalg.eigvalsh(-0.5 * J @ (D**2) @ J))[::-1].clip(min=0.0)
    return ev / ev.sum()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--samples", type=int, default=2048, help="boundary samples per shape")
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: the default)")
    args = p.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    try:
        run = runs.load_run(args.run_dir)
    except GinnError as e:
        print(e, file=sys.stderr)
        return 2
    Z = run.task.latents() if run.task.kind == "shape" else None
    if Z is None or Z.shape[0] < 3:
        print(f"{args.run_dir}: not a shape run with three or more shapes", file=sys.stderr)
        return 2
    grid = run.task.checker().context.grid
    bounds = [extract_shape(run.model, Z[i], grid).boundary for i in range(Z.shape[0])]
    samples = [b.sample(args.samples, np.random.default_rng(0)) for b in bounds]
    D = np.asarray(chamfer_matrix(bounds, samples))
    S = D.shape[0]
    print(f"{S} shapes, diversity_mean {diversity_from_matrix(D):.4g}")
    gaps = [float(np.mean(np.diagonal(D, k))) for k in range(1, S)]
    print("mean distance by index gap 1..{}: {}".format(S - 1, " ".join(f"{g:.4g}" for g in gaps)))
    print("variance share of the scaling axes: {}".format(" ".join(f"{s:.3f}" for s in scaling_shares(D)[:5])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
