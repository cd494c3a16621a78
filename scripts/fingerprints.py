#!/usr/bin/env python
"""Fingerprints of the trained weights of short runs: every built-in preset, every problem of the
public suite and the variants that take each other path of the trainer (balancing methods, models,
the L-BFGS phase, resume, ...), seed 0.

A refactoring that must not change what ginn computes is checked by writing the fingerprints
before it and comparing after::

    python scripts/fingerprints.py --write before.json           # every case, two at a time
    python scripts/fingerprints.py --check before.json           # exit 1 where a hash differs
    python scripts/fingerprints.py --only obstacle:demo --check before.json

A case is ``problem:preset`` (``-`` for the settings derived from the geometry) with an optional
``+variant``. Each trains ``ITERATIONS`` iterations (``--iterations``, default 16) with every
start iteration of a loss (and Gray-Scott's later phases) moved to half of that, so that every term
of the preset runs, one torch thread, in its own process (a process that compiled more than eight
kernel shapes runs the later ones eagerly, which rounds differently). The fingerprint is the
SHA-256 of the model's state dict (names, dtypes, shapes and bytes in name order) and, apart, of
the values of the last line of ``metrics.jsonl``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SUITE = ROOT / "benchmarks" / "suite"

#: problem -> its presets ("-": the spec's own settings; shape specs derive the rest)
PRESETS = {
    "obstacle": ["-", "paper", "demo", "quick", "single", "softplus", "siren2"],
    "bracket": ["-", "paper", "gpu", "gpu-single", "cpu", "cpu-gen", "single", "demo"],
    "plateau": ["-", "cpu", "demo"],
    "wheel": ["-"],
    "mirror": ["-", "paper", "focus-half", "demo"],
    "gray-scott": ["-", "paper", "fourier", "quick"],
}

#: variants on the obstacle's derived settings: each takes a path of the trainer or the task that
#: the presets do not
VARIANTS = {
    "lbfgs": ["training.lbfgs_steps=2"],
    "adaptive": ["balancing.method=adaptive"],
    "augmented": ["balancing.method=augmented-lagrangian", "balancing.update_every=4", "balancing.mu_growth=2"],
    "weighted": ["balancing.method=weighted"],
    "ph": ["connectedness.method=persistent-homology"],
    "sum": ["diversity.aggregation=sum", "diversity.eps=0.01"],
    "random": ["latents.draw=uniform"],
    "dim2": ["latents.dim=2", "latents.n_shapes=6"],
    "eager": ["training.compile=false"],
    "float64": ["training.dtype=float64"],
    "nokeep": ["training.keep_most_feasible=false"],
    "stop": ["training.stop_when_feasible=true"],
    "wire": ["model.kind=wire", "model.hidden=[32,32]"],
    "mlp": ["model.kind=mlp", "model.hidden=[32,32]"],
    "fourier": ["model.kind=fourier", "model.hidden=[32,32]", "model.n_features=16"],
    "raw": ["model.frame=raw"],
    "holes": ["+holes=2"],
    "band": ["sampling.n_band=64", "sampling.strain_interface_clearance=0.05", "losses.strain.weight=1e-6",
             "losses.mean_curvature.weight=1e-6", "sampling.interface_corner_weight=3"],
    "power2": ["losses.containment_power=2", "losses.containment_slope=0"],
    "restart": ["training.lr_restart_at=4", "training.lr_restart=1e-4"],
    "resume": ["+resume"],
}


def cases() -> list[str]:
    out = [f"{p}:{q}" for p, qs in PRESETS.items() for q in qs]
    out += [f"suite/{f.stem}:-" for f in sorted(SUITE.glob("*.yaml"))]
    out += [f"obstacle:-+{v}" for v in VARIANTS]
    return out


def _later(cfg: dict, cap: int) -> list[str]:
    """``--set`` items that move every start iteration beyond ``cap`` to ``cap``."""
    sets = []
    for name, term in cfg.get("losses", {}).items():
        if isinstance(term, dict) and term.get("start", 0) > cap:
            sets.append(f"losses.{name}.start={cap}")
    params = cfg.get("params", {})
    for name, term in params.get("losses", {}).items():
        if isinstance(term, dict) and term.get("start", 0) > cap:
            sets.append(f"params.losses.{name}.start={cap}")
    for key in ("reflection_start", "fine_grid_from", "flow_steps"):
        if params.get(key, 0) > cap:
            sets.append(f"params.{key}={cap}")
    if cfg.get("training", {}).get("lr_restart_at", 0) > cap:
        sets.append(f"training.lr_restart_at={cap}")
    return sets


def weights_hash(model) -> str:
    h = hashlib.sha256()
    for name, t in sorted(model.state_dict().items()):
        t = t.detach().cpu().contiguous()
        h.update(f"{name}:{t.dtype}:{tuple(t.shape)}".encode())
        h.update(t.numpy().tobytes())
    return h.hexdigest()


def run_case(case: str, iterations: int, work: Path) -> dict:
    """Train one case in this process and return its fingerprints."""
    import torch

    from ginn import runs
    from ginn.config import config_to_dict

    head, _, variant = case.partition("+")
    problem, _, preset = head.partition(":")
    if problem.startswith("suite/"):
        problem = str(SUITE / f"{problem[6:]}.yaml")
    preset = None if preset in ("", "-") else preset
    sets = [f"training.iterations={iterations}", "training.threads=1", "seed=0"]
    extra = VARIANTS.get(variant, []) if variant else []
    sets += [s for s in extra if not s.startswith("+")]
    spec, cfg = runs.resolve(problem, preset, sets=sets)
    later = _later(config_to_dict(cfg), iterations // 2)
    if later:
        spec, cfg = runs.resolve(problem, preset, sets=sets + later)
    if "+holes=2" in extra:
        from ginn.problems.spec import TopologySpec

        spec = spec.model_copy(update={"topology": TopologySpec.model_validate({"holes": 2}, context={"dim": 2})})
    torch.manual_seed(0)
    out = work / case.replace("/", "_").replace(":", "_").replace("+", "_")
    if "+resume" in extra:
        half = runs.resolve(problem, preset, sets=sets + later + [f"training.iterations={iterations // 2}"])[1]
        runs.train(spec, half, out, progress=False, results=False)
        outcome = runs.resume(out, iterations=iterations, progress=False, results=False)
    else:
        outcome = runs.train(spec, cfg, out, progress=False, results=False)
    lines = [json.loads(s) for s in (out / "metrics.jsonl").read_text().splitlines() if s.strip()]
    last = next((r for r in reversed(lines) if "event" not in r), {})
    values = {k: v for k, v in last.items() if k not in ("time",)}
    return {"weights": weights_hash(outcome.model), "last": hashlib.sha256(json.dumps(values, sort_keys=True).encode()).hexdigest(),
            "step": outcome.step, "status": outcome.status}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--write", metavar="FILE", help="write the fingerprints to FILE (JSON)")
    p.add_argument("--check", metavar="FILE", help="compare with FILE; exit 1 where a weight hash differs")
    p.add_argument("--only", nargs="+", metavar="CASE", help="cases (default: all; --list shows them)")
    p.add_argument("--list", action="store_true", help="print the cases and exit")
    p.add_argument("--iterations", type=int, default=16)
    p.add_argument("--jobs", type=int, default=2, help="cases run at once (each in its own process, one thread)")
    p.add_argument("--case", help=argparse.SUPPRESS)
    p.add_argument("--work", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.case:
        print(json.dumps(run_case(a.case, a.iterations, Path(a.work))))
        return 0
    todo = a.only or cases()
    if a.list:
        print("\n".join(todo))
        return 0
    ref = json.loads(Path(a.check).read_text()) if a.check else {}
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    results: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as work:
        def one(case: str) -> tuple[str, dict]:
            r = subprocess.run([sys.executable, __file__, "--case", case, "--iterations", str(a.iterations), "--work", work],
                               capture_output=True, text=True, env=env)
            if r.returncode != 0:
                return case, {"error": (r.stderr.strip().splitlines() or ["?"])[-1]}
            return case, json.loads(r.stdout.strip().splitlines()[-1])

        with ThreadPoolExecutor(a.jobs) as pool:
            for case, res in pool.map(one, todo):
                results[case] = res
                mark = ""
                if case in ref:
                    mark = "same" if ref[case].get("weights") == res.get("weights") else "DIFFERENT"
                    if ref[case].get("last") != res.get("last"):
                        mark += " (the last logged values differ)"
                print(f"{case:32s} {res.get('weights', res.get('error'))[:16]} {mark}", flush=True)
    if a.write:
        Path(a.write).write_text(json.dumps(results, indent=1, sort_keys=True) + "\n")
    bad = [c for c in results if c in ref and ref[c].get("weights") != results[c].get("weights")]
    errors = [c for c in results if "error" in results[c]]
    if a.check:
        print(f"{len(results) - len(bad)} of {len(results)} cases equal" + (f"; different: {', '.join(bad)}" if bad else ""))
    return 1 if bad or errors else 0


if __name__ == "__main__":
    sys.exit(main())
