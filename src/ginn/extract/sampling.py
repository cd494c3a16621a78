"""A field on a grid: every node's value, exactly near the zero level set and interpolated elsewhere.

:func:`sample_field` evaluates ``f(., z)`` at every grid node, in chunks. By default it is
*adaptive*: the field is evaluated exactly on a coarse grid and, level by level, only in the
cells that may contain the zero level set; elsewhere values are multilinear interpolations whose
sign is still right. A cell is refined when ``min |f(corner)| <= safety * G * diag(cell) / 2``,
where ``G`` is a local finite-difference slope: if ``|grad f| <= safety * G`` in the
cell, a zero inside forces the nearest corner to ``|f| <= safety * G * diag / 2``, so no zero is
missed. ``G`` is the largest slope along the edges of the cell and of its neighbours.
At the last level only the cells that follow the surface are evaluated (``narrow_final``).
``adaptive=False`` evaluates every node (same result on the tests' random networks).
"""

from __future__ import annotations

from itertools import product

import numpy as np
import torch
from scipy import ndimage
from torch import Tensor

from ..fields import Field
from .grid import Grid

__all__ = ["sample_field", "field_dtype_device"]


def field_dtype_device(field: Field, z: Tensor | None = None) -> tuple[torch.dtype, torch.device]:
    """The dtype/device to feed ``field``: those of ``z``, else of the field's parameters, else
    float64 on the CPU (exact SDFs)."""
    if z is not None:
        return z.dtype, z.device
    if isinstance(field, torch.nn.Module):
        for p in field.parameters():
            return p.dtype, p.device
    return torch.float64, torch.device("cpu")


def _eval_nodes(field: Field, grid: Grid, flat: np.ndarray, z: Tensor | None, dtype, device, chunk: int) -> np.ndarray:
    out = np.empty(flat.shape[0], dtype=np.float64 if dtype == torch.float64 else np.float32)
    with torch.no_grad():
        for s in range(0, flat.shape[0], chunk):
            x = torch.as_tensor(grid.points(flat[s : s + chunk]), dtype=dtype, device=device)
            zz = None if z is None else z.reshape(1, -1).to(dtype=dtype, device=device).expand(x.shape[0], -1)
            out[s : s + chunk] = field(x, zz).detach().to("cpu").numpy()
    return out


def _corner_slices(cells: tuple[int, ...]):
    for off in product((0, 1), repeat=len(cells)):
        yield tuple(slice(o, o + c) for o, c in zip(off, cells))


def _upsample(v: np.ndarray) -> np.ndarray:
    """Multilinear 2x refinement of node values ``(n_a + 1, ...) -> (2 n_a + 1, ...)``."""
    for a in range(v.ndim):
        shape = list(v.shape)
        shape[a] = 2 * shape[a] - 1
        u = np.empty(shape, dtype=v.dtype)
        even = [slice(None)] * v.ndim
        odd = [slice(None)] * v.ndim
        even[a] = slice(0, None, 2)
        odd[a] = slice(1, None, 2)
        u[tuple(even)] = v
        lo = [slice(None)] * v.ndim
        hi = [slice(None)] * v.ndim
        lo[a] = slice(0, -1)
        hi[a] = slice(1, None)
        u[tuple(odd)] = 0.5 * (v[tuple(lo)] + v[tuple(hi)])
        v = u
    return v


