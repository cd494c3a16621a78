"""What a Gray-Scott run writes and reports: the patterns, the four independent checks, the explorer."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

from torch import Tensor, nn

from ...extract.grid import check_grid_memory
from ...train.task import Metrics, Results
from .checks import verify_run
from .explorer import write_pattern_explorer
from .figures import write_patterns

if TYPE_CHECKING:
    from .task import GrayScottTask

__all__ = ["GrayScottResults", "GrayScottMetrics"]


class GrayScottMetrics(Metrics):
    """``ginn eval`` of a Gray-Scott run (printed as JSON without the per-latent rows)."""

    def text(self) -> str:
        return json.dumps({k: v for k, v in self.items() if k != "latents"}, indent=2, default=float)


class GrayScottResults(Results):
    """The patterns, the four checks and the explorer of a trained :class:`GrayScottTask`."""

    kind = "gray-scott"

    def __init__(self, task: GrayScottTask):
        self.task = task

    def _latents(self) -> Tensor:
        return self.task.Z if self.task.Z is not None else self.task.default_latents()

    def finalize(self, model: nn.Module, run_dir: Path) -> list[Path]:
        p = self.task.params
        paths = write_patterns(model, self._latents(), Path(run_dir), p.resolution, p.n_interpolation)
        paths.append(self.view(model, Path(run_dir) / "figures" / "explorer.html", title=f"gray-scott: {Path(run_dir).name}"))
        return paths

    def evaluate(self, model: nn.Module, resolution: int | None = None, out_dir: Path | None = None) -> GrayScottMetrics:
        """The four independent checks of :func:`ginn.tasks.gray_scott.checks.verify_run` on every trained latent."""
        n = resolution or 256
        Z = self.task.latents()
        check_grid_memory(n * n * (1 if Z is None else Z.shape[0]), 160, f"resolution {n}")
        res = verify_run(model, Z, self.task.params, resolution=n, out_dir=out_dir)
        return GrayScottMetrics({"problem": "gray-scott", **res})

    def view(self, model: nn.Module, path: Path, steps: int = 64, title: str = "") -> Path:
        """The pattern explorer (:func:`ginn.tasks.gray_scott.explorer.write_pattern_explorer`)."""
        return write_pattern_explorer(model, self._latents(), self.task.params.gs, path, steps=steps, title=title)
