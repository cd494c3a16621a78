"""The ``ginn sweep`` arguments (the sweep itself is :mod:`ginn.sweep`)."""

from __future__ import annotations

from .types import count, device


def add_sweep_parser(sub) -> None:
    s = sub.add_parser(
        "sweep",
        help="hyperparameter search with Optuna (many workers may share one study)",
        description="Run trials of an Optuna study until it holds --trials trials in total (shared by every worker "
        "on the same --storage/--study), or print the best trials with --report. See docs/scaling.md.",
    )
    s.add_argument("problem", nargs="?", help="problem name or SPEC.yaml (not needed with --report)")
    s.add_argument("--space", help="YAML search space: dotted config keys -> distributions, optional objective")
    s.add_argument("--trials", type=count(1), default=10, help="total number of trials of the study (default 10)")
    s.add_argument("--storage", help="Optuna storage URL, e.g. postgresql://user:pw@host/db (default: sqlite OUT/study.db)")
    s.add_argument("--study", help="study name (default sweep-<problem>)")
    s.add_argument("--preset", help="problem preset every trial starts from")
    s.add_argument("--out", help="sweep directory (default runs/sweep-<problem>); trials go to OUT/trials/")
    s.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="fixed config override for every trial (repeatable)")
    s.add_argument("--iterations", type=count(1), help="training iterations of every trial")
    s.add_argument("--seed", type=int, help="training seed of every trial")
    s.add_argument("--device", type=device, help="cpu (default) or cuda[:N]")
    s.add_argument("--report", action="store_true", help="print the best trials and plot the objective (PNG)")
    s.add_argument("--quiet", action="store_true", help="print nothing but errors")
