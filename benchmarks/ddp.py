"""Benchmark: iterations per second of the generative obstacle problem with 1 and 2 gloo ranks.

One process trains all S shapes; two processes (gloo, 127.0.0.1) each train S/2 shapes, average
losses and gradients and gather the diversity cross values (see ginn.train.distributed). Every
rank uses one CPU thread. The timed window excludes process start, imports, model building and
``--warmup`` iterations (the first one builds the connectedness surface network).

Run:  .venv/bin/python benchmarks/ddp.py [--preset demo] [--shapes 4] [--iterations 10] [--warmup 2]
          [--no-connectedness] [--set KEY=VALUE ...]
Prints it/s for 1 rank and 2 ranks and their ratio, and checks that both end with the same weights.

Measured (2026-11-23, the shared 2-core machine at load average 16, i.e. far less than one free
core per process): demo preset, 4 shapes, connectedness and diversity on: 1 rank 1.72 it/s,
2 ranks 1.69 it/s, ratio 0.99x; the 2-rank weights equal the 1-rank weights to 3.8e-7 (float32)
after 12 iterations.

On the shared 2-core machine the ratio is limited by the cores actually free (other jobs run
there); two ranks can at best double the throughput when two cores are idle. The point of the
2-rank CPU run is correctness; the speed-up shows on GPUs (one NCCL rank per GPU).
"""

from __future__ import annotations

import argparse
import os
import socket
import sys
import time

import torch
import torch.multiprocessing as mp


def _setup(args):
    from ginn.config import parse_set
    from ginn.problems import load_spec

    spec = load_spec("obstacle")
    over = {"latents": {"n_shapes": args.shapes}, "training": {"iterations": args.warmup + args.iterations,
                                                                "checkpoint_every": 10**9, "threads": 1}}
    if args.no_connectedness:
        over["losses"] = {"connectedness": {"weight": 0.0}}
    return spec, spec.config(args.preset, over, parse_set(args.sets))


def _time(trainer, args) -> tuple[float, torch.Tensor]:
    for _ in range(args.warmup):
        trainer.train_step()
    if trainer.dist is not None:
        trainer.dist.barrier()
    t0 = time.perf_counter()
    for _ in range(args.iterations):
        trainer.train_step()
    if trainer.dist is not None:
        trainer.dist.barrier()
    dt = time.perf_counter() - t0
    return args.iterations / dt, torch.cat([p.detach().flatten() for p in trainer.model.parameters()])


def _rank(rank: int, world: int, port: int, args, out: str) -> None:
    os.environ.update(RANK=str(rank), WORLD_SIZE=str(world), LOCAL_RANK=str(rank), MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port))
    torch.set_num_threads(1)
    from ginn.tasks import make_task
    from ginn.train.distributed import init_distributed, shutdown
    from ginn.train.trainer import Trainer

    ctx = init_distributed("cpu")
    spec, cfg = _setup(args)
    tr = Trainer(make_task(spec, cfg), cfg, None, progress=False, dist=ctx)
    ips, w = _time(tr, args)
    if rank == 0:
        torch.save({"ips": ips, "w": w}, out)
    shutdown(ctx)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="demo")
    ap.add_argument("--shapes", type=int, default=4)
    ap.add_argument("--iterations", type=int, default=10)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--no-connectedness", action="store_true")
    ap.add_argument("--set", dest="sets", action="append", default=[])
    args = ap.parse_args(argv)
    torch.set_num_threads(1)

    from ginn.tasks import make_task
    from ginn.train.trainer import Trainer

    spec, cfg = _setup(args)
    print(f"obstacle, preset {args.preset}: {args.shapes} shapes, {cfg.sampling.n_domain} domain points/shape, "
          f"model {cfg.model.kind} {cfg.model.hidden}, connectedness weight {cfg.losses.connectedness.weight}, "
          f"diversity weight {cfg.losses.diversity.weight}; {args.iterations} timed iterations after {args.warmup}", flush=True)
    ips1, w1 = _time(Trainer(make_task(spec, cfg), cfg, None, progress=False), args)
    print(f"1 rank : {ips1:.3f} it/s", flush=True)

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = f"/tmp/ginn-ddp-bench-{os.getpid()}.pt"
    mp.start_processes(_rank, args=(2, port, args, out), nprocs=2, join=True, start_method="spawn")
    r = torch.load(out)
    os.unlink(out)
    ips2 = r["ips"]
    print(f"2 ranks: {ips2:.3f} it/s (gloo, 1 thread each)")
    print(f"ratio 2 ranks / 1 rank: {ips2 / ips1:.2f}x")
    print(f"max |weights(2 ranks) - weights(1 rank)| after {args.warmup + args.iterations} iterations: {(r['w'] - w1).abs().max():.2e}")
    print(f"(load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
