"""Penalties of the surface-network connectedness loss (Appendix C.3, Algorithm 1) on one shape's graph.

Per shape (all numbers below are per shape; the batch loss is the *mean* over the ``S`` shapes,
so that its weight does not depend on the batch size):

1. **Components of the shape among the vertices.** A vertex is *inside* when ``f <= 0``. Because
   ``f`` is monotone along an integral path, a surface-network edge lies entirely inside the shape
   exactly when both its endpoints are inside; the components are the connected components of the
   inside vertices under those edges (``scipy.sparse.csgraph.connected_components``). By Morse
   theory every component of ``{f <= 0}`` contains a minimum, so inside groups without a minimum
   (paths lost at the domain boundary) are discarded.
2. **The augmented weighted graph G_a**, with every component contracted to one node (the
   paper's weight-0 edges within a component): surface-network edges between a component and an
   outside vertex, weighted by the part of the integral path that lies *outside* the shape (for
   an SDF this is the distance from the saddle to the boundary, so a two-edge path
   component-saddle-component has the length of the *gap between the boundaries*, which is the
   ``d`` of the paper's ``p ~ 1/d``); edges between two outside vertices (their path length);
   and the augmentation: an edge between every pair of outside vertices with their Euclidean
   distance.
3. **Penalties**: for every pair of components ``{c_i, c_j}`` the shortest path in G_a
   (``scipy.sparse.csgraph.dijkstra`` from every component node), of length ``d_ij``; every saddle
   on that path that is adjacent to a component on the path gets ``p_k += 1 / (d_ij + eps)``.
   Pairs with no path, or whose path has no such saddle, are counted in
   ``last_info["unreachable_pairs"]`` (the grid fallback below takes them). Then ``p`` is
   normalised to sum 1 (per shape).
4. **Loss** ``sum_k p_k f(x_k)`` with the saddle positions ``x_k`` held fixed (detached), so the
   gradient moves the field, not the points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from ..geometry.base import Box
from .critical import MINIMUM, SADDLE
from .surface_network import SurfaceNetwork

__all__ = ["Penalties", "ShapeGraph", "shape_components", "saddle_penalties", "grid_label_at", "batch_penalties"]


@dataclass
class Penalties:
    """Result of :func:`saddle_penalties` for one shape.

    Attributes:
        weights: normalised penalty per vertex ``(m,)`` (zeros when the shape is connected).
        n_components: number of components of the shape found.
        unreachable_pairs: component pairs the surface network cannot penalise: no path in G_a,
            or a shortest path with no saddle next to a component on it.
        labels: component of each vertex ``(m,)`` (-1 outside the shape or discarded).
        raw_total: sum of the penalties before normalisation (``weights * raw_total`` are the
            raw ``sum 1 / (d_ij + eps)``).
    """

    weights: np.ndarray
    n_components: int
    unreachable_pairs: int
    labels: np.ndarray
    raw_total: float = 0.0


@dataclass
class ShapeGraph:
    """The surface network of one shape in local indices (input of :func:`saddle_penalties`).

    Attributes:
        x: vertex positions ``(m, d)``; f: values ``(m,)``; kind: ``MINIMUM/SADDLE/MAXIMUM``
            ``(m,)``; valid: vertices kept (inside the design region) ``(m,)``.
        start, end: path endpoints ``(P,)`` (end -1: reached no vertex).
        length, outside_length: path arc lengths and their parts with ``f > 0`` ``(P,)``.
        end_label: grid component (1..n_grid, 0 none) at the path's anchor ``(P,)`` (used when
            the path reached no valid inside vertex).
        vertex_label: grid component at each vertex ``(m,)`` (0 none).
        n_grid: number of grid components (0 when the grid support is off).
    """

    x: np.ndarray
    f: np.ndarray
    kind: np.ndarray
    valid: np.ndarray
    start: np.ndarray
    end: np.ndarray
    length: np.ndarray
    outside_length: np.ndarray
    end_label: np.ndarray
    vertex_label: np.ndarray
    n_grid: int = 0


def shape_components(g: ShapeGraph) -> tuple[np.ndarray, np.ndarray, int]:
    """Components of ``{f <= 0}`` of one shape, from the surface network and the grid.

    Nodes are the vertices and the grid components; they are joined by (i) paths that start at an
    inside vertex and end at an inside vertex or (via its anchor) in a grid component (such a path
    never leaves the shape, ``f`` being monotone along it), and (ii) an inside vertex and the grid
    component at its position. A class is a component of the shape if it holds a grid component
    or an inside minimum (Morse: every component that does not touch the domain boundary has one).

    Returns:
        ``labels`` of the vertices ``(m,)`` (``0..C-1``; -1 outside/invalid/discarded), the
        component of each grid component ``(n_grid,)`` and ``C``.
    """
    m = g.f.shape[0]
    inside = (g.f <= 0) & g.valid
    n = m + g.n_grid
    ends = np.where((g.end >= 0) & inside[np.maximum(g.end, 0)], g.end, -1)
    ends = np.where((ends < 0) & (g.end_label > 0), m + g.end_label - 1, ends)
    link = inside[g.start] & (ends >= 0)
    u = [g.start[link]]
    v = [ends[link]]
    vl = inside & (g.vertex_label > 0)
    u.append(np.nonzero(vl)[0])
    v.append(m + g.vertex_label[vl] - 1)
    u, v = np.concatenate(u), np.concatenate(v)
    A = sparse.coo_matrix((np.ones(len(u)), (u, v)), shape=(n, n))
    _, lab = csgraph.connected_components(A, directed=False)
    member = np.concatenate([inside, np.ones(g.n_grid, dtype=bool)])
    anchor = np.concatenate([inside & (g.kind == MINIMUM), np.ones(g.n_grid, dtype=bool)])
    good = np.zeros(lab.max() + 1 if n else 0, dtype=bool)
    good[lab[anchor]] = True
    keep = np.unique(lab[member & good[lab]])
    remap = np.full(lab.max() + 1 if n else 0, -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    labels = np.where(member[:m], remap[lab[:m]], -1)
    return labels, remap[lab[m:]], int(len(keep))


def saddle_penalties(g: ShapeGraph, eps: float) -> Penalties:
    """Algorithm 1 on the augmented surface network of one shape.

    Arguments:
        g: :class:`ShapeGraph`.
        eps: the ``eps`` of ``1 / (d + eps)``.

    Returns:
        :class:`Penalties`.
    """
    m = g.f.shape[0]
    labels, grid_comp, C = shape_components(g)
    weights = np.zeros(m)
    if C <= 1:
        return Penalties(weights, C, 0, labels)
    outside = np.nonzero((g.f > 0) & g.valid)[0]
    node = np.full(m, -1, dtype=np.int64)
    node[labels >= 0] = labels[labels >= 0]
    node[outside] = C + np.arange(len(outside))
    N = C + len(outside)
    W = np.full((N, N), np.inf)
    if len(g.start):
        a = node[g.start]
        b = np.where(g.end >= 0, node[np.maximum(g.end, 0)], -1)
        via_anchor = (b < 0) & (g.end_label > 0)
        b = np.where(via_anchor, grid_comp[np.maximum(g.end_label - 1, 0)] if g.n_grid else -1, b)
        ok = (a >= 0) & (b >= 0) & (a != b)
        w = np.where((a >= C) & (b >= C), g.length, g.outside_length)
        w = np.maximum(w, 1e-12)
        np.minimum.at(W, (a[ok], b[ok]), w[ok])
        np.minimum.at(W, (b[ok], a[ok]), w[ok])
    if len(outside) > 1:
        xo = g.x[outside]
        D = np.linalg.norm(xo[:, None, :] - xo[None, :, :], axis=-1)
        np.fill_diagonal(D, np.inf)
        W[C:, C:] = np.minimum(W[C:, C:], np.maximum(D, 1e-12))
    W[~np.isfinite(W)] = 0.0
    dist, pred = csgraph.dijkstra(sparse.csr_matrix(W), directed=False, indices=np.arange(C), return_predecessors=True)
    is_saddle = np.zeros(N, dtype=bool)
    is_saddle[node[outside]] = g.kind[outside] == SADDLE
    vertex_of = np.full(N, -1, dtype=np.int64)
    vertex_of[node[outside]] = outside
    unreachable = 0
    for i in range(C):
        for j in range(i + 1, C):
            dij = dist[i, j]
            if not np.isfinite(dij):
                unreachable += 1
                continue
            path = [j]
            while path[-1] != i:
                path.append(int(pred[i, path[-1]]))
            path = np.asarray(path)
            comp = path < C
            adj = np.zeros(len(path), dtype=bool)
            adj[:-1] |= comp[1:]
            adj[1:] |= comp[:-1]
            hit = path[adj & ~comp & is_saddle[path]]
            if len(hit) == 0:  # joined only through maxima or path anchors: nothing to lower here
                unreachable += 1
                continue
            weights[vertex_of[hit]] += 1.0 / (dij + eps)
    total = weights.sum()
    if total > 0:
        weights /= total
    return Penalties(weights, C, unreachable, labels, float(total))


def grid_label_at(pos: np.ndarray, labels: np.ndarray, box: Box) -> np.ndarray:
    """Label of the nearest labelled node among the ``2^d`` corners of the grid cell of each
    position (0 if none, or for NaN positions).

    Arguments:
        pos: ``(n, d)``; labels: int grid ``(n_1, ..., n_d)`` over ``box`` (vertex grid).
    """
    n, d = pos.shape
    out = np.zeros(n, dtype=np.int64)
    ok = np.isfinite(pos).all(axis=1)
    if not ok.any():
        return out
    shape = np.asarray(labels.shape)
    lo, hi = np.asarray(box.lo, float), np.asarray(box.hi, float)
    u = (pos[ok] - lo) / (hi - lo) * (shape - 1)
    base = np.clip(np.floor(u).astype(np.int64), 0, shape - 2)
    corners = np.array(np.meshgrid(*[[0, 1]] * d, indexing="ij")).reshape(d, -1).T  # (2^d, d)
    nodes = base[:, None, :] + corners[None]  # (n, 2^d, d)
    lab = labels[tuple(nodes[..., i] for i in range(d))]  # (n, 2^d)
    dist = np.linalg.norm(nodes - u[:, None, :], axis=-1)
    dist = np.where(lab > 0, dist, np.inf)
    best = dist.argmin(axis=1)
    pick = lab[np.arange(len(best)), best]
    out[ok] = np.where(np.isfinite(dist.min(axis=1)), pick, 0)
    return out


def batch_penalties(
    net: SurfaceNetwork,
    valid: np.ndarray,
    n_shapes: int,
    eps: float,
    grid_labels: list[np.ndarray] | None = None,
    box: Box | None = None,
) -> tuple[np.ndarray, list[Penalties]]:
    """:func:`saddle_penalties` for every shape of a batch.

    Arguments:
        net: the surface network of all shapes.
        valid: vertices kept ``(m,)``.
        n_shapes: ``S``.
        eps: of ``1 / (d + eps)``.
        grid_labels: optional per-shape labelled grids of ``{f <= 0}`` (∩ E) over ``box``
            (:func:`ginn.extract.grid.label_components`), giving components that touch
            the domain or region boundary.

    Returns:
        the penalty of every vertex ``(m,)`` (normalised per shape) and the per-shape results.
    """
    pts = net.points
    x = pts.x.detach().cpu().double().numpy()
    f = pts.f.detach().cpu().double().numpy()
    kind = pts.kind.cpu().numpy()
    shape = pts.shape.cpu().numpy()
    p = np.zeros(pts.m)
    results = []
    path_shape = shape[net.path_start] if net.n_paths else np.zeros(0, np.int64)
    for s in range(n_shapes):
        vid = np.nonzero(shape == s)[0]
        local = np.full(pts.m + 1, -1, dtype=np.int64)
        local[vid] = np.arange(len(vid))
        ps = path_shape == s
        start = local[net.path_start[ps]]
        end = local[net.path_end[ps]]  # -1 maps to local[-1] == -1
        if grid_labels is not None:
            assert box is not None
            gl = grid_labels[s]
            n_grid = int(gl.max())
            end_label = grid_label_at(net.path_anchor[ps], gl, box)
            vertex_label = grid_label_at(x[vid], gl, box)
        else:
            n_grid = 0
            end_label = np.zeros(int(ps.sum()), np.int64)
            vertex_label = np.zeros(len(vid), np.int64)
        g = ShapeGraph(
            x[vid], f[vid], kind[vid], valid[vid], start, end,
            net.path_length[ps], net.path_outside_length[ps], end_label, vertex_label, n_grid,
        )
        r = saddle_penalties(g, eps)
        p[vid] = r.weights
        results.append(r)
    return p, results
