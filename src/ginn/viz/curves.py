"""``loss_curves.png``: the numeric series of a run's ``metrics.jsonl`` against the step, one panel
per family of series.

A family is what shares a unit and a question: the loss terms with ``total`` (one panel, so that
their sizes compare at a glance), each nested group of an iteration record (``multipliers``), each
nested group of an event record (``feasibility: ratios``, ``feasibility: worst``, ...), the
event's own scalars, and ``lr``, ``grad_norm`` and the ``_diagnostics`` apart. A run logs about
forty series; drawn one per panel, matplotlib spent seconds laying out their axes at the end of
every run, and the figure was a wall of small plots.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path

from ..train.rundir import read_metrics
from .figure import new_figure, save_figure

__all__ = ["loss_curve_panels", "plot_loss_curves"]

_STEP_KEYS = ("step", "epoch", "iteration", "iter", "it")
_SKIP_KEYS = ("time", "seconds", "lr_scale")
_ALONE = ("lr", "grad_norm")
LOSSES = "losses"

#: ``{panel: {series: (steps, values)}}``
Panels = dict[str, dict[str, tuple[list[float], list[float]]]]


def _flatten(d: dict, prefix: str = "") -> dict[str, float]:
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out[key] = float(v)
    return out


def _panel(key: str, event: str | None) -> tuple[str, str]:
    """(panel, label within the panel) of the flattened ``key`` of a record (of ``event``, if any)."""
    group, _, leaf = key.rpartition(".")
    if event is not None:
        return (f"{event}: {group}" if group else event), leaf
    if group:
        return group, leaf
    if key in _ALONE:
        return key, key
    if key.startswith("_"):  # the label without its underscore: matplotlib leaves "_..." out of legends
        return "diagnostics", key.lstrip("_")
    return LOSSES, key


def _order(panel: str, from_event: bool) -> tuple:
    """The losses first, then the other families of iteration records, ``lr``, ``grad_norm``,
    the diagnostics, then the events' panels."""
    if from_event:
        return (5, panel)
    if panel == LOSSES:
        return (0, "")
    rank = {"lr": 2, "grad_norm": 3, "diagnostics": 4}
    return (rank.get(panel, 1), panel)


def loss_curve_panels(records: Iterable[dict], keys: Sequence[str] | None = None) -> Panels:
    """The series of ``records`` (``metrics.jsonl``'s lines) grouped into panels, in drawing order.

    A series is a flattened numeric key (``a.b`` for nested dicts) against the record's step
    (``step``/``epoch``/``iteration``, else the line number); non-finite values, booleans and
    wall-clock keys are left out; ``keys`` (flattened names) keeps only those. In the losses panel
    ``total``/``loss`` come first."""
    panels: Panels = {}
    events: set[str] = set()
    for i, rec in enumerate(records):
        event = rec.get("event") if isinstance(rec.get("event"), str) else None
        flat = _flatten(rec)
        step = next((flat[k] for k in _STEP_KEYS if k in flat), float(i))
        for k, v in flat.items():
            if k in _STEP_KEYS or k in _SKIP_KEYS or (keys is not None and k not in keys) or not math.isfinite(v):
                continue
            panel, label = _panel(k, event)
            if event is not None:
                events.add(panel)
            xs, ys = panels.setdefault(panel, {}).setdefault(label, ([], []))
            xs.append(step)
            ys.append(v)
    ordered = {}
    for name in sorted(panels, key=lambda p: _order(p, p in events)):
        series = panels[name]
        first = [k for k in ("total", "loss") if k in series] if name == LOSSES else []
        ordered[name] = {k: series[k] for k in first + sorted(k for k in series if k not in first)}
    return ordered


def plot_loss_curves(metrics_jsonl: str | Path, path: str | Path, keys: Sequence[str] | None = None) -> Path:
    """Draw :func:`loss_curve_panels` of a JSON-lines log into ``path``: three panels a row, a
    legend where a panel holds more than one series, log scale where at least half the values are
    positive and these span more than a factor 20 (the others, zeros of a term not yet started,
    are left out of a log panel)."""
    panels = loss_curve_panels(read_metrics(Path(metrics_jsonl)), keys)
    n = max(1, len(panels))
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    fig = new_figure(4.5 * cols, 3.0 * rows)
    for i, (name, series) in enumerate(panels.items()):
        ax = fig.add_subplot(rows, cols, i + 1)
        values = [v for _, ys in series.values() for v in ys]
        for label, (xs, ys) in series.items():
            ax.plot(xs, ys, lw=1.3 if label in ("total", "loss") else 0.9, label=label,
                    marker="." if len(xs) < 3 else None)
        positive = [v for v in values if v > 0]
        if positive and 2 * len(positive) >= len(values) and max(positive) / min(positive) > 20:
            ax.set_yscale("log", nonpositive="mask")
        only = next(iter(series)) if len(series) == 1 else name
        ax.set_title(name if only == name else f"{name}: {only}", fontsize=8)
        ax.tick_params(which="both", labelsize=7)
        ax.grid(alpha=0.3)
        if len(series) > 1:
            ax.legend(fontsize=6, ncol=2 if len(series) > 6 else 1, frameon=False, loc="upper right")
    if not panels:
        fig.add_subplot(1, 1, 1).text(0.5, 0.5, "no numeric series", ha="center")
    return save_figure(fig, path)
