#!/usr/bin/env python
"""Reproduce the rows of docs/results.md, and regenerate its tables and figures from run directories.

The rows live in ``docs/results.yaml``: for each, the ``ginn train`` command that produces it, the
``ginn eval`` resolution, the conditions it was measured under, its measured values and the figures
it contributes. ``docs/results.md`` holds the prose; every table in it sits between the markers
``<!-- table NAME -->`` and ``<!-- end table -->`` and is generated from ``results.yaml``.

    python scripts/reproduce.py                       # list the rows and their commands
    python scripts/reproduce.py --train ROW [ROW ...] # train and evaluate rows into runs/reproduce/ROW
    python scripts/reproduce.py --write               # take the measured values and figures from the run
                                                      # directories present, rewrite results.yaml's values
                                                      # and every table of results.md
    python scripts/reproduce.py --check               # exit 1 if results.md's tables are not what
                                                      # results.yaml gives (the test suite runs this)

``--runs DIR`` changes where run directories live (default ``runs/reproduce``).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
ROWS_FILE = DOCS / "results.yaml"
RESULTS_MD = DOCS / "results.md"

# --- what a table shows: (header, key, format) --------------------------------------------------------

_SHAPE = [
    ("shapes", "n_shapes", "d"), ("one piece in E with every interface", "conn", "frac"),
    ("b0", "b0", ".2f"), ("b0(Ω∩E)", "b0_E", ".2f"), ("CI/n_I", "ci", ".2f"),
    ("CD1 mean", "cd1", ".1e"), ("CD1 worst", "cd1_max", ".1e"),
    ("vol_out mean", "vol_out", ".1e"), ("vol_out worst", "vol_out_max", ".1e"),
    ("δ_mean", "delta", ".3f"), ("E_strain", "strain", ".0f"),
]
COLUMNS = {
    "shape": _SHAPE,
    "plateau": [("CD2 to reference", "cd2", ".4f"), ("area", "area", ".4f"), ("area error", "area_err", "pct"),
                ("mean abs κ_H", "kappa", ".3f"), ("CD1(Γ, surface)", "icd1", ".3f")],
    "mirror": [("max abs error", "max_err", ".1e"), ("RMS error", "rms_err", ".1e"), ("abs h(0)", "h0", ".1e")],
    "gray-scott": [("latents passing", "passing", "frac"), ("worst residual rel", "rel_max", ".4f"),
                   ("worst change of v", "change_max", ".3f"), ("controls' change", "control", "range"),
                   ("min std(v)", "std_min", ".3f"), ("min nearest distance", "nearest_min", ".3f")],
}


def summarize(kind: str, m: dict) -> dict:
    """The values a table of ``kind`` shows, from a run's ``metrics.json``."""
    if kind in ("shape", "plateau"):
        shapes = m.get("shapes", [])
        mean = m.get("mean", {})

        def worst(key: str):
            vals = [s.get(key) for s in shapes if s.get(key) is not None]
            return max(vals) if vals else None

        conn = sum(1 for s in shapes if s.get("b0_in_design_region") == 1 and s.get("connected_interfaces_share") == 1.0)
        out = {"n_shapes": m.get("n_shapes"), "conn": [conn, len(shapes)], "b0": mean.get("b0"),
               "b0_E": mean.get("b0_in_design_region"), "ci": mean.get("connected_interfaces_share"),
               "cd1": mean.get("interface_cd1"), "cd1_max": worst("interface_cd1"),
               "vol_out": mean.get("volume_outside"), "vol_out_max": worst("volume_outside"),
               "delta": m.get("diversity_mean"), "strain": mean.get("surface_strain")}
        if kind == "plateau":
            out = {"cd2": m["cd2_to_reference"], "area": m["area"], "area_err": m["area_relative_error"],
                   "kappa": m["mean_abs_mean_curvature"], "icd1": m["interface_cd1"]}
        return out
    if kind == "mirror":
        return {"max_err": m["max_abs_error_vs_exact"], "rms_err": m["rms_error_vs_exact"], "h0": m["interface_error"]}
    if kind == "gray-scott":
        lat = m["latents"]
        return {"passing": [m["latents_passing"], m["n_latents"]], "rel_max": max(x["rel"] for x in lat),
                "change_max": max(x["change"] for x in lat),
                "control": [min(x["control_change"] for x in lat), max(x["control_change"] for x in lat)],
                "std_min": min(x["std_v"] for x in lat), "nearest_min": min(x["nearest_distance"] for x in lat)}
    raise ValueError(f"unknown table kind {kind!r}")


def fmt(value, spec: str) -> str:
    if value is None:
        return "–"
    if spec == "frac":
        return f"{value[0]}/{value[1]}"
    if spec == "range":
        return f"{value[0]:.2f}-{value[1]:.2f}"
    if spec == "pct":
        return f"{100 * value:+.1f} %"
    if isinstance(value, float) and not math.isfinite(value):
        return "–"
    if spec == "d":
        return str(int(value))
    return format(float(value), spec)


# --- rows -----------------------------------------------------------------------------------------------


def load_rows() -> dict:
    return yaml.safe_load(ROWS_FILE.read_text())


