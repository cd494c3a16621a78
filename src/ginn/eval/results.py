"""Typed results of an evaluation: one shape's metrics, the verdict on a set of shapes, and the
whole of ``ginn eval`` on a shape run. Each serialises to the JSON of ``metrics.json``
(``to_json``) and reads it back (``from_json``), so results cross layers and processes as
objects, and a run directory keeps the same plain files."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..constraints.catalog import describe, verdict_text
from ..constraints.verdict import Verdict, Violation, number_text
from .report import format_table

__all__ = ["METRIC_NAMES", "ShapeMetrics", "FeasibilitySummary", "ShapeEvaluation", "finite_or_none", "number_text"]

#: Per-shape metric names, in the order of the paper's tables (:mod:`ginn.eval.metrics`).
METRIC_NAMES = (
    "b0",
    "b0_in_design_region",
    "b1_in_design_region",
    "b2_in_design_region",
    "genus",
    "disconnected_volume",
    "disconnected_volume_in_design_region",
    "connected_interfaces_share",
    "interface_cd1",
    "interface_cd1_worst",
    "boundary_overlap",
    "volume_outside",
    "volume_outside_off_interfaces",
    "volume_fraction",
    "surface_strain",
    "symmetry_error",
)


def finite_or_none(v: Any) -> Any:
    """JSON has no infinity: undefined values (e.g. the CD1 of an empty shape) become None."""
    return None if isinstance(v, float) and not math.isfinite(v) else v


@dataclass(frozen=True)
class ShapeMetrics:
    """The metrics of one shape (``None``: not measured, not applicable or undefined).

    Attributes: the names of :data:`METRIC_NAMES` (:mod:`ginn.eval.metrics` defines each), and
    ``extra``: the metrics that verdicts measure themselves (:meth:`ginn.constraints.Verdict.measure`).
    Verdicts read either by name (``metrics.get(name)``).
    """

    b0: int | None = None
    b0_in_design_region: int | None = None
    b1_in_design_region: int | None = None
    b2_in_design_region: int | None = None
    genus: int | None = None
    disconnected_volume: float | None = None
    disconnected_volume_in_design_region: float | None = None
    connected_interfaces_share: float | None = None
    interface_cd1: float | None = None
    interface_cd1_worst: float | None = None
    boundary_overlap: float | None = None
    volume_outside: float | None = None
    volume_outside_off_interfaces: float | None = None
    volume_fraction: float | None = None
    surface_strain: float | None = None
    symmetry_error: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def get(self, name: str, default: Any = None) -> Any:
        v = getattr(self, name) if name in METRIC_NAMES else self.extra.get(name)
        return default if v is None else v

    def to_json(self) -> dict:
        """Every metric, infinities as None (the JSON of ``metrics.json``)."""
        out = {k: finite_or_none(getattr(self, k)) for k in METRIC_NAMES}
        out.update({k: finite_or_none(v) for k, v in self.extra.items()})
        return out

    @classmethod
    def from_json(cls, data: Mapping) -> ShapeMetrics:
        return cls(**{k: data.get(k) for k in METRIC_NAMES}, extra={k: v for k, v in data.items() if k not in METRIC_NAMES})

    def finite(self) -> ShapeMetrics:
        """The same with undefined (infinite) values as None, as ``metrics.json`` holds them."""
        return ShapeMetrics.from_json(self.to_json())


@dataclass
class FeasibilitySummary:
    """The verdict on a set of shapes (:func:`ginn.eval.feasibility.summarize`).

    Attributes:
        feasible, shapes: how many shapes meet every bound, of how many.
        violations: per shape, ``{constraint: Violation}`` (empty: feasible).
        worst: the largest CD1, volume outside E that the verdict bounds and number of pieces
            inside E over the shapes (``interface_cd1``, ``volume_outside``, ``b0_in_design_region``).
        ratios: each constraint's largest value over its bound (None: undefined, e.g. an empty shape).
        set_violations: bounds on the set it misses (a least diversity).
        latents: the latent code of each shape ``[[z_1, ..., z_k], ...]`` where the summary names
            them (held-out codes), else None.
        shape_ratios: per shape, its largest value over a bound (None: undefined), where the
            summary names its codes (the worst latent is the one with the largest).
        heldout: the verdict at the held-out codes of the latent set (a generative model judged
            beyond the codes it reports, :func:`ginn.eval.feasibility.judge_latent_set`), or None.
    """

    feasible: int
    shapes: int
    violations: list[dict[str, Violation]]
    worst: dict[str, float] = field(default_factory=dict)
    ratios: dict[str, float | None] = field(default_factory=dict)
    set_violations: dict[str, Violation] = field(default_factory=dict)
    latents: list[list[float]] | None = None
    shape_ratios: list[float | None] | None = None
    heldout: FeasibilitySummary | None = None

    @property
    def all_feasible(self) -> bool:
        """Every shape feasible, every bound on the set met and every held-out code feasible."""
        return (self.feasible == self.shapes and not self.set_violations
                and (self.heldout is None or self.heldout.feasible == self.heldout.shapes))

    @property
    def share(self) -> float:
        """The feasible share of the shapes."""
        return self.feasible / self.shapes if self.shapes else 1.0

    def rank(self) -> tuple[int, bool, int]:
        """What a better candidate has more of: feasible reported shapes, then the set's bounds met
        (a least diversity), then feasible held-out codes."""
        return self.feasible, not self.set_violations, 0 if self.heldout is None else self.heldout.feasible

    def judged_ratios(self) -> dict[str, float | None]:
        """Each constraint's largest value over its bound over the reported shapes and the
        held-out codes (None: undefined somewhere)."""
        out = dict(self.ratios)
        if self.heldout is not None:
            for k, v in self.heldout.ratios.items():
                a = out.get(k, 0.0)
                out[k] = None if a is None or v is None else max(a, v)
        return out

    def worst_latent(self) -> tuple[list[float], float | None, dict[str, Violation]] | None:
        """The code with the largest value over a bound, that value (None: undefined, e.g. an
        empty shape) and what it violates; None where the summary names no codes."""
        if not self.latents or self.shape_ratios is None:
            return None
        key = [math.inf if r is None else r for r in self.shape_ratios]
        i = max(range(len(key)), key=key.__getitem__)
        return self.latents[i], self.shape_ratios[i], self.violations[i]

    def heldout_text(self, verdicts: list[Verdict] | tuple = ()) -> str:
        """``held-out latents: 250 of 256 feasible (97.7 %); worst z = (0.81): interface ...``."""
        h = self.heldout
        if h is None:
            return ""
        text = f"held-out latents: {h.feasible} of {h.shapes} feasible ({100 * h.share:.1f} %)"
        w = h.worst_latent()
        if w is not None:
            z, r, bad = w
            what = verdict_text(bad, verdicts) if bad else f"feasible, its tightest bound {100 * r:.0f} % used"
            text += f"; worst z = ({', '.join(f'{v:.4g}' for v in z)}): {what}"
        return text

    def violated_counts(self) -> dict[str, int]:
        """How many shapes violate each constraint."""
        return dict(Counter(name for v in self.violations for name in v))

    def text(self, verdicts: list[Verdict] | tuple = ()) -> str:
        """One line with the count, then one line per infeasible shape naming what it violates
        (the texts of ``verdicts``, or of the built-in verdicts), then the set's misses."""
        lines = [f"feasible shapes: {self.feasible} of {self.shapes}"]
        lines += [f"  shape {i}: {verdict_text(v, verdicts)}" for i, v in enumerate(self.violations) if v]
        lines += [f"  the set: {describe(name, v, verdicts)}" for name, v in self.set_violations.items()]
        if self.heldout is not None:
            lines.append(self.heldout_text(verdicts))
        return "\n".join(lines)

    def short(self) -> str:
        """A few words for a progress bar: ``12/16, worst interface 8.1e-03, outside 1.0e-04``."""
        text = f"{self.feasible}/{self.shapes}"
        if self.heldout is not None:
            text += f", Z {100 * self.heldout.share:.0f}%"
        if "interface_cd1" in self.worst:
            text += f", worst interface {self.worst['interface_cd1']:.1e}"
        if "volume_outside" in self.worst:
            text += f", outside {self.worst['volume_outside']:.1e}"
        return text

    def to_json(self) -> dict:
        return {"feasible": self.feasible, "shapes": self.shapes,
                "violations": [{k: v.to_json() for k, v in per.items()} for per in self.violations],
                "worst": dict(self.worst), "ratios": dict(self.ratios),
                "set_violations": {k: v.to_json() for k, v in self.set_violations.items()},
                **({} if self.latents is None else {"latents": [list(z) for z in self.latents]}),
                **({} if self.shape_ratios is None else {"shape_ratios": list(self.shape_ratios)}),
                **({} if self.heldout is None else {"heldout": self.heldout.to_json()})}

    @classmethod
    def from_json(cls, data: Mapping) -> FeasibilitySummary:
        held = data.get("heldout")
        return cls(int(data["feasible"]), int(data["shapes"]),
                   [{k: Violation.from_json(v) for k, v in per.items()} for per in data.get("violations", [])],
                   dict(data.get("worst") or {}), dict(data.get("ratios") or {}),
                   {k: Violation.from_json(v) for k, v in (data.get("set_violations") or {}).items()},
                   data.get("latents"), data.get("shape_ratios"), None if held is None else cls.from_json(held))


