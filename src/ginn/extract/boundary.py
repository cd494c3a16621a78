"""Shape boundaries: the zero contours (2D) and meshes (3D) of a field sampled on a grid.

The shape is ``Omega = {f <= 0}`` restricted to the domain box ``X``. :func:`extract_boundary`
runs marching squares / marching cubes (scikit-image) on the values padded with a positive layer,
so every contour and mesh is closed where the shape meets the domain boundary (watertight
meshes); the cap vertices are snapped onto the box faces and flagged (``on_level_set`` False)
because they do not lie on ``{f = 0}``.

Connectivity convention: marching squares uses the saddle rule (``fully_connected='high'``) that
matches the face-connected labelling of :func:`ginn.extract.grid.label_components`, so in 2D the
contour and the labelling agree exactly. Marching cubes (Lewiner) follows the trilinear
interpolant, which agrees except in ambiguous cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..geometry.mesh import closest_on_segments, closest_on_triangles
from .grid import Grid

__all__ = ["Boundary", "extract_boundary"]


@dataclass
class Boundary:
    """The boundary of an extracted shape: closed polylines (2D) or a triangle mesh (3D).

    Attributes:
        vertices: ``(n, d)`` float64 world coordinates.
        elements: ``(m, d)`` int64 vertex indices: segments (2D) or triangles (3D), oriented so
            that the shape is on the left of a segment / behind a triangle (outward orientation).
        on_level_set: ``(n,)`` bool; False for the cap vertices snapped onto the domain faces.
    """

    vertices: np.ndarray
    elements: np.ndarray
    on_level_set: np.ndarray

    _tree: cKDTree | None = None

    @property
    def dim(self) -> int:
        return self.vertices.shape[1]

    @property
    def n_elements(self) -> int:
        return int(self.elements.shape[0])

    def element_measures(self) -> np.ndarray:
        """Lengths (2D) or areas (3D) of the elements, ``(m,)``."""
        V, E = self.vertices, self.elements
        if self.dim == 2:
            return np.linalg.norm(V[E[:, 1]] - V[E[:, 0]], axis=1)
        return 0.5 * np.linalg.norm(np.cross(V[E[:, 1]] - V[E[:, 0]], V[E[:, 2]] - V[E[:, 0]]), axis=1)

    def measure(self) -> float:
        return float(self.element_measures().sum())

    def level_set_elements(self) -> np.ndarray:
        """Boolean ``(m,)``: elements whose vertices all lie on ``{f = 0}`` (not on a cap)."""
        return self.on_level_set[self.elements].all(axis=1)

    def signed_volume(self, elements: np.ndarray | None = None) -> float:
        """Enclosed area (2D) or volume (3D) of the (closed) boundary; positive for the shape."""
        V = self.vertices
        E = self.elements if elements is None else elements
        if E.shape[0] == 0:
            return 0.0
        c = V.mean(axis=0)  # reduces cancellation
        a, b = V[E[:, 0]] - c, V[E[:, 1]] - c
        if self.dim == 2:
            return float(0.5 * np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]))
        cc = V[E[:, 2]] - c
        return float(np.einsum("ij,ij->i", a, np.cross(b, cc)).sum() / 6.0)

    def components(self) -> tuple[np.ndarray, int]:
        """Connected components of the boundary graph: ``(label per element (m,), count)``."""
        n = self.vertices.shape[0]
        E = self.elements
        if E.shape[0] == 0:
            return np.zeros(0, dtype=np.int64), 0
        rows = np.concatenate([E[:, i] for i in range(E.shape[1])])
        cols = np.concatenate([E[:, (i + 1) % E.shape[1]] for i in range(E.shape[1])])
        A = coo_matrix((np.ones(rows.shape[0], dtype=np.int8), (rows, cols)), shape=(n, n))
        _, vlab = connected_components(A, directed=False)
        elab = vlab[E[:, 0]]
        uniq, elab = np.unique(elab, return_inverse=True)
        return elab.astype(np.int64), int(uniq.shape[0])

    def n_outer_components(self) -> int:
        """Number of boundary components enclosing a positive volume (outer shells, not cavities):
        the zeroth Betti number of the shape as seen by the contour / mesh."""
        lab, n = self.components()
        if n == 0:
            return 0
        V = self.vertices
        c = V.mean(axis=0)
        E = self.elements
        a, b = V[E[:, 0]] - c, V[E[:, 1]] - c
        if self.dim == 2:
            contrib = 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
        else:
            contrib = np.einsum("ij,ij->i", a, np.cross(b, V[E[:, 2]] - c)) / 6.0
        vol = np.bincount(lab, weights=contrib, minlength=n)
        return int(np.sum(vol > 0))

    def sample(self, n: int, rng: np.random.Generator, level_set_only: bool = False) -> np.ndarray:
        """``n`` points uniformly distributed by length/area on the boundary, ``(n, d)`` (empty when
        there is nothing to sample)."""
        w = self.element_measures()
        if level_set_only:
            w = w * self.level_set_elements()
        tot = w.sum()
        if n <= 0 or tot <= 0:
            return np.zeros((0, self.dim))
        e = rng.choice(self.n_elements, size=n, p=w / tot)
        V, E = self.vertices, self.elements[e]
        if self.dim == 2:
            t = rng.random(n)[:, None]
            return V[E[:, 0]] * (1 - t) + V[E[:, 1]] * t
        r1, r2 = rng.random(n), rng.random(n)
        s = np.sqrt(r1)
        return (
            V[E[:, 0]] * (1 - s)[:, None] + V[E[:, 1]] * (s * (1 - r2))[:, None] + V[E[:, 2]] * (s * r2)[:, None]
        )

    def polylines(self) -> list[np.ndarray]:
        """2D only: the boundary as polylines ``[(k_i, 2)]``, closed ones repeating their first
        vertex at the end (walks the segments of each component in order)."""
        if self.dim != 2:
            raise ValueError("polylines are for 2D boundaries")
        out = []
        E = self.elements
        if E.shape[0] == 0:
            return out
        nxt = np.full(self.vertices.shape[0], -1, dtype=np.int64)
        nxt[E[:, 0]] = E[:, 1]
        has_prev = np.zeros(self.vertices.shape[0], dtype=bool)
        has_prev[E[:, 1]] = True
        seen = np.zeros(self.vertices.shape[0], dtype=bool)
        starts = [v for v in E[:, 0] if not has_prev[v]] + list(E[:, 0])  # open chains first
        for s0 in starts:
            if seen[s0]:
                continue
            chain = [s0]
            seen[s0] = True
            v = nxt[s0]
            while v >= 0 and not seen[v]:
                chain.append(v)
                seen[v] = True
                v = nxt[v]
            if v == s0:
                chain.append(s0)
            out.append(self.vertices[np.asarray(chain)])
        return out

    def centroid_tree(self) -> cKDTree:
        if self._tree is None:
            self._tree = cKDTree(self.vertices[self.elements].mean(axis=1))
        return self._tree

    def distance(self, x: np.ndarray, k: int = 16, chunk: int = 8192) -> np.ndarray:
        """Euclidean distance from points ``x (q, d)`` to the boundary, ``(q,)``.

        The exact distance to the ``k`` elements with the nearest centroids (a KD-tree query): exact
        whenever the closest element is among them, and never more than one element diameter too
        large otherwise. ``inf`` when the boundary is empty.
        """
        x = np.asarray(x, dtype=np.float64)
        if self.n_elements == 0:
            return np.full(x.shape[0], np.inf)
        k = min(k, self.n_elements)
        tree = self.centroid_tree()
        V, E = self.vertices.astype(np.float64, copy=False), self.elements
        out = np.empty(x.shape[0])
        for s in range(0, x.shape[0], chunk):
            p = x[s : s + chunk]
            _, idx = tree.query(p, k=k)
            idx = idx.reshape(p.shape[0], k)
            el = E[idx]  # (q, k, d)
            pp = p[:, None, :]
            if self.dim == 2:
                c = closest_on_segments(pp, V[el[..., 0]], V[el[..., 1]])
            else:
                c = closest_on_triangles(np.broadcast_to(pp, el.shape[:2] + (3,)), V[el[..., 0]], V[el[..., 1]], V[el[..., 2]])
            out[s : s + chunk] = np.linalg.norm(c - pp, axis=-1).min(axis=1)
        return out


def _pad(values: np.ndarray) -> np.ndarray:
    p = float(np.max(np.abs(values))) if values.size else 1.0
    p = p if p > 0 else 1.0
    return np.pad(values.astype(np.float64, copy=False), 1, mode="constant", constant_values=p)


def extract_boundary(values: np.ndarray, grid: Grid, close: bool = True) -> Boundary:
    """Zero contour (2D, marching squares) or zero isosurface (3D, marching cubes) of node values.

    Arguments:
        values: ``grid.shape`` node values (shape = ``values <= 0``).
        grid: the grid they were sampled on.
        close: pad with a positive layer so the boundary is closed at the domain faces (caps are
            snapped onto the faces and flagged in ``on_level_set``).

    Returns:
        :class:`Boundary` (empty arrays when the level set is empty).
    """
    from skimage import measure  # scikit-image takes about a second to import; only extraction needs it

    d = grid.dim
    vol = _pad(values) if close else values.astype(np.float64, copy=False)
    off = 1.0 if close else 0.0
    if np.all(vol > 0) or np.all(vol < 0):
        return Boundary(np.zeros((0, d)), np.zeros((0, d), dtype=np.int64), np.zeros(0, dtype=bool))
    if d == 2:
        contours = measure.find_contours(vol, 0.0, fully_connected="high", positive_orientation="low")
        verts, elems, start = [], [], 0
        for c in contours:
            closed = len(c) > 2 and np.allclose(c[0], c[-1])
            pts = c[:-1] if closed else c
            k = len(pts)
            if k < 2:
                continue
            i = np.arange(k)
            seg = np.stack([i, (i + 1) % k], axis=1) if closed else np.stack([i[:-1], i[1:]], axis=1)
            verts.append(pts)
            elems.append(seg + start)
            start += k
        if not verts:
            return Boundary(np.zeros((0, 2)), np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=bool))
        P = np.concatenate(verts).astype(np.float64)
        F = np.concatenate(elems).astype(np.int64)
    elif d == 3:
        v, f, _, _ = measure.marching_cubes(vol, 0.0, method="lewiner", allow_degenerate=False)
        P = v.astype(np.float64)
        F = f.astype(np.int64)
    else:
        raise ValueError(f"extraction supports d = 2 or 3, got {d}")
    P = P - off
    n_max = np.asarray(grid.cells, dtype=np.float64)
    cap = np.any((P < 0) | (P > n_max), axis=1)
    P = np.clip(P, 0.0, n_max)
    X = grid.lo + P * grid.spacing
    return Boundary(X, F, ~cap)
