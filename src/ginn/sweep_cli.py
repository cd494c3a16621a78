"""`ginn sweep` argument parser (the implementation lives in ginn.sweep)."""

from __future__ import annotations


def add_sweep_parser(sub) -> None:
    s = sub.add_parser("sweep", help="hyperparameter search with Optuna")
    s.add_argument("problem", nargs="?", help="problem name or SPEC.yaml")
    s.add_argument("--space", help="YAML search space")
    s.add_argument("--trials", type=int, default=10)
    s.add_argument("--storage", help="Optuna storage URL (default: SQLite file in the sweep directory)")
    s.add_argument("--study", help="study name")
    s.add_argument("--preset")
    s.add_argument("--out", help="sweep directory (default runs/sweep-<problem>)")
    s.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE")
    s.add_argument("--report", action="store_true", help="print the best trials and plot the objective")
    s.add_argument("--device")