@dataclass
class ShapeEvaluation:
    """``ginn eval`` of shapes: every metric of every shape, their means, the diversity of the set
    and the verdict; ``reference`` holds comparisons with a known answer (Plateau's minimal surface).

    ``to_json()`` is ``metrics.json``; ``text()`` what ``ginn eval`` prints.
    """

    problem: str
    shapes: list[ShapeMetrics]
    mean: dict[str, float | None]
    diversity_mean: float | None
    feasibility: FeasibilitySummary
    reference: dict = field(default_factory=dict)
    verdicts: list[Verdict] = field(default_factory=list, repr=False)  # what judged it (their texts)
    #: a generative model's latent set: the resolution of the held-out verdicts and the smoothness
    #: of z -> shape (:mod:`ginn.eval.latent_space`); empty for a single shape
    latent_space: dict = field(default_factory=dict)
    #: the verdicts whose length the grid cannot resolve (:func:`ginn.eval.feasibility.unresolved`)
    unresolved: dict = field(default_factory=dict)

    @property
    def n_shapes(self) -> int:
        return len(self.shapes)

    def to_json(self) -> dict:
        return {"problem": self.problem, "n_shapes": self.n_shapes, "shapes": [s.to_json() for s in self.shapes],
                "mean": dict(self.mean), "diversity_mean": self.diversity_mean,
                "feasibility": self.feasibility.to_json(),
                **({"latent_space": dict(self.latent_space)} if self.latent_space else {}),
                **({"unresolved": dict(self.unresolved)} if self.unresolved else {}), **self.reference}

    def text(self) -> str:
        text = format_table(self.to_json(), self.feasibility.text(self.verdicts))
        ls = self.latent_space
        if ls.get("path_codes"):
            def num(v):
                return "undefined (a shape is empty)" if v is None else f"{v:.3g}"

            text += (f"\nlatent smoothness over {ls['path_codes']} codes on paths through Z: shape change per unit "
                     f"latent at most {num(ls['change_rate_max'])} (mean {num(ls['change_rate_mean'])}), "
                     f"{ls['topology_changes']} change(s) of topology")
        if ls.get("resolution"):
            text += f"\n(held-out latents judged on the evaluation grid, {ls['resolution']} cells along the longest side)"
        for name, u in self.unresolved.items():
            text += (f"\n{name}: the ball of diameter {u['length']:.3g} spans {u['cells']:.2g} cells of this grid, "
                     f"under the 2 that its opening needs to change anything, so this grid cannot find a shape "
                     f"violating it: judge with --resolution {u['resolution']}")
        if self.reference:
            text += "\n" + "\n".join(f"{k}: {v}" for k, v in self.reference.items())
        return text

    @classmethod
    def from_json(cls, data: Mapping) -> ShapeEvaluation:
        known = ("problem", "n_shapes", "shapes", "mean", "diversity_mean", "feasibility", "latent_space", "unresolved")
        return cls(data.get("problem", ""), [ShapeMetrics.from_json(s) for s in data.get("shapes", [])],
                   dict(data.get("mean") or {}), data.get("diversity_mean"),
                   FeasibilitySummary.from_json(data["feasibility"]), {k: v for k, v in data.items() if k not in known},
                   latent_space=dict(data.get("latent_space") or {}), unresolved=dict(data.get("unresolved") or {}))