def train_args(row: dict, runs: Path) -> list[str]:
    """The ``ginn train`` arguments of a row (its run directory under ``runs``)."""
    args = ["train", row["problem"]]
    if row.get("preset"):
        args += ["--preset", row["preset"]]
    args += ["--seed", str(row.get("seed", 0))]
    for s in row.get("set", []):
        args += ["--set", s]
    return args + ["--out", str(runs / row["id"])]


def command(row: dict) -> str:
    """The row's ``ginn train`` command as a user types it (run directory left to the default)."""
    args = train_args(row, Path("RUN"))[:-2]
    return "ginn " + " ".join(shlex.quote(a) for a in args)


def eval_args(row: dict, runs: Path) -> list[str]:
    args = ["eval", str(runs / row["id"])]
    if row.get("eval_resolution"):
        args += ["--resolution", str(row["eval_resolution"])]
    return args


def table(name: str, spec: dict, rows: list[dict]) -> str:
    """The markdown table ``name`` (its rows in file order)."""
    cols = COLUMNS[spec["kind"]]
    head = ["row", *[c[0] for c in cols], "training", "command"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        if r["table"] != name:
            continue
        v = r.get("measured", {})
        cells = [r["label"], *[fmt(v.get(key), f) for _, key, f in cols], r.get("time", "–")]
        cells.append("paper" if r.get("paper") else f"`{command(r)}`")
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    return "\n".join(lines)


def render(md: str, data: dict) -> str:
    """``md`` with every marked table regenerated."""
    def repl(m: re.Match) -> str:
        name = m.group(1)
        if name not in data["tables"]:
            raise SystemExit(f"results.md names table {name!r}, which results.yaml does not define")
        return f"<!-- table {name} -->\n{table(name, data['tables'][name], data['rows'])}\n<!-- end table -->"

    return re.sub(r"<!-- table (\S+) -->\n.*?<!-- end table -->", repl, md, flags=re.S)


# --- commands -------------------------------------------------------------------------------------------


def ginn(args: list[str]) -> None:
    exe = Path(sys.executable).with_name("ginn")
    cmd = [str(exe) if exe.exists() else "ginn", *args]
    print("$", " ".join(shlex.quote(a) for a in cmd), flush=True)
    code = subprocess.run(cmd).returncode
    if code != 0:  # ginn has said why in one line
        sys.exit(code)


def do_train(data: dict, ids: list[str], runs: Path) -> None:
    by_id = {r["id"]: r for r in data["rows"]}
    for i in ids:
        row = by_id.get(i)
        if row is None or row.get("paper"):
            raise SystemExit(f"reproduce.py: no trainable row {i!r} (see `python scripts/reproduce.py`)")
        ginn(train_args(row, runs))
        ginn(eval_args(row, runs))


def do_write(data: dict, runs: Path) -> int:
    n = 0
    for row in data["rows"]:
        run = runs / row["id"]
        metrics = run / "metrics.json"
        if row.get("paper") or not metrics.is_file():
            continue
        kind = data["tables"][row["table"]]["kind"]
        row["measured"] = summarize(kind, json.loads(metrics.read_text()))
        status = json.loads((run / "status.json").read_text()) if (run / "status.json").is_file() else {}
        if "seconds" in status:
            row["time"] = f"{status['seconds'] / 60:.1f} min ({row.get('conditions', 'this machine')})"
        for src, dst in (row.get("figures") or {}).items():
            if (run / src).is_file():
                shutil.copyfile(run / src, DOCS / "img" / dst)
        n += 1
    header = _leading_comments(ROWS_FILE.read_text())
    ROWS_FILE.write_text(header + yaml.safe_dump(data, sort_keys=False, allow_unicode=True, width=120))
    RESULTS_MD.write_text(render(RESULTS_MD.read_text(), data))
    return n


def _leading_comments(text: str) -> str:
    """The comment lines at the top of a YAML file (yaml.safe_dump does not keep them)."""
    out = []
    for line in text.splitlines():
        if line.startswith("#") or not line.strip():
            out.append(line + "\n")
        else:
            break
    return "".join(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--train", nargs="+", metavar="ROW", help="train and evaluate these rows")
    p.add_argument("--write", action="store_true", help="regenerate results.yaml's values and results.md's tables")
    p.add_argument("--check", action="store_true", help="exit 1 when results.md's tables are out of date")
    p.add_argument("--runs", default=str(ROOT / "runs" / "reproduce"), help="where the rows' run directories live")
    a = p.parse_args(argv)
    data = load_rows()
    runs = Path(a.runs)
    if a.train:
        do_train(data, a.train, runs)
    if a.write:
        print(f"updated {do_write(data, runs)} row(s) from {runs}; wrote {RESULTS_MD.relative_to(ROOT)}")
    if a.check:
        current = RESULTS_MD.read_text()
        if render(current, data) != current:
            print("docs/results.md is out of date with docs/results.yaml: run python scripts/reproduce.py --write")
            return 1
        print("docs/results.md matches docs/results.yaml")
    if not (a.train or a.write or a.check):
        for r in data["rows"]:
            if not r.get("paper"):
                print(f"{r['id']:28s} {command(r)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
