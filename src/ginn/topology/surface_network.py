"""The surface network of a neural field (Appendix C.2, steps 3-4), for all shapes at once.

From every saddle ``s`` (Morse index ``1..d-1``) ``2 d`` integral paths start at ``x_s ± delta v_i``
for each Hessian eigenvector ``v_i``; a path along an eigenvector with a negative eigenvalue
*descends* (follows ``-grad f``, towards a minimum), one along a positive eigenvalue *ascends*
(``+grad f``, towards a maximum). All paths of all saddles of all shapes are integrated together,
one batched gradient evaluation per step, with explicit Euler steps along the normalised gradient
and an adaptive step length ``h = clip(0.5 * distance to the nearest reachable critical point,
h_min, h_max)`` (large steps far from every critical point, geometric approach near the end).

A path ends when it comes within ``capture`` of a critical point of its shape whose value lies
on the right side of the saddle's value (it cannot reach any other, since ``f`` is monotone along
an integral path), leaves the domain box, stalls (``|grad f|`` vanishes away from every known
critical point) or runs out of steps; only the first kind gives an edge.

Besides its endpoints, each edge records the path's arc length and the part of it that lies
*outside* the shape (``f > 0``, by linear interpolation of ``f`` between steps); the connectedness
loss uses the latter as the distance between a component and a saddle.

The graph is returned as a :class:`SurfaceNetwork` whose :meth:`SurfaceNetwork.adjacency` is a
``scipy.sparse`` matrix over the critical points (vertices) of all shapes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy import sparse
from torch import Tensor

from ..fields import Field, gradient
from ..geometry.base import Box
from .critical import CriticalPoints, cell_size, latents_of

END_VERTEX, END_LEFT_DOMAIN, END_STALLED, END_MAX_STEPS = 0, 1, 2, 3


@dataclass(frozen=True)
class PathOptions:
    """Settings of the integral-path tracing (lengths as fractions of a seed-grid cell).

    Attributes:
        start_offset: distance of a path's first point from its saddle.
        capture: a path ends at a critical point closer than this.
        h_min, h_max: bounds of the adaptive Euler step.
        max_steps: steps before a path is abandoned.
        ascending: also trace the ascending paths (saddle -> maximum). They do not change the
            connectedness loss (components are joined through descending paths), so leaving them
            out halves the cost; the paper traces both.
        stall_tol: ``|grad f|`` below which a path that is not near any known critical point stops.
    """

    start_offset: float = 0.2
    capture: float = 0.1
    h_min: float = 0.05
    h_max: float = 0.5
    max_steps: int = 200
    ascending: bool = True
    stall_tol: float = 1e-6


@dataclass
class SurfaceNetwork:
    """Critical points (vertices) and integral paths (edges) of all shapes.

    Attributes:
        points: the vertices.
        edges: ``(E, 2)`` int array ``(saddle, end vertex)``, vertex indices into ``points``.
        descending: ``(E,)`` bool: the path descends (towards a minimum).
        length: arc length of each path ``(E,)``.
        outside_length: arc length where ``f > 0`` ``(E,)``.
        n_paths: number of paths traced; ``ends``: ``(P,)`` how each ended (``END_*`` codes).
    """

    points: CriticalPoints
    edges: np.ndarray
    descending: np.ndarray
    length: np.ndarray
    outside_length: np.ndarray
    n_paths: int
    ends: np.ndarray

    def adjacency(self, weight: str = "length") -> sparse.csr_matrix:
        """Symmetric ``(m, m)`` sparse matrix of the edges weighted by ``length`` or
        ``outside_length`` (the smaller of parallel edges; a tiny positive floor keeps zero
        weights as edges)."""
        m = self.points.m
        w = np.maximum(getattr(self, weight), 1e-12)
        u, v = self.edges[:, 0], self.edges[:, 1]
        dense = np.full((m, m), np.inf)
        np.minimum.at(dense, (u, v), w)
        np.minimum.at(dense, (v, u), w)
        dense[~np.isfinite(dense)] = 0.0
        return sparse.csr_matrix(dense)


def _padded_points(points: CriticalPoints, S: int) -> tuple[Tensor, Tensor, Tensor]:
    """Per-shape padded vertex table: positions ``(S, M, d)``, values ``(S, M)`` (NaN padding) and
    global indices ``(S, M)`` (-1 padding)."""
    m, d = points.m, points.dim
    counts = torch.bincount(points.shape, minlength=S)
    M = max(int(counts.max()) if m > 0 else 0, 1)
    start = torch.cumsum(counts, 0) - counts
    order = torch.argsort(points.shape, stable=True)
    slot = torch.arange(m, device=points.x.device) - start[points.shape[order]]
    X = points.x.new_full((S, M, d), float("nan"))
    F = points.x.new_full((S, M), float("nan"))
    I = torch.full((S, M), -1, dtype=torch.long, device=points.x.device)
    X[points.shape[order], slot] = points.x[order]
    F[points.shape[order], slot] = points.f[order]
    I[points.shape[order], slot] = order
    return X, F, I


def trace_surface_network(
    field: Field,
    Z: Tensor | None,
    box: Box,
    points: CriticalPoints,
    grid: int = 16,
    options: PathOptions = PathOptions(),
) -> SurfaceNetwork:
    """Integral paths from every saddle of every shape, traced together.

    Arguments:
        field: ``(x, z) -> (n,)``.
        Z: latent codes ``(S, k)`` or None.
        box: the domain; paths leaving it end there.
        points: the critical points (vertices) of all shapes.
        grid: seed-grid cells along the longest axis (sets the length scale of ``options``).
        options: path settings.

    Returns:
        :class:`SurfaceNetwork`.
    """
    S = 1 if Z is None else Z.shape[0]
    d = points.dim
    h = cell_size(box, grid)
    dev, dt = points.x.device, points.x.dtype
    kind_index = points.index
    sad = torch.nonzero((kind_index > 0) & (kind_index < d), as_tuple=False).squeeze(-1)
    empty = SurfaceNetwork(points, np.zeros((0, 2), np.int64), np.zeros(0, bool), np.zeros(0), np.zeros(0), 0, np.zeros(0, np.int64))
    if sad.numel() == 0:
        return empty
    # start points: saddle x eigenvector x sign
    lam = points.eigvals[sad]  # (n_s, d)
    V = points.eigvecs[sad]  # (n_s, d, d) columns
    signs = torch.tensor([1.0, -1.0], device=dev, dtype=dt)
    start_vertex = sad[:, None, None].expand(-1, d, 2)
    dirs = V.transpose(1, 2)[:, :, None, :] * signs[None, None, :, None]  # (n_s, d, 2, d)
    desc = (lam < 0)[:, :, None].expand(-1, -1, 2)
    sel = torch.ones_like(desc) if options.ascending else desc
    start_vertex, dirs, desc = start_vertex[sel], dirs[sel], desc[sel]
    pos = points.x[start_vertex] + options.start_offset * h * dirs
    P = pos.shape[0]
    shape = points.shape[start_vertex]
    z_all = latents_of(Z, shape)
    sgn = torch.where(desc, -1.0, 1.0).to(dt)  # follow sgn * grad f
    Xv, Fv, Iv = _padded_points(points, S)
    f0 = points.f[start_vertex]
    # reachable end vertices: strictly lower (descending) / higher (ascending) value than the saddle
    Fp = Fv[shape]  # (P, M)
    reach = torch.where(desc[:, None], Fp < f0[:, None], Fp > f0[:, None]) & (Iv[shape] != start_vertex[:, None])
    lo, hi = box.tensors(dev, dt)
    end = torch.full((P,), -1, dtype=torch.long, device=dev)
    how = torch.full((P,), END_MAX_STEPS, dtype=torch.long, device=dev)
    length = torch.zeros(P, device=dev, dtype=dt)
    out_len = torch.zeros(P, device=dev, dtype=dt)
    f_prev = f0.clone()
    prev_pos = points.x[start_vertex].clone()
    alive = torch.ones(P, dtype=torch.bool, device=dev)
    # the first segment (saddle -> start point)
    seg = (pos - prev_pos).norm(dim=-1)
    cap, hmin, hmax = options.capture * h, options.h_min * h, options.h_max * h
    for _ in range(options.max_steps):
        idx = torch.nonzero(alive, as_tuple=False).squeeze(-1)
        if idx.numel() == 0:
            break
        p = pos[idx]
        f, g = gradient(field, p, None if z_all is None else z_all[idx])
        # bookkeeping of the segment that just ended at p
        fa, fb = f_prev[idx], f
        frac_out = _fraction_positive(fa, fb)
        length[idx] += seg[idx]
        out_len[idx] += seg[idx] * frac_out
        f_prev[idx] = f
        # capture
        dist = (p[:, None, :] - Xv[shape[idx]]).norm(dim=-1)  # (n, M)
        dist = torch.where(reach[idx], dist, torch.full_like(dist, float("inf")))
        dmin, arg = dist.min(dim=1)
        captured = dmin <= cap
        gnorm = g.norm(dim=-1)
        stalled = ~captured & (gnorm <= options.stall_tol)
        out = ~((p >= lo) & (p <= hi)).all(-1) & ~captured
        ci = idx[captured]
        end[ci] = Iv[shape[ci], arg[captured]]
        how[ci] = END_VERTEX
        # close the path with the last little segment to the vertex
        last = dmin[captured]
        length[ci] += last
        out_len[ci] += last * _fraction_positive(f[captured], Fv[shape[ci], arg[captured]])
        how[idx[out]] = END_LEFT_DOMAIN
        how[idx[stalled]] = END_STALLED
        alive[idx[captured | out | stalled]] = False
        go = ~(captured | out | stalled)
        gi = idx[go]
        step = (0.5 * dmin[go]).clamp(min=hmin, max=hmax)
        u = sgn[gi, None] * g[go] / gnorm[go, None].clamp_min(1e-30)
        new = p[go] + step[:, None] * u
        seg[gi] = step
        pos[gi] = new
    ok = (how == END_VERTEX).cpu().numpy()
    sv = start_vertex.cpu().numpy()
    edges = np.stack([sv[ok], end.cpu().numpy()[ok]], axis=1).astype(np.int64)
    return SurfaceNetwork(
        points,
        edges,
        desc.cpu().numpy()[ok],
        length.detach().cpu().double().numpy()[ok],
        out_len.detach().cpu().double().numpy()[ok],
        P,
        how.cpu().numpy(),
    )


def _fraction_positive(fa: Tensor, fb: Tensor) -> Tensor:
    """Fraction of a segment with ``f > 0`` when ``f`` goes linearly from ``fa`` to ``fb``."""
    both = (fa > 0) & (fb > 0)
    none = (fa <= 0) & (fb <= 0)
    denom = (fa - fb).abs().clamp_min(1e-30)
    mixed = torch.where(fa > 0, fa.clamp_min(0) / denom, fb.clamp_min(0) / denom).clamp(0, 1)
    return torch.where(both, torch.ones_like(fa), torch.where(none, torch.zeros_like(fa), mixed))
