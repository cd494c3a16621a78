"""Cost of one training iteration of the built-in presets, and where it goes.

    python benchmarks/step_cost.py                                  # every preset below, 2 threads
    python benchmarks/step_cost.py --presets obstacle:quick --shapes 4 16 64
    python benchmarks/step_cost.py --presets obstacle:quick --shapes 16 64 --compare full-diversity
    python benchmarks/step_cost.py --presets bracket:cpu --from-iteration 1200      # connectedness on
    python benchmarks/step_cost.py --presets bracket:cpu --from-iteration 1200 --compare direct-membership
    python benchmarks/step_cost.py --presets bracket:cpu --checkpoint RUN/checkpoints/last.pt --compare direct-membership
    python benchmarks/step_cost.py --presets bracket:gpu --device cuda --steps 2 --blocks 2
    python benchmarks/step_cost.py --suite                          # the problem suite, derived settings
    python benchmarks/step_cost.py --presets obstacle: --checkpoint RUN/checkpoints/last.pt \
        --compare settings --vs-set sampling.n_domain=1024        # a setting against another value

For each configuration it prints seconds per iteration (the median over ``--blocks`` blocks of
``--steps`` iterations; configurations take turns block by block, so a drift of the machine's
speed hits all of them alike) and the share of each part of a step (of all blocks together; a
part inside another counts for itself only): sampling, the main pass (with the terms computed
from its values), the zero-level-set projection, curvature and strain (with their Hessian
pass), diversity, connectedness, the compliance term of a structural problem (the field at the
element centres, the volume offset) and its finite-element solves apart, and the backward pass
with the optimiser step, and the share
of connectedness calls that rebuilt the whole surface network (the rest are warm updates,
``docs/connectedness.md``). ``--shapes`` overrides the number of shapes of generative shape
presets and prints the scaling exponent of the step cost (``t ~ S^a`` between the first and the
last count). ``--compare full-diversity`` runs every configuration twice, with the exact
nearest-pair diversity (ginn's) and with the full ``S x S`` computation, and prints their ratio;
``--compare direct-membership`` does the same with the design region answering for itself about
every candidate sample outside E and every connectedness path point instead of its exact grid
lookup (``ginn.geometry.lookup``); ``--compare every-saddle`` with the connectedness paths traced
from every saddle instead of only those in E (the same penalties);
``--compare settings`` with the ``--vs-set`` settings on top (``--set`` applies to all).
``--memory`` measures peak memory in a fresh process per configuration (max RSS on the CPU,
``torch.cuda.max_memory_allocated`` on a GPU).
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import resource
import statistics
import subprocess
import sys
import time
from collections import defaultdict
from contextlib import contextmanager
from functools import partial
from pathlib import Path

import torch

from ginn import runs
from ginn.config import deep_merge, parse_set
from ginn.constraints import Batch
from ginn.physics import ElasticitySolver
from ginn.tasks import make_task
from ginn.tasks.shape import ShapeTask
from ginn.topology import trace_surface_network
from ginn.train.checkpoint import load_checkpoint
from ginn.train.trainer import Trainer

constraint_diversity = importlib.import_module("ginn.constraints.diversity")
diversity_module = importlib.import_module("ginn.losses.diversity")
#: the part of a step each constraint's loss is charged to (the rest: the main pass, with the
#: terms computed from its values)
CHARGED = {"mean_curvature": "curvature/strain", "strain": "curvature/strain", "diversity": "diversity",
           "connectedness": "connectedness", "compliance": "compliance"}

SUITE = sorted(str(p) for p in (Path(__file__).resolve().parent / "suite").glob("*.yaml")) + ["obstacle", "bracket", "wheel"]
PRESETS = ["obstacle:demo", "obstacle:quick", "bracket:cpu", "bracket:cpu-gen", "plateau:cpu", "mirror:", "gray-scott:quick"]
PARTS = ["sampling", "main pass", "projection", "curvature/strain", "diversity", "connectedness", "compliance", "FE solves",
         "backward+step"]


class Clock:
    """Accumulates wall time per part while a step runs; a part inside another is charged to
    itself only (the outer part pauses)."""

    def __init__(self):
        self.t = defaultdict(float)
        self.calls = 0  # connectedness calls, and those that rebuilt the surface network
        self.rebuilds = 0
        self._open: list[list] = []  # [name, since] of the parts running, innermost last

    @contextmanager
    def part(self, name: str):
        now = time.perf_counter()
        if self._open:
            outer = self._open[-1]
            self.t[outer[0]] += now - outer[1]
        self._open.append([name, now])
        try:
            yield
        finally:
            now = time.perf_counter()
            inner, since = self._open.pop()
            self.t[inner] += now - since
            if self._open:
                self._open[-1][1] = now

    def wrap(self, obj, attr: str, name: str):
        fn = getattr(obj, attr)

        def timed(*a, **kw):
            with self.part(name):
                return fn(*a, **kw)

        setattr(obj, attr, timed)

    def wrap_class(self, cls, attr: str, name: str):
        """Time a method of every instance of ``cls`` (the batches a step creates)."""
        fn = getattr(cls, attr)

        def timed(obj, *a, **kw):
            with self.part(name):
                return fn(obj, *a, **kw)

        setattr(cls, attr, timed)


def _full_diversity(field, xb, Z, mask, p, eps):
    return diversity_module.diversity(field, xb, Z, mask, "min", p, eps)


def _trace_every_saddle(loss, field, Z, pts, valid):
    """The connectedness paths from every saddle, in E or not (the baseline of ``every-saddle``)."""
    return trace_surface_network(field, Z, loss.domain, pts, loss.config.grid, loss.options.paths, region=loss._membership)


class _Timed:
    """A connectedness loss whose calls are counted (and how many rebuilt the surface network);
    everything else delegates."""

    def __init__(self, inner, clock: Clock):
        self._inner, self._clock = inner, clock

    def __call__(self, *a, **kw):
        out = self._inner(*a, **kw)
        info = getattr(self._inner, "last_info", None) or {}
        self._clock.calls += 1
        # the share of the shapes built afresh (a build can take some shapes only)
        n = len(info.get("n_components") or [1])
        self._clock.rebuilds += info["rebuilt"] / n if "rebuilt" in info else float(info.get("update") == "full")
        return out

    def __getattr__(self, attr):
        return getattr(self._inner, attr)


def build(preset: str, shapes: int | None, device: str, threads: int, from_iteration: int = 0,
          baseline: str = "none", checkpoint: str | None = None, sets: dict | None = None):
    problem, _, name = preset.partition(":")
    over: dict = deep_merge(sets or {}, {"device": device, "training": {"threads": threads}})
    if shapes is not None:
        over["latents"] = {"n_shapes": shapes}
    spec, cfg = runs.resolve(problem, name or None, over)
    state = None if checkpoint is None else load_checkpoint(checkpoint, map_location=device)
    if state is not None and int(state["step"]) >= cfg.training.iterations - 100:
        # a finished run's checkpoint: time Adam steps (past the iterations a step is the L-BFGS phase)
        more = cfg.training.model_copy(update={"iterations": int(state["step"]) + 10**6})
        cfg = cfg.model_copy(update={"training": more})
    task = make_task(spec, cfg)
    trainer = Trainer(task, cfg, None, progress=False)
    trainer.step = from_iteration  # the terms active from there on (e.g. connectedness), on the untrained field
    if state is not None:  # a trained field instead (a run of the same preset)
        trainer.load_state_dict(state)
    clock = Clock()
    if isinstance(task, ShapeTask):
        if baseline == "direct-membership":  # E answers for itself: the samples outside E and the paths' points
            task.setting._membership = task.problem.design_region
        clock.wrap(task, "draw_batch", "sampling")
        for c in task.constraints:
            clock.wrap(c, "loss", CHARGED.get(c.name, "main pass"))
            if c.name == "connectedness" and "connectedness" in trainer.active_terms(10**9):
                loss = c.fn
                if baseline == "direct-membership" and hasattr(loss, "_membership"):
                    loss._membership = loss.region
                if baseline == "every-saddle" and hasattr(loss, "_trace"):  # paths from the saddles outside E too
                    loss._trace = partial(_trace_every_saddle, loss)
                c._fn = _Timed(loss, clock)
        for attr, name in (("evaluate", "main pass"), ("_project", "projection")):
            clock.wrap_class(Batch, attr, name)
        clock.wrap_class(ElasticitySolver, "solve", "FE solves")
    clock.wrap(task, "loss_terms", "loss")
    return trainer, clock


def run_block(trainer: Trainer, clock: Clock, steps: int, full_diversity: bool) -> dict:
    """``steps`` iterations; returns the seconds per iteration of each part."""
    div_fn = constraint_diversity.diversity_nearest
    if full_diversity:
        constraint_diversity.diversity_nearest = _full_diversity
    clock.t.clear()
    clock.calls = clock.rebuilds = 0
    t0 = time.perf_counter()
    try:
        for _ in range(steps):
            trainer.train_step()
            if trainer.device.type == "cuda":
                torch.cuda.synchronize()
    finally:
        constraint_diversity.diversity_nearest = div_fn
    total = time.perf_counter() - t0
    t = dict(clock.t)
    out = {"total": total / steps, "calls": clock.calls, "rebuilds": clock.rebuilds}
    for k in PARTS[:-1]:
        out[k] = t.get(k, 0.0) / steps
    out["main pass"] += t.get("loss", 0.0) / steps  # the step's own work outside the parts above
    out["backward+step"] = out["total"] - sum(out[k] for k in PARTS[:-1])
    return out


def peak_rss() -> float:
    """This process's peak resident memory in GiB: ``VmHWM`` (Linux; reset by exec, unlike
    ``ru_maxrss``, which a child inherits from the parent), else ``ru_maxrss``."""
    try:
        for line in open("/proc/self/status"):
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 2**20
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20


def peak_memory(args, preset: str, shapes: int | None, full: bool) -> float:
    """Peak memory (GiB) of a fresh process training this configuration for ``--steps`` iterations."""
    code = (
        "import sys, resource, torch, json; sys.argv = ['step_cost']; import importlib.util as u;"
        f"spec = u.spec_from_file_location('sc', {__file__!r}); m = u.module_from_spec(spec); spec.loader.exec_module(m);"
        f"tr, ck = m.build({preset!r}, {shapes!r}, {args.device!r}, {args.threads}, {args.from_iteration},"
        f" {args.compare if full else 'none'!r}, {args.checkpoint!r}, {variant_sets(args, full)!r});"
        f"m.run_block(tr, ck, {args.steps}, {full and args.compare == 'full-diversity'});"
        "cuda = torch.cuda.is_available() and tr.device.type == 'cuda';"
        "print(json.dumps(torch.cuda.max_memory_allocated() / 2**30 if cuda else m.peak_rss()))"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    return float(r.stdout.strip().splitlines()[-1])


def variant_sets(args, baseline: bool) -> dict:
    """The settings of a configuration: ``--set``, and ``--vs-set`` on top for the baseline."""
    sets = parse_set(args.set)
    return deep_merge(sets, parse_set(args.vs_set)) if baseline and args.compare == "settings" else sets


def label(preset: str) -> str:
    """``problem:preset`` with a spec file's path shortened to its name (``wheel-2d:``)."""
    problem, _, name = preset.partition(":")
    return f"{Path(problem).stem if problem.endswith('.yaml') else problem}:{name}"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--presets", nargs="+", default=PRESETS, help="problem:preset (mirror: for the defaults)")
    p.add_argument("--shapes", nargs="+", type=int, help="numbers of shapes for generative shape presets")
    p.add_argument("--steps", type=int, default=5, help="iterations per block (5: a whole connectedness rebuild cycle of the CPU presets)")
    p.add_argument("--blocks", type=int, default=4, help="blocks per configuration (taken in turns)")
    p.add_argument("--warmup", type=int, default=2, help="iterations before timing")
    p.add_argument("--threads", type=int, default=2, help="torch threads")
    p.add_argument("--device", default="cpu")
    p.add_argument("--compare", choices=["none", "full-diversity", "direct-membership", "every-saddle", "settings"],
                   default="none",
                   help="also time each configuration with this baseline and print the ratio (settings: the --vs-set ones)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a setting of every configuration")
    p.add_argument("--vs-set", action="append", default=[], metavar="KEY=VALUE",
                   help="the baseline's settings for --compare settings (e.g. sampling.n_domain=1024)")
    p.add_argument("--memory", action="store_true", help="also measure peak memory (a fresh process each)")
    p.add_argument("--from-iteration", type=int, default=0,
                   help="time the iterations from this one on (the loss terms active there; the field is untrained)")
    p.add_argument("--checkpoint", help="start from this checkpoint of a run of the (one) preset: a trained field")
    p.add_argument("--suite", action="store_true",
                   help="time the problems of benchmarks/suite.py (its YAML files and the built-in obstacle, bracket and "
                        "wheel) with the settings ginn derives, instead of --presets")
    args = p.parse_args(argv)
    if args.suite:
        args.presets = [f"{problem}:" for problem in SUITE]
    torch.set_num_threads(args.threads)

    configs = []
    for preset in args.presets:
        counts = args.shapes if args.shapes and not preset.startswith(("mirror", "gray-scott", "plateau")) else [None]
        for s in counts:
            for full in ([False, True] if args.compare != "none" else [False]):
                configs.append((preset, s, full))
    full_div = args.compare == "full-diversity"
    built = {}
    for c in configs:
        tr, ck = build(c[0], c[1], args.device, args.threads, args.from_iteration,
                       args.compare if c[2] else "none", args.checkpoint, variant_sets(args, c[2]))
        if args.warmup > 0:
            run_block(tr, ck, args.warmup, c[2] and full_div)
        built[c] = (tr, ck)
    results: dict = {c: [] for c in configs}
    for _ in range(args.blocks):
        for c in configs:
            results[c].append(run_block(*built[c], args.steps, c[2] and full_div))

    print(f"# {args.device}, {args.threads} thread(s); median of {args.blocks} interleaved blocks of {args.steps} iterations")
    print("| preset | shapes | variant | s / iteration | " + " | ".join(PARTS) + " | full rebuilds |"
          + (" peak memory (GiB) |" if args.memory else ""))
    print("|" + "---|" * (5 + len(PARTS) + (1 if args.memory else 0)))
    med = {}
    for c in configs:
        rows = results[c]
        med[c] = statistics.median(r["total"] for r in rows)
        whole = sum(r["total"] for r in rows)  # shares: of all the blocks' time together
        shares = [f"{100 * max(sum(r[k] for r in rows), 0.0) / whole:.0f} %" for k in PARTS]
        calls = sum(r["calls"] for r in rows)
        rebuilds = f"{100 * sum(r['rebuilds'] for r in rows) / calls:.0f} %" if calls else "–"
        mem = f" {peak_memory(args, c[0], c[1], c[2]):.2f} |" if args.memory else ""
        n = c[1] if c[1] is not None else built[c][0].cfg.latents.n_shapes
        print(f"| {label(c[0])} | {n} | {args.compare if c[2] else 'ginn'} | {med[c]:.3f} | " + " | ".join(shares)
              + f" | {rebuilds} |{mem}")
    if args.compare != "none":
        for preset, s, full in configs:
            if not full:
                print(f"{label(preset)} S={s}: ginn / {args.compare} = {med[(preset, s, False)] / med[(preset, s, True)]:.2f}")
    if args.shapes and len(args.shapes) > 1:
        lo, hi = args.shapes[0], args.shapes[-1]
        for preset in args.presets:
            for full in ([False, True] if args.compare != "none" else [False]):
                a, b = med.get((preset, lo, full)), med.get((preset, hi, full))
                if a and b:
                    print(f"{label(preset)} ({args.compare if full else 'ginn'}): {lo} -> {hi} shapes costs x{b / a:.2f}, "
                          f"exponent {math.log(b / a) / math.log(hi / lo):.2f}")
    print(json.dumps({f"{c[0]}|{c[1]}|{c[2]}": med[c] for c in configs}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
