"""Small tensor helpers shared by the geometry modules (not public)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor


def as_f64(v, name: str = "value", shape: tuple[int, ...] | None = None) -> Tensor:
    """A float64 CPU tensor from a number / sequence / tensor; checks finiteness and shape.

    Raises:
        ValueError: non-finite entries or a shape mismatch.
    """
    if isinstance(v, Tensor):
        t = v.detach().to("cpu", torch.float64).clone()
    else:
        t = torch.from_numpy(np.array(v, dtype=np.float64))
    if not torch.isfinite(t).all():
        raise ValueError(f"{name} must be finite")
    if shape is not None and tuple(t.shape) != shape:
        raise ValueError(f"{name} must have shape {shape}, got {tuple(t.shape)}")
    return t


def unit(v, name: str = "vector") -> Tensor:
    """``v / |v|`` as float64; raises ValueError for a zero vector."""
    t = as_f64(v, name)
    n = t.norm()
    if n <= 1e-12:
        raise ValueError(f"{name} must be non-zero")
    return t / n


def like(t: Tensor, x: Tensor) -> Tensor:
    """``t`` on the device and in the dtype of ``x``."""
    return t.to(device=x.device, dtype=x.dtype)


def box_combine(q: Tensor) -> Tensor:
    """Exact SDF of an intersection of slabs from per-axis excesses ``q`` ``(n, k)``.

    ``|max(q, 0)| + min(max_i q_i, 0)``: the classic box formula, also used for capped cylinders and
    extrusions (with ``q = (in-plane sdf, |height| - h)``).
    """
    outside = q.clamp_min(0).norm(dim=-1)
    inside = q.max(dim=-1).values.clamp_max(0)
    return outside + inside


def orthonormal_frame(axis: Tensor) -> tuple[Tensor, Tensor]:
    """Two unit vectors ``(u, v)`` (float64, 3D) completing the unit ``axis`` to a right-handed frame."""
    a = axis / axis.norm()
    helper = torch.tensor([1.0, 0.0, 0.0], dtype=a.dtype) if abs(float(a[0])) < 0.9 else torch.tensor([0.0, 1.0, 0.0], dtype=a.dtype)
    u = torch.linalg.cross(a, helper)
    u = u / u.norm()
    v = torch.linalg.cross(a, u)
    return u, v


def rand(gen: torch.Generator | None, shape: Sequence[int], device, dtype) -> Tensor:
    """Uniform [0, 1) numbers drawn with ``gen`` (on the generator's device) then moved to ``device``."""
    gdev = gen.device if gen is not None else torch.device("cpu")
    r = torch.rand(tuple(shape), generator=gen, device=gdev, dtype=torch.float64 if dtype == torch.float64 else torch.float32)
    return r.to(device=device if device is not None else gdev, dtype=dtype)


def randn(gen: torch.Generator | None, shape: Sequence[int], device, dtype) -> Tensor:
    """Standard normal numbers drawn with ``gen`` then moved to ``device``/``dtype``."""
    gdev = gen.device if gen is not None else torch.device("cpu")
    r = torch.randn(tuple(shape), generator=gen, device=gdev, dtype=torch.float64 if dtype == torch.float64 else torch.float32)
    return r.to(device=device if device is not None else gdev, dtype=dtype)


def split_count(n: int, weights: Sequence[float]) -> list[int]:
    """Split ``n`` into non-negative integers proportional to ``weights`` (largest remainder; exact sum)."""
    w = torch.as_tensor(list(weights), dtype=torch.float64)
    if len(w) == 0:
        if n:
            raise ValueError("cannot split a positive count over no parts")
        return []
    if (w < 0).any() or not torch.isfinite(w).all() or w.sum() <= 0:
        raise ValueError("weights must be finite, non-negative and not all zero")
    share = w / w.sum() * n
    base = torch.floor(share).long()
    rest = n - int(base.sum())
    if rest > 0:
        order = torch.argsort(share - base, descending=True, stable=True)
        base[order[:rest]] += 1
    return [int(b) for b in base]
