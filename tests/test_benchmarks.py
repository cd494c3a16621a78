"""Helpers of the benchmark scripts that a figure in docs/results.md depends on."""

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_seconds_per_iteration_reads_the_last_logged_iteration(tmp_path):
    ab = _load("against_commit")
    rows = [{"step": 0, "time": 0.3}, {"step": 10, "time": 1.5},
            {"step": 20, "event": "feasibility", "feasible": 3},  # events carry no clock
            {"step": 20, "time": 4.0}]
    (tmp_path / "metrics.jsonl").write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    assert ab.seconds_per_iteration(tmp_path) == 4.0 / 20
    # from the end of iteration 0 on: without what the run paid once at its start
    assert ab.seconds_per_iteration(tmp_path, after_first=True) == (4.0 - 0.3) / 20
    assert ab.seconds_per_iteration(tmp_path / "missing") is None
