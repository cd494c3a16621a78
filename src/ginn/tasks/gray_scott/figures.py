"""Result files of a gray-scott run: patterns of the trained latents, a latent interpolation strip
(the paper's Figure 5) and the sampled fields as ``.npy`` arrays."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from .checks import sample_fields


def _save_image(A: np.ndarray, path: Path, vmin: float, vmax: float) -> None:
    """A grayscale-free colour PNG of ``A (h, w)`` via matplotlib's ``imsave`` (no axes)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    plt.imsave(path, A, cmap="viridis", vmin=vmin, vmax=vmax, origin="lower")


def interpolation_latents(Z: Tensor, steps: int) -> Tensor:
    """``steps`` latents on the segment from the first to the second trained latent, ``(steps, k)``
    (neighbours for evenly spaced 1D codes: the strip shows how one trained pattern morphs into the next)."""
    t = torch.linspace(0.0, 1.0, steps, dtype=Z.dtype, device=Z.device)[:, None]
    return (1 - t) * Z[0] + t * Z[1]


def write_patterns(model: nn.Module, Z: Tensor, run_dir: Path, resolution: int = 256, n_interp: int = 8) -> list[Path]:
    """Write ``patterns/u_{s:02d}.npy``, ``v_{s:02d}.npy`` (``(resolution, resolution)``, ``[i, j]`` at
    ``x = (i, j) / resolution``), ``patterns/v_{s:02d}.png`` for every latent, ``patterns_v.png`` (all
    latents side by side) and ``interpolation_v.png`` (a strip along the segment from the first to the second latent).

    Returns:
        the written paths.
    """
    out_dir = Path(run_dir) / "patterns"
    out_dir.mkdir(parents=True, exist_ok=True)
    W = sample_fields(model, Z, resolution)
    files: list[Path] = []
    vmin, vmax = float(W[:, 1].min()), float(W[:, 1].max())
    for s in range(W.shape[0]):
        for c, name in enumerate("uv"):
            f = out_dir / f"{name}_{s:02d}.npy"
            np.save(f, W[s, c])
            files.append(f)
        f = out_dir / f"v_{s:02d}.png"
        _save_image(W[s, 1], f, vmin, vmax)
        files.append(f)
    gap = np.full((resolution, max(2, resolution // 32)), np.nan)
    row = np.concatenate([x for s in range(W.shape[0]) for x in (W[s, 1], gap)][:-1], axis=1)
    f = Path(run_dir) / "patterns_v.png"
    _save_image(np.nan_to_num(row, nan=vmax), f, vmin, vmax)
    files.append(f)
    if Z.shape[0] >= 2 and Z.shape[1] > 0:
        Zi = interpolation_latents(Z, n_interp)
        Wi = sample_fields(model, Zi, resolution)
        row = np.concatenate([x for s in range(Wi.shape[0]) for x in (Wi[s, 1], gap)][:-1], axis=1)
        f = Path(run_dir) / "interpolation_v.png"
        _save_image(np.nan_to_num(row, nan=vmax), f, vmin, vmax)
        files.append(f)
    return files
