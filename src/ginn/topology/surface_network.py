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
an integral path), leaves the domain box, stalls (it oscillates around a zero of the gradient that
is not a known critical point: every reversal of direction halves its step, and it stops below
``h_min``) or runs out of steps; only the first kind gives an edge, but every path keeps its
*anchor*, the last point where it was inside the shape, which the connectedness loss uses to
attach paths that end in a component without a known vertex (one touching the domain boundary).

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
from ..geometry.base import Box, Region
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
        ascending: also trace the ascending paths (saddle -> maximum), as the paper does.
            Leaving them out halves the tracing but changes the loss: an ascending path from a
            saddle inside a shape to a maximum outside it is an edge of G_a from that component
            (on the trained obstacle, 16 shapes, the penalties differ at each of 3 full builds).
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

    Path-level arrays (``P`` paths, every path traced):

    Attributes:
        points: the vertices.
        path_start: saddle each path starts from ``(P,)`` (vertex index).
        path_end: vertex it reached ``(P,)``, -1 when it ended otherwise (see ``ends``).
        path_descending: ``(P,)`` bool: the path descends (towards a minimum).
        path_length: arc length ``(P,)``.
        path_outside_length: arc length where ``f > 0`` ``(P,)``.
        path_anchor: the last point of the path inside the shape (and inside the region given to
            the tracer) ``(P, d)``; NaN rows for paths that never were inside.
        ends: how each path ended ``(P,)`` (``END_*`` codes).
    """

    points: CriticalPoints
    path_start: np.ndarray
    path_end: np.ndarray
    path_descending: np.ndarray
    path_length: np.ndarray
    path_outside_length: np.ndarray
    path_anchor: np.ndarray
    ends: np.ndarray

    @property
    def n_paths(self) -> int:
        return int(len(self.path_start))

    @property
    def edges(self) -> np.ndarray:
        """``(E, 2)`` ``(saddle, end vertex)`` of the paths that reached a vertex."""
        ok = self.path_end >= 0
        return np.stack([self.path_start[ok], self.path_end[ok]], axis=1).astype(np.int64)

    def adjacency(self, weight: str = "length") -> sparse.csr_matrix:
        """Symmetric ``(m, m)`` sparse matrix of the edges weighted by ``"length"`` or
        ``"outside_length"`` (the smaller of parallel edges; a tiny positive floor keeps zero
        weights as edges)."""
        m = self.points.m
        ok = self.path_end >= 0
        w = np.maximum(getattr(self, "path_" + weight)[ok], 1e-12)
        u, v = self.path_start[ok], self.path_end[ok]
        dense = np.full((m, m), np.inf)
        np.minimum.at(dense, (u, v), w)
        np.minimum.at(dense, (v, u), w)
        dense[~np.isfinite(dense)] = 0.0
        return sparse.csr_matrix(dense)

    def with_shapes(self, sub: np.ndarray, net: SurfaceNetwork) -> tuple[SurfaceNetwork, np.ndarray, np.ndarray]:
        """This network with the shapes ``sub`` (``(k,)`` indices) replaced by ``net`` (their new
        network, shapes numbered ``0..k-1`` in the order of ``sub``): the vertices stay sorted by
        shape and the paths' vertex indices follow them.

        Returns:
            the network, the old vertices kept ``(q,)`` and the order ``(m,)`` that sorts the kept
            vertices followed by ``net``'s into the new ones (for per-vertex arrays).
        """
        old, new = self.points, net.points
        dev = old.shape.device
        gsub = torch.from_numpy(sub).to(dev)
        keep = ~np.isin(old.shape.cpu().numpy(), sub)
        kidx = np.nonzero(keep)[0]
        kt = torch.from_numpy(kidx).to(dev)
        fields = ("x", "f", "grad_norm", "eigvals", "eigvecs")
        cols = {k: torch.cat([getattr(old, k)[kt], getattr(new, k)]) for k in fields}
        shape = torch.cat([old.shape[kt], gsub[new.shape]])
        order = torch.argsort(shape, stable=True)
        m = int(shape.shape[0])
        pos = np.empty(m, dtype=np.int64)
        pos[order.cpu().numpy()] = np.arange(m)
        at = np.full(old.m, -1, dtype=np.int64)
        at[kidx] = np.arange(len(kidx))  # old vertex -> its row in the concatenation
        pk = keep[self.path_start] if self.n_paths else np.zeros(0, dtype=bool)

        def ends(e: np.ndarray, rows: np.ndarray) -> np.ndarray:
            return np.where(e >= 0, pos[rows[np.maximum(e, 0)]], -1)

        new_rows = len(kidx) + np.arange(new.m)
        pts = CriticalPoints(shape=shape[order], **{k: v[order] for k, v in cols.items()})
        cat = lambda a, b: np.concatenate([a, b])  # noqa: E731
        merged = SurfaceNetwork(
            pts,
            cat(pos[at[self.path_start[pk]]], pos[new_rows[net.path_start]]),
            cat(ends(self.path_end[pk], at), ends(net.path_end, new_rows)),
            cat(self.path_descending[pk], net.path_descending),
            cat(self.path_length[pk], net.path_length),
            cat(self.path_outside_length[pk], net.path_outside_length),
            cat(self.path_anchor[pk], net.path_anchor),
            cat(self.ends[pk], net.ends),
        )
        return merged, kidx, order.cpu().numpy()

    @staticmethod
    def empty(points: CriticalPoints) -> SurfaceNetwork:
        d = points.dim
        z = np.zeros(0)
        i = np.zeros(0, np.int64)
        return SurfaceNetwork(points, i, i.copy(), np.zeros(0, bool), z, z.copy(), np.zeros((0, d)), i.copy())


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
    region: Region | None = None,
    sources: Tensor | None = None,
) -> SurfaceNetwork:
    """Integral paths from every saddle of every shape, traced together.

    Arguments:
        field: ``(x, z) -> (n,)``.
        Z: latent codes ``(S, k)`` or None.
        box: the domain; paths leaving it end there.
        points: the critical points (vertices) of all shapes.
        grid: seed-grid cells along the longest axis (sets the length scale of ``options``).
        options: path settings.
        region: optional region (the design region E): anchors (last points inside the shape)
            must also lie in it.
        sources: optional ``(m,)`` bool over the vertices: only the saddles marked are traced
            from (None: every saddle). Every vertex still ends the paths that reach it.

    Returns:
        :class:`SurfaceNetwork`.
    """
    S = 1 if Z is None else Z.shape[0]
    d = points.dim
    h = cell_size(box, grid)
    dev, dt = points.x.device, points.x.dtype
    kind_index = points.index
    is_saddle = (kind_index > 0) & (kind_index < d)
    if sources is not None:
        is_saddle = is_saddle & sources.to(is_saddle.device)
    sad = torch.nonzero(is_saddle, as_tuple=False).squeeze(-1)
    if sad.numel() == 0:
        return SurfaceNetwork.empty(points)
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
    # anchor candidates (points inside the shape and the box), in the order they were reached;
    # which of them lie in the region is asked once, after the tracing
    cand_path, cand_x = [torch.nonzero(f0 <= 0).squeeze(-1)], [prev_pos[f0 <= 0]]
    # the first segment (saddle -> start point)
    seg = (pos - prev_pos).norm(dim=-1)
    cap, hmin, hmax = options.capture * h, options.h_min * h, options.h_max * h
    hcur = torch.full((P,), hmax, device=dev, dtype=dt)
    u_prev = dirs * sgn[:, None]  # the direction the path starts in (away from the saddle)
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
        now_in = (f <= 0) & ((p >= lo) & (p <= hi)).all(-1)
        cand_path.append(idx[now_in])
        cand_x.append(p[now_in])
        # capture
        dist = (p[:, None, :] - Xv[shape[idx]]).norm(dim=-1)  # (n, M)
        dist = torch.where(reach[idx], dist, torch.full_like(dist, float("inf")))
        dmin, arg = dist.min(dim=1)
        captured = dmin <= cap
        gnorm = g.norm(dim=-1)
        u = sgn[idx, None] * g / gnorm[:, None].clamp_min(1e-30)
        # a reversal of direction means the path overshot a zero of the gradient: halve the step
        rev = (u * u_prev[idx]).sum(-1) < 0
        hcur[idx[rev]] = hcur[idx[rev]] * 0.5
        stalled = ~captured & ((gnorm <= options.stall_tol) | (hcur[idx] < hmin))
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
        step = torch.minimum((0.5 * dmin[go]).clamp(min=hmin, max=hmax), hcur[gi])
        new = p[go] + step[:, None] * u[go]
        u_prev[gi] = u[go]
        seg[gi] = step
        pos[gi] = new
    anchor = _last_inside(torch.cat(cand_path), torch.cat(cand_x), P, region)
    return SurfaceNetwork(
        points,
        start_vertex.cpu().numpy().astype(np.int64),
        end.cpu().numpy().astype(np.int64),
        desc.cpu().numpy(),
        length.detach().cpu().double().numpy(),
        out_len.detach().cpu().double().numpy(),
        anchor.detach().cpu().double().numpy(),
        how.cpu().numpy(),
    )


def _fraction_positive(fa: Tensor, fb: Tensor) -> Tensor:
    """Fraction of a segment with ``f > 0`` when ``f`` goes linearly from ``fa`` to ``fb``."""
    both = (fa > 0) & (fb > 0)
    none = (fa <= 0) & (fb <= 0)
    denom = (fa - fb).abs().clamp_min(1e-30)
    mixed = torch.where(fa > 0, fa.clamp_min(0) / denom, fb.clamp_min(0) / denom).clamp(0, 1)
    return torch.where(both, torch.ones_like(fa), torch.where(none, torch.zeros_like(fa), mixed))


def _last_inside(path: Tensor, x: Tensor, P: int, region: Region | None) -> Tensor:
    """Each path's last candidate point inside ``region``, ``(P, d)`` (NaN rows for none).

    Arguments:
        path: the path of each candidate ``(c,)``, candidates in the order they were reached.
        x: the candidates ``(c, d)``.
        P: number of paths.
        region: the region (None: every candidate counts).
    """
    anchor = x.new_full((P, x.shape[1]), float("nan"))
    if region is not None and path.numel() > 0:
        keep = region.contains(x).to(x.device)
        path, x = path[keep], x[keep]
    if path.numel() == 0:
        return anchor
    order = torch.arange(path.numel(), device=path.device)
    last = torch.full((P,), -1, dtype=torch.long, device=path.device).scatter_reduce(0, path, order, "amax")
    has = last >= 0
    anchor[has] = x[last[has]]
    return anchor
