"""What a mirror run writes and reports: its profile, figure, error against the exact parabola and view."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from torch import nn

from ...config import MirrorParams
from ...train.task import Metrics, Results
from .explorer import write_mirror_view
from .figures import plot_mirror
from .optics import evaluate_mirror, profile

__all__ = ["MirrorResults", "write_profile"]


class MirrorResults(Results):
    """The profile, figure, error against the exact parabola and view of a trained mirror."""

    kind = "mirror"

    def __init__(self, params: MirrorParams):
        self.params = params

    def finalize(self, model: nn.Module, run_dir: Path) -> list[Path]:
        run_dir = Path(run_dir)
        run_dir.mkdir(parents=True, exist_ok=True)
        paths = write_profile(model, self.params, run_dir)
        paths.append(plot_mirror(model, self.params, run_dir / "mirror.png"))
        paths.append(self.view(model, run_dir / "figures" / "explorer.html", title=f"mirror: {run_dir.name}"))
        return paths

    def evaluate(self, model: nn.Module, resolution: int | None = None, out_dir: Path | None = None) -> Metrics:
        """Errors against the exact parabola (:func:`ginn.tasks.mirror.optics.evaluate_mirror`)."""
        return Metrics({"problem": "mirror", **evaluate_mirror(model, self.params)})

    def view(self, model: nn.Module, path: Path, steps: int = 64, title: str = "") -> Path:
        """The mirror's page (:func:`ginn.tasks.mirror.explorer.write_mirror_view`)."""
        return write_mirror_view(model, self.params, path, title=title)


def write_profile(model: nn.Module, params: MirrorParams, run_dir: Path) -> list[Path]:
    """Write the profile ``x, h(x), x^2/(4F)`` as ``mirror_profile.csv`` and ``mirror_profile.npy`` ``(n, 3)``."""
    p = params
    x, h = profile(model, p, p.n_eval)
    table = np.stack([x, h, x * x / (4.0 * p.focus)], axis=1)
    run_dir = Path(run_dir)
    csv, npy = run_dir / "mirror_profile.csv", run_dir / "mirror_profile.npy"
    np.savetxt(csv, table, delimiter=",", header="x,h,exact", comments="")
    np.save(npy, table)
    return [csv, npy]
