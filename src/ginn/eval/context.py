"""What the metrics of a problem share, computed once on the evaluation grid, and one shape on that grid.

:func:`prepare_context` gives the design-region masks, near-uniform samples of the design
region's boundary and the interface samples (:class:`MetricContext`); :func:`extract_shape`
samples a field on the grid, extracts its closed boundary and labels its components
(:class:`ExtractedShape`). The metrics themselves are :mod:`ginn.eval.metrics`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from ..extract.boundary import Boundary, extract_boundary
from ..extract.grid import Grid, label_components, make_grid
from ..extract.proximity import nodes_near
from ..extract.sampling import sample_field
from ..fields import Field, as_field
from ..geometry.base import Box, Region
from ..problems.problem import Problem

__all__ = ["MetricContext", "ExtractedShape", "prepare_context", "extract_shape", "near_interfaces"]


class _BoxRegion(Region):
    """The domain box as a region (the design region when a problem has none)."""

    def __init__(self, box: Box):
        self.box = box
        self.dim = box.dim

    def sdf(self, x: Tensor) -> Tensor:
        lo, hi = self.box.tensors(x.device, x.dtype)
        c, r = (lo + hi) / 2, (hi - lo) / 2
        q = (x - c).abs() - r
        return q.clamp_min(0).norm(dim=-1) + q.max(dim=-1).values.clamp_max(0)


def _region_sdf(region: Region, x: np.ndarray, chunk: int = 1 << 18) -> np.ndarray:
    out = np.empty(x.shape[0])
    with torch.no_grad():
        for s in range(0, x.shape[0], chunk):
            out[s : s + chunk] = region.sdf(torch.as_tensor(x[s : s + chunk], dtype=torch.float64)).double().numpy()
    return out


# --- context shared by all shapes of a problem ------------------------------------------------------


@dataclass
class MetricContext:
    """Everything about a problem that the metrics need, computed once on the evaluation grid.

    Attributes:
        problem: the problem.
        grid: the evaluation grid over the domain.
        weights: trapezoid node weights ``(grid.shape)`` (float32).
        in_design: ``(grid.shape)`` bool, node in E.
        counted_outside: ``(grid.shape)`` bool, node outside E and farther than the interface
            tolerance from every interface (``volume_outside_off_interfaces``).
        vol_design, vol_outside_design: vol(E) and vol(X \\ E).
        design_boundary_points: ``(m, d)`` near-uniform samples of dE, with
            ``design_boundary_weights`` ``(m,)``.
        interface_points: ``(q, d)`` interface samples; ``interface_component``: ``(q,)`` global
            component index; ``n_interface_components``: n_I.
        eps: the connection tolerance (0.01 * unit_scale).
    """

    problem: Problem
    grid: Grid
    weights: np.ndarray
    in_design: np.ndarray
    counted_outside: np.ndarray
    vol_design: float
    vol_outside_design: float
    design_boundary_points: np.ndarray
    design_boundary_weights: np.ndarray
    interface_points: np.ndarray
    interface_component: np.ndarray
    n_interface_components: int
    eps: float


def _design_boundary_samples(
    region: Region, grid: Grid, sdf_ext: np.ndarray, ext: Grid, n_max: int, rng
) -> tuple[np.ndarray, np.ndarray]:
    """Near-uniform samples of dE: band nodes ``|sdf| < h`` projected onto ``sdf = 0``, weighted by
    the hat function ``1 - |sdf| / h`` (hat functions sum to one along every grid line, so a face at
    any offset from the nodes gets the same total weight per area)."""
    h = float(grid.spacing.min())
    flat_sdf = sdf_ext.reshape(-1)
    band = np.flatnonzero(np.abs(flat_sdf) < h)
    if band.size == 0 or n_max <= 0:
        return np.zeros((0, grid.dim)), np.zeros(0)
    if band.size > n_max:
        band = np.sort(rng.choice(band, size=n_max, replace=False))
    w = 1.0 - np.abs(flat_sdf[band].astype(np.float64)) / h
    x = ext.points(band)
    step = 0.25 * h
    for _ in range(2):
        s0 = _region_sdf(region, x)
        g = np.empty_like(x)
        for a in range(grid.dim):
            e = np.zeros(grid.dim)
            e[a] = step
            g[:, a] = (_region_sdf(region, x + e) - _region_sdf(region, x - e)) / (2 * step)
        g2 = np.maximum((g * g).sum(1), 1e-12)
        x = x - (s0 / g2)[:, None] * g
    return x, w


def near_interfaces(problem: Problem, grid: Grid, among: np.ndarray) -> np.ndarray:
    """``(grid.shape)`` bool: the nodes of the mask ``among`` within the interface tolerance
    ``tolerances.interface * unit_scale`` of an interface (exact distances; an interface without
    :meth:`~ginn.geometry.base.Interface.distance` marks none)."""
    h = float(problem.tolerances.interface) * float(problem.unit_scale)
    return nodes_near(problem.interfaces, grid, among, h) if h > 0 else np.zeros(grid.shape, dtype=bool)


def prepare_context(
    problem: Problem,
    resolution: int,
    *,
    n_interface_samples: int = 4096,
    n_design_boundary_samples: int = 50_000,
    seed: int = 0,
) -> MetricContext:
    """Precompute the design-region masks, dE samples and interface samples for ``problem``.

    Arguments:
        problem: the problem (domain, design region, interfaces, unit scale).
        resolution: cells along the longest axis of the domain.
        n_interface_samples: interface samples, split between interfaces by measure.
        n_design_boundary_samples: at most this many samples of dE.
        seed: for the samples.
    """
    grid = make_grid(problem.domain, resolution)
    rng = np.random.default_rng(seed)
    region = problem.design_region if problem.design_region is not None else _BoxRegion(problem.domain)
    ext = grid.extended(4)
    # adaptive: exact |sdf_E| near dE (the band below is inside the refined cells), sign elsewhere
    sdf_ext = sample_field(as_field(region.sdf), ext, None, dtype=torch.float32, device="cpu")
    inner = tuple(slice(4, -4) for _ in range(grid.dim))
    in_design = sdf_ext[inner] <= 0
    weights = grid.node_weights()
    vol_E = float(weights[in_design].sum(dtype=np.float64))
    vol_out = float(weights[~in_design].sum(dtype=np.float64)) if problem.design_region is not None else 0.0
    dE, dE_w = _design_boundary_samples(region, grid, sdf_ext, ext, n_design_boundary_samples, rng)
    del sdf_ext
    counted_outside = ~in_design & ~near_interfaces(problem, grid, ~in_design)

    pts, comps = [], []
    offset = 0
    measures = [max(float(i.measure()), 0.0) for i in problem.interfaces]
    total = sum(measures)
    gen = torch.Generator().manual_seed(seed)
    for itf, m in zip(problem.interfaces, measures):
        n = max(16, int(round(n_interface_samples * (m / total if total > 0 else 1.0 / len(measures)))))
        x, _ = itf.sample(n, generator=gen, dtype=torch.float64)
        pts.append(x.double().cpu().numpy())
        comps.append(itf.component_of(x).cpu().numpy().astype(np.int64) + offset)
        offset += int(itf.n_components)
    ip = np.concatenate(pts) if pts else np.zeros((0, grid.dim))
    ic = np.concatenate(comps) if comps else np.zeros(0, dtype=np.int64)
    return MetricContext(
        problem=problem,
        grid=grid,
        weights=weights,
        in_design=in_design,
        counted_outside=counted_outside,
        vol_design=vol_E,
        vol_outside_design=vol_out,
        design_boundary_points=dE,
        design_boundary_weights=dE_w,
        interface_points=ip,
        interface_component=ic,
        n_interface_components=offset,
        eps=0.01 * float(problem.unit_scale),
    )


# --- one shape ----------------------------------------------------------------------------------------


@dataclass
class ExtractedShape:
    """One shape on the evaluation grid.

    Attributes:
        values: node values ``(grid.shape)``; ``inside = values <= 0``.
        boundary: the closed extracted boundary.
        labels: face-connected component labels of the inside nodes (0 = outside); ``n_labels``.
    """

    values: np.ndarray
    boundary: Boundary
    labels: np.ndarray
    n_labels: int

    @property
    def inside(self) -> np.ndarray:
        return self.values <= 0


def extract_shape(
    field: Field, z: Tensor | None, grid: Grid, *, adaptive: bool = True, timings: dict | None = None
) -> ExtractedShape:
    """Sample ``field(., z)`` on ``grid``, extract its closed boundary and label its components
    (``timings``, when given, receives the seconds of the three steps)."""
    t0 = time.perf_counter()
    values = sample_field(field, grid, z, adaptive=adaptive)
    t1 = time.perf_counter()
    boundary = extract_boundary(values, grid, close=True)
    t2 = time.perf_counter()
    labels, n = label_components(values <= 0)
    t3 = time.perf_counter()
    if timings is not None:
        for k, v in (("extract.sample_field", t1 - t0), ("extract.marching", t2 - t1), ("extract.label", t3 - t2)):
            timings[k] = timings.get(k, 0.0) + v
    return ExtractedShape(values, boundary, labels, n)


