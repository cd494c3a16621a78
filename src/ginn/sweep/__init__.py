"""Hyperparameter sweeps with Optuna: ``ginn sweep PROBLEM --space SPACE.yaml --trials N``.

Every trial is a normal run directory (``OUT/trials/<study>-<number>``: config.yaml, metrics.jsonl,
checkpoint, metrics.json from ``ginn eval``), trained by :func:`ginn.runs.train` from the problem's
config plus ``--preset``/``--set`` plus the trial's sampled values. The objective is computed from
the ``ginn eval`` metrics (:func:`ginn.runs.evaluate`); intermediate values for pruning are
reported every ``report_every`` iterations by a trainer hook.

The search space file (YAML) maps dotted config keys to distributions, plus a few options::

    losses.eikonal.weight: {type: float, low: 1.0e-6, high: 1.0e-3, log: true}
    model.w0_first:        {type: float, low: 0.5, high: 3.0}
    training.lr:           {type: float, low: 1.0e-4, high: 1.0e-2, log: true}
    model.kind:            {type: categorical, choices: [siren, resmlp]}
    sampling.n_boundary:   {type: int, low: 64, high: 512, step: 64}
    objective: {interface_cd1: 10.0, b0_error: 1.0}   # optional (default: DEFAULT_OBJECTIVE)
    direction: minimize            # optional
    sampler: tpe                   # tpe (default) | random
    pruner: median                 # median (default) | none
    report_every: 50               # iterations between intermediate values (default iterations / 10)
    intermediate: [interface, design_region, obstacle]   # unweighted loss terms summed for pruning
    eval_resolution: 128           # grid resolution of the evaluation (default: ginn eval's)
    seed: 0                        # sampler seed (default: none, so parallel workers differ)

Parameters may also be listed under a ``params:`` mapping.

Objective: ``sum_k w_k * m_k`` over the metrics ``m_k`` named in ``objective``, minimised. Names
are the metrics of ``ginn eval`` (means over shapes: ``b0``, ``interface_cd1``,
``connected_interfaces_share``, ..., and ``diversity_mean``; for other task kinds, any numeric
top-level field of metrics.json) and two derived ones: ``b0_error`` = mean over shapes of
``|b0 - 1|`` (one connected component wanted) and ``ci_missing`` = ``1 - connected_interfaces_share``.
Length metrics (``interface_cd1``, ``diversity_mean``) are divided by the problem's ``unit_scale``.
The default (:data:`DEFAULT_OBJECTIVE`) is ``b0_error + ci_missing + 10 interface_cd1 - diversity_mean``
(the diversity term only for generative models). A metric that is missing or not finite (e.g. an
empty shape) adds ``|w| * MISSING_PENALTY``.

Budget: ``--trials N`` is the study's total number of trials, shared by every worker: a worker
takes the storage's lock (a file lock next to an SQLite file, an advisory lock on PostgreSQL),
counts the trials and creates the next one only if fewer than N exist, so N trials run in total
however many workers there are. Storage: an SQLite file ``OUT/study.db`` by default; a
``postgresql://`` URL lets workers on many machines share one study.
"""

from .objective import DEFAULT_OBJECTIVE, MISSING_PENALTY, metric_value, objective_value
from .space import SearchSpace, check_space_keys, load_space, parse_space, suggest
from .study import (
    SweepSetup,
    budget_lock,
    default_storage,
    make_storage,
    open_study,
    report,
    require_optuna,
    run_trial,
    run_worker,
    study_names,
)

__all__ = [
    "DEFAULT_OBJECTIVE", "MISSING_PENALTY", "metric_value", "objective_value",
    "SearchSpace", "parse_space", "load_space", "check_space_keys", "suggest",
    "SweepSetup", "budget_lock", "default_storage", "make_storage", "open_study", "study_names",
    "report", "require_optuna", "run_trial", "run_worker",
]
