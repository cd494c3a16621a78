"""One `ginn` command run alternately with this tree and with an earlier commit's source.

    python benchmarks/against_commit.py --base HEAD~20 --runs 3 \\
        --this-extra="--set training.feasibility_checks=0" -- \\
        train obstacle --preset quick --iterations 200 --no-results --quiet

The base commit's ``src/`` is checked out with ``git worktree`` into a temporary folder; each
round runs the command once with ``PYTHONPATH`` at the base's source and once at this tree's, in
alternating order (base first in even rounds), each in a fresh process with the same
``OMP_NUM_THREADS`` (``--threads``), and writes its run directory to a temporary folder;
``--this-extra`` adds arguments to this tree's command only (a setting the base does not know,
e.g. turning off the feasibility checks, which cost a fixed time per check and would otherwise
weigh on a short command), ``--base-extra`` to the base's only (e.g. the preset that trained a
problem there). It prints
every pair's wall seconds and the ratio of this tree to the base, then the median of the ratios:
pairing rounds keeps the figure true while the machine's speed drifts. Both sides pay the same
start-up (imports, problem build), so a command of many iterations gives a step-cost ratio.
For a training command it also prints each run's mean seconds per iteration (the training
clock of its last logged iteration over that iteration's number, from ``metrics.jsonl``: the
steps and the feasibility checks between them, without start-up and results) and their ratio,
which compares runs of different lengths, and the same from the end of the first iteration on
(without what a run pays once when it starts training, such as compiling kernels):

    python benchmarks/against_commit.py --base REV --runs 2 --threads 2 \\
        --base-extra="--preset quick" -- train obstacle --no-results --quiet
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def seconds_per_iteration(run_dir: Path, after_first: bool = False) -> float | None:
    """Training seconds per iteration of a run directory: the clock of its last logged iteration
    over that iteration's number; with ``after_first``, the clock from the end of iteration 0 on
    over the iterations after it (None without a training log)."""
    log = run_dir / "metrics.jsonl"
    if not log.is_file():
        return None
    first = last = None
    for line in log.read_text().splitlines():
        row = json.loads(line)
        if "time" not in row:
            continue
        if row.get("step", 0) == 0:
            first = row
        else:
            last = row
    if last is None:
        return None
    if not after_first:
        return last["time"] / last["step"]
    return None if first is None else (last["time"] - first["time"]) / last["step"]


def run_once(src: Path, args: list[str], out: Path, threads: int) -> float:
    """Wall seconds of ``python -m ginn ARGS --out OUT`` with ``src`` first on the path."""
    env = dict(os.environ, PYTHONPATH=str(src), OMP_NUM_THREADS=str(threads), MKL_NUM_THREADS=str(threads))
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "ginn", *args, "--out", str(out)], env=env, cwd=out.parent,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        sys.exit(f"ginn {' '.join(args)} failed with {src}: {done.stderr.strip().splitlines()[-1:]}")
    return seconds


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the commit to compare against (any git revision)")
    parser.add_argument("--runs", type=int, default=3, help="rounds (one run of each side per round)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads of every run")
    parser.add_argument("--this-extra", default="", help="arguments added to this tree's command only (one string)")
    parser.add_argument("--base-extra", default="", help="arguments added to the base's command only (one string)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- then the ginn command (without --out)")
    a = parser.parse_args(argv)
    command = a.command[1:] if a.command[:1] == ["--"] else a.command
    if not command:
        parser.error("give the ginn command after --")
    with tempfile.TemporaryDirectory(prefix="ginn-ab-") as tmp:
        base_tree = Path(tmp) / "base"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(base_tree), a.base], check=True)
        try:
            sides = {"base": base_tree / "src", "this": ROOT / "src"}
            commands = {"base": command + shlex.split(a.base_extra), "this": command + shlex.split(a.this_extra)}
            ratios, step_ratios, later_ratios = [], [], []
            print(f"ginn {' '.join(command)}  ({a.threads} thread(s), base {a.base} adds {a.base_extra!r}; "
                  f"this tree adds {a.this_extra!r})")
            for r in range(a.runs):
                order = ["base", "this"] if r % 2 == 0 else ["this", "base"]
                secs, per_it, later = {}, {}, {}
                for side in order:
                    out = Path(tmp) / f"run-{side}-{r}"
                    secs[side] = run_once(sides[side], commands[side], out, a.threads)
                    per_it[side] = seconds_per_iteration(out)
                    later[side] = seconds_per_iteration(out, after_first=True)
                ratios.append(secs["this"] / secs["base"])
                line = f"round {r}: base {secs['base']:.1f} s, this {secs['this']:.1f} s, ratio {ratios[-1]:.3f}"
                if per_it["base"] and per_it["this"]:
                    step_ratios.append(per_it["this"] / per_it["base"])
                    line += (f"; s / iteration base {per_it['base']:.4f}, this {per_it['this']:.4f}, "
                             f"ratio {step_ratios[-1]:.3f}")
                if later["base"] and later["this"]:
                    later_ratios.append(later["this"] / later["base"])
                    line += (f"; after the first iteration base {later['base']:.4f}, this {later['this']:.4f}, "
                             f"ratio {later_ratios[-1]:.3f}")
                print(line, flush=True)
            print(f"median ratio this/base: {statistics.median(ratios):.3f} (min {min(ratios):.3f}, max {max(ratios):.3f})")
            if step_ratios:
                print(f"median ratio of s / iteration: {statistics.median(step_ratios):.3f} "
                      f"(min {min(step_ratios):.3f}, max {max(step_ratios):.3f})")
            if later_ratios:
                print(f"median ratio of s / iteration after the first: {statistics.median(later_ratios):.3f} "
                      f"(min {min(later_ratios):.3f}, max {max(later_ratios):.3f})")
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base_tree)], check=False)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
