"""The public problem suite: train every problem with the settings ginn chooses, and count feasible runs.

    python benchmarks/suite.py                          # every problem, seed 0
    python benchmarks/suite.py --seeds 0 1 2
    python benchmarks/suite.py --only wheel-2d bridge-2d --out runs/suite
    python benchmarks/suite.py --iterations 200          # a quick look (not the benchmark)
    python benchmarks/suite.py --set training.lr_decay=0.1  # a candidate default, on every problem
    python benchmarks/suite.py --only obstacle --topology holes=2   # a topology target on every problem
    python benchmarks/suite.py --make                   # a thickness and a volume bound on every solid

The problems are ``benchmarks/suite/*.yaml``, written the way users write specs: geometry, the
number of shapes and nothing about training, plus the built-in ``obstacle``, ``bracket``,
``plateau`` and ``wheel`` with their geometry and shapes (number and latent range) only: the
obstacle, bracket and wheel as ``ginn train NAME`` trains them, plateau without the paper's settings that its spec
states, so that every problem trains with the settings ginn derives). Each (problem, seed) is trained into ``--out``,
evaluated like ``ginn eval`` (the problem's tolerances, ``docs/problem-spec.md``), and printed as
one row: feasible shapes of all, the worst CD1 (the interface tolerance times ``unit_scale`` in
brackets), the worst volume outside E that the verdict bounds (beyond the interface tolerance of
the interfaces) and the worst of the paper's vol_out (all of it), the diversity, the objective's
quality where the objective is the point of the problem (Plateau's CD2 and area against its
reference, a structural problem's compliance and its ratio to the SIMP reference's), and the wall
time of training and evaluation; for a
generative problem also the held-out codes of its latent set that give a feasible shape and the
smoothness of z -> shape (``ginn eval``). The last lines are the share of (problem, seed) pairs that
end with every shape feasible and of the generative ones with at least 90 % of the held-out codes
feasible. A JSON copy of the table goes to ``OUT/suite.json``, row by row (a row of the same problem
and seed replaces the earlier one, so several suite processes can share ``--out``). SIGINT or
SIGTERM stops the suite after checkpointing the run in progress.

``--topology KEY=N`` (``holes``, ``tunnels``, ``cavities``; repeatable) adds a target to every
problem's ``topology`` (``docs/problem-spec.md``): the row's problem is then named with it
(``obstacle-holes2``, run directory ``obstacle-holes2-s0``), a shape is feasible only with that count, and a
line under the row counts the shapes per number of holes (2D) or per genus of the exported mesh (3D).

``--make`` adds manufacturing bounds to every problem whose shapes are solid parts (every one but
plateau, a surface): ``min_thickness`` of ``MAKE_THICKNESS`` times half the domain's longest side
(a few cells of the evaluation grid, so that the opening measures it) and ``volume_fraction`` at most ``MAKE_VOLUME`` of
E, both with their derived loss weights. The row's problem is named with ``-make``, and a line under
the row gives the range of the shapes' thickness_removed and volume_fraction.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from pydantic import ValidationError

from ginn import runs
from ginn.config import deep_merge, parse_set
from ginn.errors import GinnError, SpecError
from ginn.geometry.base import Box
from ginn.problems import ProblemSpec, load_spec
from ginn.problems.derived import half_longest_side
from ginn.problems.problem import Problem
from ginn.problems.spec import TopologySpec
from ginn.problems.structural import simp_reference

HERE = Path(__file__).resolve().parent / "suite"
BUILTIN = ["obstacle", "bracket", "plateau", "wheel"]
#: ``--make``: the least thickness, in units of half the domain's longest side (3.2 cells of the 3D
#: evaluation grid, 128 cells along that side; 12.8 of the 2D one, 512), and the largest volume
#: fraction of E
MAKE_THICKNESS = 0.05
MAKE_VOLUME = 0.5
#: problems whose shapes are surfaces, not parts: ``--make`` leaves them out
SURFACES = ("plateau",)


def problems() -> dict[str, str]:
    """``{name: spec file or built-in name}`` of the whole suite."""
    out = {p.stem: str(p) for p in sorted(HERE.glob("*.yaml"))}
    out.update({name: name for name in BUILTIN})
    return out


def as_user_spec(spec: ProblemSpec) -> ProblemSpec:
    """``spec`` as a user would write it: geometry, tolerances and the shapes (number, latent range)
    only. The built-in obstacle and bracket are that already without a preset."""
    return spec.model_copy(update={"defaults": {"latents": dict(spec.defaults.get("latents", {}))}, "presets": {}})


def with_topology(spec: ProblemSpec, targets: dict[str, int]) -> ProblemSpec:
    """``spec`` with ``targets`` added to its topology and to its name (``obstacle-holes2``: a
    valid spec name, which the run directory's recorded spec keeps).

    Raises:
        SpecError: a target the problem's dimension does not have, or a bad count.
    """
    if not targets:
        return spec
    try:
        topo = TopologySpec.model_validate({**spec.topology.model_dump(exclude_none=True), **targets},
                                           context={"dim": spec.geometry.dim})
    except ValidationError as e:
        err = e.errors()[0]
        raise SpecError(f"--topology {'.'.join(map(str, err['loc']))}: {err['msg']} ({spec.name})") from None
    label = "-".join(f"{k}{v}" for k, v in sorted(targets.items()))
    return spec.model_copy(update={"topology": topo, "name": f"{spec.name}-{label}"})


def with_make(spec: ProblemSpec) -> ProblemSpec:
    """``spec`` with ``min_thickness`` ``MAKE_THICKNESS`` times half the domain's longest side and
    ``volume_fraction`` at most ``MAKE_VOLUME`` added to its tolerances (a bound the spec states
    already is kept), named ``NAME-make``."""
    scale = half_longest_side(Box(tuple(spec.geometry.domain.lo), tuple(spec.geometry.domain.hi)))
    tol = spec.tolerances.model_dump(exclude_none=True)
    tol.setdefault("min_thickness", {"size": MAKE_THICKNESS * float(scale)})
    tol.setdefault("volume_fraction", {"max": MAKE_VOLUME})
    return spec.model_copy(update={"tolerances": type(spec.tolerances).model_validate(tol), "name": f"{spec.name}-make"})


def run_one(problem: str, seed: int, out: Path, iterations: int | None, threads: int, resolution: int | None,
            sets: dict | None = None, topology: dict[str, int] | None = None, make: bool = False) -> dict | None:
    """Train and evaluate one (problem, seed); the row of the table as a dict (None: the training
    was interrupted)."""
    over: dict = {"seed": seed, "training": {"threads": threads}}
    if iterations is not None:
        over["training"]["iterations"] = iterations
    if sets:
        over = deep_merge(over, sets)
    spec = with_topology(as_user_spec(load_spec(problem)), topology or {})
    if make:
        spec = with_make(spec)
    head = {"problem": str(Path(problem).resolve()) if problem.endswith(".yaml") else spec.name}
    cfg = spec.config(None, head, over)
    t0 = time.perf_counter()
    outcome = runs.train(spec, cfg, out, progress=False, results=False)
    if outcome.status != "completed":  # SIGINT / SIGTERM: stop the suite, not only this run
        return None
    metrics = runs.evaluate(outcome.run_dir, resolution=resolution)
    wall = time.perf_counter() - t0
    feas = metrics["feasibility"]
    worst = feas["worst"]
    tol = outcome.task.problem.tolerances.interface * outcome.task.problem.unit_scale
    return {"problem": spec.name, "seed": seed, "dim": outcome.task.problem.dim, "feasible": feas["feasible"],
            "shapes": feas["shapes"], "worst_cd1": worst.get("interface_cd1"), "cd1_bound": tol,
            "worst_volume_outside": worst.get("volume_outside"),
            "worst_vol_out": max((m["volume_outside"] for m in metrics["shapes"] if m.get("volume_outside") is not None),
                                 default=None),
            "diversity_mean": metrics.get("diversity_mean"),
            "heldout": None if feas.get("heldout") is None else [feas["heldout"]["feasible"], feas["heldout"]["shapes"]],
            "change_rate_max": metrics.get("latent_space", {}).get("change_rate_max"),
            "topology_changes": metrics.get("latent_space", {}).get("topology_changes"),
            "minutes": wall / 60.0, "iterations": outcome.step,
            "objective": objective(metrics["shapes"], outcome.task.problem),
            "holes": [m.get("b1_in_design_region") for m in metrics["shapes"]],
            "genus": [m.get("genus") for m in metrics["shapes"]],
            "thickness_removed": _values(metrics["shapes"], "thickness_removed"),
            "volume_fraction": _values(metrics["shapes"], "volume_fraction")}


def _values(shapes: list[dict], key: str) -> list[float] | None:
    """``[least, largest]`` of a metric over the shapes (None where no shape has it)."""
    v = [m[key] for m in shapes if m.get(key) is not None]
    return [min(v), max(v)] if v else None


def make_line(r: dict) -> str:
    """``  thickness removed 0 to 0.0031, volume fraction 0.21 to 0.48`` under a ``--make`` row."""
    parts = []
    for key, label in (("thickness_removed", "thickness removed"), ("volume_fraction", "volume fraction")):
        v = r.get(key)
        parts.append(f"{label} –" if not v else f"{label} {v[0]:.3g} to {v[1]:.3g}")
    return "  " + ", ".join(parts)


def objective(shapes: list[dict], problem: Problem | None = None) -> dict | None:
    """The quality of the objective where the problem's objective is the point of it: the worst
    CD2 to the reference surface and the area's relative error furthest from 0 (a problem with a
    reference, Plateau's), or the least and largest compliance and, given the ``problem``, the
    compliance of its SIMP reference (:func:`ginn.problems.structural.simp_reference`; a structural
    problem); None otherwise."""
    cd2 = [m["cd2_to_reference"] for m in shapes if m.get("cd2_to_reference") is not None]
    if cd2:
        err = [m["area_relative_error"] for m in shapes if m.get("area_relative_error") is not None]
        return {"cd2_to_reference": max(cd2), "area_relative_error": max(err, key=abs) if err else None}
    c = [m["compliance"] for m in shapes if m.get("compliance") is not None]
    if not c:
        return None
    out = {"compliance": [min(c), max(c)]}
    if problem is not None and problem.physics is not None:
        out["simp"] = simp_reference(problem).compliance
    return out


def objective_text(o: dict | None) -> str:
    """``CD2 0.0050, area -1.3 %``, ``compliance 180 to 239 (1.16 to 1.27 x SIMP)`` or ``–``."""
    if not o:
        return "–"
    if "compliance" in o:
        lo, hi = o["compliance"]
        text = f"compliance {lo:.4g}" if lo == hi else f"compliance {lo:.4g} to {hi:.4g}"
        ref = o.get("simp")
        if ref:
            text += f" ({lo / ref:.2f} x SIMP)" if lo == hi else f" ({lo / ref:.2f} to {hi / ref:.2f} x SIMP)"
        return text
    err = o.get("area_relative_error")
    return f"CD2 {o['cd2_to_reference']:.2g}" + ("" if err is None else f", area {100 * err:+.1f} %")


def topology_line(r: dict) -> str:
    """Shapes per number of holes (2D) or per genus of the exported mesh (3D): ``  holes per shape: 2: 10, 1: 6``."""
    key, what = ("genus", "genus") if r.get("dim") == 3 else ("holes", "holes")
    values = [v for v in r.get(key, []) if v is not None]
    counts = {v: values.count(v) for v in sorted(set(values), reverse=True)}
    return f"  {what} per shape: " + ", ".join(f"{v}: {n}" for v, n in counts.items())


def _f(v, fmt: str = ".2e") -> str:
    return "–" if v is None else format(v, fmt)


def _z(r: dict) -> str:
    """The held-out codes of the latent set: ``250/256 (97.7 %)``; – for a single shape."""
    h = r.get("heldout")
    return "–" if not h else f"{h[0]}/{h[1]} ({100 * h[0] / h[1]:.1f} %)"


def format_row(r: dict) -> str:
    return (f"| {r['problem']} | {r['seed']} | {r['feasible']}/{r['shapes']} | {_z(r)} "
            f"| {_f(r['worst_cd1'])} ({_f(r['cd1_bound'], '.0e')}) "
            f"| {_f(r['worst_volume_outside'])} | {_f(r.get('worst_vol_out'))} | {_f(r['diversity_mean'], '.3f')} "
            f"| {_f(r.get('change_rate_max'), '.2f')} | {_f(r.get('topology_changes'), 'd')} | {objective_text(r.get('objective'))} "
            f"| {r['minutes']:.1f} |")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", nargs="+", type=int, default=[0])
    p.add_argument("--only", nargs="+", help="problem names (default: all)")
    p.add_argument("--out", default="runs/suite", help="where the run directories go (one per problem and seed)")
    p.add_argument("--iterations", type=int, help="override the iteration budget (a quick look, not the benchmark)")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--resolution", type=int, help="evaluation grid (default: that of ginn eval)")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="a setting applied to every problem (to measure a candidate default; not the benchmark)")
    p.add_argument("--topology", action="append", default=[], metavar="KEY=N",
                   help="a topology target added to every problem: holes=N (2D), tunnels=N, cavities=N (3D)")
    p.add_argument("--make", action="store_true",
                   help=f"add min_thickness {MAKE_THICKNESS} x half the domain's longest side and volume_fraction <= "
                        f"{MAKE_VOLUME} to every problem but the surfaces ({', '.join(SURFACES)}), which it leaves out")
    args = p.parse_args(argv)
    suite = problems()
    names = args.only or [n for n in suite if not (args.make and n in SURFACES)]
    unknown = [n for n in names if n not in suite]
    if unknown:
        print(f"--only: unknown problem(s) {', '.join(unknown)} (the suite: {', '.join(suite)})", file=sys.stderr)
        return 2
    try:
        sets = parse_set(args.sets)
    except GinnError as e:
        print(e, file=sys.stderr)
        return 2
    topology = {}
    for item in args.topology:
        key, eq, value = item.partition("=")
        if key not in ("holes", "tunnels", "cavities") or not eq or not value.isdigit():
            print(f"--topology: {item!r} is not holes=N, tunnels=N or cavities=N (N a whole number)", file=sys.stderr)
            return 2
        topology[key] = int(value)
    if args.make and any(n in SURFACES for n in names):
        print(f"--make: {', '.join(n for n in names if n in SURFACES)} is a surface, not a part; leave it out of --only",
              file=sys.stderr)
        return 2
    tag = "".join(f"-{k}{v}" for k, v in sorted(topology.items())) + ("-make" if args.make else "")
    out = Path(args.out)
    print("| problem | seed | feasible | held-out latents feasible | worst CD1 (bound) | worst vol outside E | worst vol_out "
          "| diversity | shape change per unit latent (max) | topology changes | objective | minutes |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for name in names:
        for seed in args.seeds:
            run_dir = out / f"{name}{tag}-s{seed}"
            try:
                r = run_one(suite[name], seed, run_dir, args.iterations, args.threads, args.resolution, sets, topology,
                            args.make)
            except GinnError as e:
                print(f"{name}: {e}", file=sys.stderr)
                return 2
            if r is None:
                print(f"stopped: {name} seed {seed} was interrupted (`ginn resume {run_dir}` continues it); "
                      f"the finished rows are in {out / 'suite.json'}", file=sys.stderr)
                return 130
            rows.append(r)
            print(format_row(r), flush=True)
            if topology:
                print(topology_line(r), flush=True)
            if args.make:
                print(make_line(r), flush=True)
            record(out / "suite.json", r)
    ok = sum(r["feasible"] == r["shapes"] for r in rows)
    print(f"every shape feasible in {ok} of {len(rows)} (problem, seed) pairs ({100 * ok / max(len(rows), 1):.0f} %)")
    gen = [r for r in rows if r.get("heldout")]
    if gen:
        z = sum(r["heldout"][0] >= 0.9 * r["heldout"][1] for r in gen)
        print(f"at least 90 % of the held-out latents feasible in {z} of {len(gen)} generative (problem, seed) pairs")
    return 0


def record(path: Path, row: dict) -> None:
    """Add ``row`` to the JSON list at ``path``, replacing an earlier row of the same (problem, seed):
    several suite processes may share one ``--out``."""
    rows = json.loads(path.read_text()) if path.exists() else []
    rows = [r for r in rows if (r["problem"], r["seed"]) != (row["problem"], row["seed"])] + [row]
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    tmp.write_text(json.dumps(rows, indent=2))
    tmp.replace(path)


if __name__ == "__main__":
    sys.exit(main())
