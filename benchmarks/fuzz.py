"""A fuzz pass over what a user hands ginn: spec files, command-line flags and run-directory files.

    python benchmarks/fuzz.py                  # 240 cases, seed 0
    python benchmarks/fuzz.py --n 600 --seed 3

Every case is an input known to be bad, run through ginn's command line in this process:

- ``spec``: one field of a valid spec given a value of the wrong type, out of range, non-finite
  or huge, a point of the wrong length, an unknown primitive, an unknown key, or a required key
  removed; then ``ginn train SPEC``;
- ``flag``: one flag of ``train``, ``eval``, ``export`` or ``view`` given a bad value;
- ``run``: one file of a finished run directory (``config.yaml``, ``problem.yaml``,
  ``status.json``, ``metrics.jsonl``, the checkpoint) truncated, overwritten with random bytes,
  emptied or removed, or a config field given a bad value; then a command that reads the run.

A ``spec`` or ``flag`` case passes when ginn exits with status 2 and prints one line
``ginn: error: ...``; a ``run`` case when ginn exits with 0 or 2 (a command that does not read
the damaged file may succeed), prints one line when it fails, and ``ginn status RUN`` still
answers afterwards with one of those. No case may raise out of the command line (a traceback).
Prints every failure and the counts per kind; exits 1 on any failure.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import random
import shutil
import sys
import tempfile
from pathlib import Path

import yaml

from ginn.cli import main as ginn_main

SPEC = {
    "name": "fuzz",
    "geometry": {
        "dim": 2,
        "domain": {"lo": [-1.0, -0.5], "hi": [1.0, 0.5]},
        "design_region": {"type": "rectangle", "lo": [-0.9, -0.4], "hi": [0.9, 0.4]},
        "interfaces": [{"type": "segment", "a": [-0.9, -0.4], "b": [-0.9, 0.4]},
                       {"type": "circle", "center": [0.5, 0.0], "radius": 0.2}],
        "obstacles": [{"type": "disk", "center": [0.0, 0.0], "radius": 0.1}],
    },
    "tolerances": {"interface": 0.005},
    "defaults": {"latents": {"n_shapes": 2}, "training": {"iterations": 2}},
}
#: keys without which a spec is incomplete
REQUIRED = [("geometry",), ("geometry", "dim"), ("geometry", "domain"), ("geometry", "domain", "lo"),
            ("geometry", "domain", "hi"), ("geometry", "interfaces", 0, "type"), ("geometry", "interfaces", 1, "radius")]
BAD_NUMBERS = ["abc", None, {}, [], float("nan"), float("inf"), -float("inf"), 1e300, -1e300, True]
BAD_POINTS = ["x", [], [1.0], [1.0, 2.0, 3.0], [None, 1.0], ["a", "b"], [float("nan"), 0.0], [1e300, 0.0]]

FLAGS = {
    "train": [["--iterations", "-1"], ["--iterations", "x"], ["--iterations", "1e99"], ["--seed", "-1"],
              ["--seed", "1e24"], ["--seed", "x"], ["--device", "tpu"], ["--device", "cuda:x"],
              ["--set", "nokey=1"], ["--set", "model.hidden=x"], ["--set", "training.lr=-1"],
              ["--set", "latents.n_shapes=0"], ["--set", "model=3"], ["--set", "training.lr"],
              ["--set", "training.lr=.nan"], ["--preset", "nosuchpreset"], ["--set", "latents.n_shapes=1000000000"],
              ["--set", "device=tpu"], ["--set", "params.kind=mirror"]],
    "eval": [["--resolution", "0"], ["--resolution", "-3"], ["--resolution", "x"], ["--resolution", "100000000"],
             ["--heldout", "-1"], ["--heldout", "x"], ["--heldout", "100000000"], ["--device", "tpu"]],
    "export": [["--latent", "nan"], ["--latent", "inf"], ["--latent", "x"], ["--latent", "1e308"],
               ["--latent", "0.1", "0.2"], ["--resolution", "0"], ["--format", "docx"]],
    "view": [["--steps", "0"], ["--steps", "x"], ["--steps", "99999999999"]],
}
RUN_FILES = ["config.yaml", "problem.yaml", "status.json", "metrics.jsonl", "checkpoints/last.pt"]
RUN_COMMANDS = [["eval", "{run}", "--resolution", "32", "--heldout", "2"], ["plot", "{run}", "--resolution", "32"],
                ["export", "{run}", "--resolution", "32", "--out", "{tmp}/ex"], ["view", "{run}", "--steps", "2"],
                ["resume", "{run}", "--iterations", "4", "--no-results", "--quiet"], ["status", "{run}"]]
TINY = ["--set", "sampling.n_domain=64", "--set", "sampling.n_outside=32", "--set", "sampling.n_interface=32",
        "--set", "model.hidden=[8,8]", "--set", "training.threads=1", "--quiet", "--no-results"]


def call(argv: list[str]) -> tuple[int | None, str, str | None]:
    """``(exit status, stderr, escaped exception)`` of ``ginn ARGV`` run in this process."""
    err = io.StringIO()
    code, escaped = 0, None
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = ginn_main([str(a) for a in argv])
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else 2
        except BaseException as e:  # noqa: BLE001 - what the fuzz pass looks for
            escaped = f"{type(e).__name__}: {e}"
    return code, err.getvalue(), escaped


def _errors(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip() and not line.startswith("ginn: note:")]


def _leaves(node, path=()):
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _leaves(v, (*path, k))
    elif isinstance(node, list) and node and not all(isinstance(v, (int, float)) for v in node):
        for i, v in enumerate(node):
            yield from _leaves(v, (*path, i))
    else:
        yield path, node


def _set(tree, path, value):
    for k in path[:-1]:
        tree = tree[k]
    tree[path[-1]] = value


def spec_case(rng: random.Random) -> tuple[str, dict]:
    spec = copy.deepcopy(SPEC)
    how = rng.choice(["value", "value", "value", "unknown key", "missing key", "type"])
    leaves = [(p, v) for p, v in _leaves(spec) if p[0] not in ("name", "defaults") and p[-1] != "type"]
    if how == "value":
        path, v = rng.choice(leaves)
        bad = rng.choice(BAD_POINTS if isinstance(v, list) else BAD_NUMBERS)
        if path[-1] == "dim":
            bad = rng.choice([1, 4, "x", None, 2.5])
        _set(spec, path, bad)
        return f"{'.'.join(map(str, path))} = {bad!r}", spec
    if how == "unknown key":
        nodes = [spec, spec["geometry"], spec["geometry"]["domain"], spec["geometry"]["interfaces"][1], spec["tolerances"]]
        rng.choice(nodes)["nosuchkey"] = 1
        return "an unknown key", spec
    if how == "missing key":
        path = rng.choice(REQUIRED)
        node = spec
        for k in path[:-1]:
            node = node[k]
        del node[path[-1]]
        return f"{'.'.join(map(str, path))} removed", spec
    path = rng.choice([("geometry", "interfaces", 0, "type"), ("geometry", "design_region", "type"),
                       ("geometry", "obstacles", 0, "type")])
    _set(spec, path, rng.choice(["nosuchtype", 3, None, "sphere"]))
    return f"{'.'.join(map(str, path))} an unknown primitive", spec


def damage(path: Path, rng: random.Random) -> str:
    how = rng.choice(["truncate", "random bytes", "empty", "remove", "bad field"])
    if how == "truncate" and path.exists():
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    elif how == "random bytes":
        path.write_bytes(bytes(rng.randrange(256) for _ in range(200)))
    elif how == "empty":
        path.write_bytes(b"")
    elif how == "remove":
        path.unlink(missing_ok=True)
    elif path.suffix in (".yaml", ".json"):
        text = path.read_text()
        for key in ("lr:", "n_shapes:", "dim:", "radius:", '"step":', "iterations:"):
            if key in text:
                head, tail = text.split(key, 1)
                rest = tail.split("\n", 1)
                path.write_text(head + key + " " + rng.choice(["abc", "-1", "[1, 2]", ".nan", "{}"]) +
                                ("\n" + rest[1] if len(rest) > 1 else ""))
                break
        else:
            path.write_text("{unclosed: [")
    else:
        path.write_bytes(b"\x00\xff" * 50)
    return how


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=240, help="number of cases (a third of each kind)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    rng = random.Random(args.seed)
    failures: list[str] = []
    counts = {"spec": 0, "flag": 0, "run": 0}
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        base = tmp / "base"
        code, err, escaped = call(["train", "obstacle", "--preset", "demo", "--iterations", "3", "--out", base, *TINY])
        if code != 0 or escaped:
            print(f"could not train the base run: {escaped or err}", file=sys.stderr)
            return 1
        for i in range(args.n):
            kind = ("spec", "flag", "run")[i % 3]
            counts[kind] += 1
            case = tmp / f"case{i}"
            case.mkdir()
            if kind == "spec":
                what, spec = spec_case(rng)
                (case / "spec.yaml").write_text(yaml.safe_dump(spec))
                argv = ["train", case / "spec.yaml", "--out", case / "run", *TINY]
            elif kind == "flag":
                cmd = rng.choice(list(FLAGS))
                flag = rng.choice(FLAGS[cmd])
                what = f"{cmd} {' '.join(flag)}"
                argv = [cmd, "obstacle", *TINY[:8], "--out", case / "run", *flag] if cmd == "train" else [cmd, base, *flag]
            else:
                run = case / "run"
                shutil.copytree(base, run)
                name = rng.choice(RUN_FILES)
                how = damage(run / name, rng)
                cmd = rng.choice(RUN_COMMANDS)
                argv = [a.format(run=run, tmp=case) for a in cmd]
                what = f"{name} {how}; ginn {cmd[0]}"
            code, err, escaped = call(argv)
            lines = _errors(err)
            if escaped:
                failures.append(f"{kind} [{what}]: traceback: {escaped}")
            elif kind != "run" and code == 0:
                failures.append(f"{kind} [{what}]: exit 0 on a bad input")
            elif code not in (0, 2):
                failures.append(f"{kind} [{what}]: exit {code}")
            elif code == 2 and (len(lines) != 1 or not lines[0].startswith("ginn: error:")):
                failures.append(f"{kind} [{what}]: not one error line: {err.strip()[:300]!r}")
            elif kind == "run":
                s_code, s_err, s_escaped = call(["status", case / "run"])
                if s_escaped or s_code not in (0, 2):
                    failures.append(f"run [{what}]: ginn status afterwards: {s_escaped or s_code} {s_err[:200]!r}")
            shutil.rmtree(case, ignore_errors=True)
    for f in failures:
        print(f)
    total = sum(counts.values())
    print(f"{total - len(failures)} of {total} cases answered as they should "
          f"({', '.join(f'{n} {k}' for k, n in counts.items())}); {len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