def _cell_slopes(v: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Largest finite-difference slope ``|df| / h`` over the edges of each cell, ``(cells)``."""
    cells = tuple(n - 1 for n in v.shape)
    out = np.zeros(cells, dtype=v.dtype)
    for a in range(v.ndim):
        lo = [slice(None)] * v.ndim
        hi = [slice(None)] * v.ndim
        lo[a] = slice(0, -1)
        hi[a] = slice(1, None)
        e = np.abs(v[tuple(hi)] - v[tuple(lo)]) / h[a]  # edges along a: cells[a] x nodes elsewhere
        for off in product((0, 1), repeat=v.ndim - 1):
            sl, j = [], 0
            for b in range(v.ndim):
                if b == a:
                    sl.append(slice(None))
                else:
                    sl.append(slice(off[j], off[j] + cells[b]))
                    j += 1
            np.maximum(out, e[tuple(sl)], out=out)
    return out


def _corner_stats(v: np.ndarray, cells: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Per cell: min and max of the corner values, ``(cells)`` each."""
    cmin = cmax = None
    for sl in _corner_slices(cells):
        c = v[sl]
        if cmin is None:
            cmin, cmax = c.copy(), c.copy()
        else:
            np.minimum(cmin, c, out=cmin)
            np.maximum(cmax, c, out=cmax)
    return cmin, cmax


def sample_field(
    field: Field,
    grid: Grid,
    z: Tensor | None = None,
    *,
    adaptive: bool = True,
    safety: float = 2.0,
    final_safety: float = 1.0,
    narrow_final: bool = True,
    seed_margin: float = 0.5,
    min_coarse_cells: int = 8,
    chunk: int = 1 << 16,
    dtype: torch.dtype | None = None,
    device: torch.device | str | None = None,
) -> np.ndarray:
    """Values of ``field(., z)`` at every node of ``grid``.

    Arguments:
        field: callable ``(x, z) -> (n,)``.
        grid: the node grid.
        z: one latent code ``(k,)`` (or ``(1, k)``), or None.
        adaptive: evaluate exactly only near the zero level set (see the module docstring).
        safety: factor on the estimated gradient bound of the adaptive refinement (coarse levels,
            where a miss would lose a feature larger than the final spacing).
        final_safety: the factor for the last refinement (cells of twice the final spacing, whose
            corners are exact, so the local slope is a good bound; a miss there could only lose a
            feature smaller than about two cells).
        narrow_final: at the last level evaluate only the cells that follow the surface: the
            children of refined cells whose interpolated corners change sign or come within the
            threshold, then, repeatedly, every child whose corners change sign until all such
            corners are exact (instead of every node of every refined cell).
        seed_margin: the seeds of ``narrow_final`` are the children whose smallest interpolated
            ``|f|`` at a corner is at most ``seed_margin`` times the refinement threshold.
        min_coarse_cells: the coarsest adaptive level keeps at least this many cells per axis.
        chunk: points per forward pass.
        dtype, device: of the points fed to the field (default: :func:`field_dtype_device`).

    Returns:
        ``grid.shape`` array (float32 unless the field runs in float64) of values; exact where the
        sign could change, multilinearly interpolated (sign-correct) elsewhere.
    """
    dt, dev = field_dtype_device(field, z)
    dtype = dtype or dt
    device = torch.device(device) if device is not None else dev
    store = np.float64 if dtype == torch.float64 else np.float32
    levels = 0
    if adaptive:
        while all(c % (2 << levels) == 0 and (c >> (levels + 1)) >= min_coarse_cells for c in grid.cells):
            levels += 1
    g = grid.coarsened(levels)
    v = _eval_nodes(field, g, np.arange(g.n_nodes), z, dtype, device, chunk).reshape(g.shape)
    if levels == 0:
        return v.astype(store, copy=False)
    exact = np.ones(g.shape, dtype=bool)
    parent_active = np.ones(g.cells, dtype=bool)
    for lev in range(levels, 0, -1):
        h = g.spacing
        # local gradient bound: the largest slope over the cell and its neighbours
        slope = ndimage.maximum_filter(_cell_slopes(v, h), size=3, mode="nearest")
        fac = final_safety if lev == 1 else safety
        thr = fac * slope * (0.5 * float(np.linalg.norm(h)))
        absv = np.abs(v)
        cmin = None
        for sl in _corner_slices(g.cells):
            cmin = absv[sl] if cmin is None else np.minimum(cmin, absv[sl])
        active = parent_active & (cmin <= thr)
        # next level
        g = grid.coarsened(lev - 1)
        v = _upsample(v)
        ex = np.zeros(g.shape, dtype=bool)
        ex[tuple(slice(0, None, 2) for _ in g.cells)] = exact
        if lev == 1 and narrow_final:
            # children of the active cells: seed with those that may cross (interpolated values),
            # then follow the surface: evaluate the corners of every child with a sign change
            # until all of them are exact
            children = active
            sl_f = slope
            for a in range(g.dim):
                children = np.repeat(children, 2, axis=a)
                sl_f = np.repeat(sl_f, 2, axis=a)
            thr_f = final_safety * sl_f * (0.5 * float(np.linalg.norm(g.spacing)))
            cmin, cmax = _corner_stats(v, g.cells)
            # smallest |corner| of cells without a sign change (0 where the sign changes)
            amin = np.where(cmin > 0, cmin, np.where(cmax < 0, -cmax, 0))
            cand = children & (amin <= seed_margin * thr_f)
            del sl_f, thr_f, amin
            exact = ex
            for _ in range(64):
                need = np.zeros(g.shape, dtype=bool)
                for sl in _corner_slices(g.cells):
                    need[sl] |= cand
                need &= ~exact
                flat = np.flatnonzero(need)
                if flat.size == 0:
                    break
                v.reshape(-1)[flat] = _eval_nodes(field, g, flat, z, dtype, device, chunk)
                exact |= need
                cmin, cmax = _corner_stats(v, g.cells)
                all_exact = np.ones(g.cells, dtype=bool)
                for sl in _corner_slices(g.cells):
                    all_exact &= exact[sl]
                cand = children & (cmin <= 0) & (cmax > 0) & ~all_exact
            break
        need = np.zeros(g.shape, dtype=bool)
        for off in product((0, 1, 2), repeat=g.dim):
            need[tuple(slice(o, o + 2 * (c // 2), 2) for o, c in zip(off, g.cells))] |= active
        need &= ~ex
        flat = np.flatnonzero(need)
        if flat.size:
            v.reshape(-1)[flat] = _eval_nodes(field, g, flat, z, dtype, device, chunk)
        exact = ex | need
        if lev > 1:
            parent_active = active
            for a in range(g.dim):
                parent_active = np.repeat(parent_active, 2, axis=a)
    return v.astype(store, copy=False)
