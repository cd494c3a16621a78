"""Shape extraction: a field on a grid, its zero contours (2D) and meshes (3D).

The shape is ``Omega = {f <= 0}`` restricted to the domain box ``X``.

* :func:`make_grid` builds a node grid over the domain (``resolution`` cells along the longest axis).
* :func:`sample_field` evaluates ``f(., z)`` at every grid node, in chunks. By default it is
  *adaptive*: the field is evaluated exactly on a coarse grid and, level by level, only in the
  cells that may contain the zero level set; elsewhere values are multilinear interpolations whose
  sign is still right. A cell is refined when ``min |f(corner)| <= safety * G * diag(cell) / 2``,
  where ``G`` is a local finite-difference slope: if ``|grad f| <= safety * G`` in the
  cell, a zero inside forces the nearest corner to ``|f| <= safety * G * diag / 2``, so no zero is
  missed. ``G`` is the largest slope along the edges of the cell and of its neighbours.
  At the last level only the cells that follow the surface are evaluated (``narrow_final``).
  ``adaptive=False`` evaluates every node (same result on the tests' random networks).
* :func:`extract_boundary` runs marching squares / marching cubes (scikit-image) on the values
  padded with a positive layer, so every contour and mesh is closed where the shape meets the
  domain boundary (watertight meshes); the cap vertices are snapped onto the box faces and flagged
  (``on_level_set`` False) because they do not lie on ``{f = 0}``.

Connectivity convention: the shape's grid nodes are face-connected (4-connectivity in 2D,
6-connectivity in 3D) in :func:`label_components`, and marching squares uses the matching saddle
rule (``fully_connected='high'``), so in 2D the contour and the labelling agree exactly. Marching
cubes (Lewiner) follows the trilinear interpolant, which agrees except in ambiguous cells.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np
import torch
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from torch import Tensor

from .fields import Field
from .geometry.base import Box

__all__ = [
    "Grid",
    "Boundary",
    "make_grid",
    "sample_field",
    "field_dtype_device",
    "extract_boundary",
    "label_components",
    "interpolate",
]


# --- grids ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Grid:
    """A node grid over a box: ``cells[a] + 1`` nodes along axis ``a`` including both faces.

    Attributes:
        lo, hi: box corners, ``(d,)`` float64 arrays.
        cells: number of cells per axis.
    """

    lo: np.ndarray
    hi: np.ndarray
    cells: tuple[int, ...]

    @property
    def dim(self) -> int:
        return len(self.cells)

    @property
    def shape(self) -> tuple[int, ...]:
        """Nodes per axis."""
        return tuple(c + 1 for c in self.cells)

    @property
    def spacing(self) -> np.ndarray:
        return (self.hi - self.lo) / np.asarray(self.cells, dtype=np.float64)

    @property
    def n_nodes(self) -> int:
        return int(np.prod(self.shape))

    def axis_coords(self, a: int) -> np.ndarray:
        return np.linspace(self.lo[a], self.hi[a], self.cells[a] + 1)

    def points(self, flat_index: np.ndarray | None = None) -> np.ndarray:
        """Node positions ``(n, d)`` for flat (C-order) node indices (all nodes when None)."""
        if flat_index is None:
            flat_index = np.arange(self.n_nodes)
        idx = np.unravel_index(flat_index, self.shape)
        return np.stack([self.lo[a] + idx[a] * self.spacing[a] for a in range(self.dim)], axis=-1)

    def to_index(self, x: np.ndarray) -> np.ndarray:
        """World coordinates ``(n, d)`` to fractional node indices ``(n, d)``."""
        return (np.asarray(x, dtype=np.float64) - self.lo) / self.spacing

    def node_weights(self) -> np.ndarray:
        """Trapezoid quadrature weights ``(shape)`` (float32): ``sum = vol(box)``; a set's volume is
        the sum of the weights of its nodes."""
        w = np.float32(np.prod(self.spacing)) * np.ones((), dtype=np.float32)
        for a in range(self.dim):
            wa = np.ones(self.shape[a], dtype=np.float32)
            wa[0] = wa[-1] = 0.5
            w = np.multiply.outer(w, wa)
        return np.ascontiguousarray(w)

    def coarsened(self, levels: int) -> "Grid":
        return Grid(self.lo, self.hi, tuple(c >> levels for c in self.cells))

    def extended(self, pad: int) -> "Grid":
        """The grid with ``pad`` more nodes beyond every face, same spacing."""
        h = self.spacing
        return Grid(self.lo - pad * h, self.hi + pad * h, tuple(c + 2 * pad for c in self.cells))


def make_grid(domain: Box, resolution: int) -> Grid:
    """A grid over ``domain`` with ``resolution`` cells along its longest axis and about the same
    spacing along the others (their cell counts rounded to multiples of 8 when ``resolution >= 64``
    so that adaptive sampling can coarsen them)."""
    lo = np.asarray(domain.lo, dtype=np.float64)
    hi = np.asarray(domain.hi, dtype=np.float64)
    ext = hi - lo
    if np.any(ext <= 0):
        raise ValueError(f"degenerate domain {domain}")
    resolution = int(resolution)
    if resolution < 2:
        raise ValueError("resolution must be at least 2")
    m = 8 if resolution >= 64 else 1
    cells = []
    for e in ext:
        c = resolution * e / ext.max()
        cells.append(resolution if e == ext.max() else max(m, int(round(c / m)) * m))
    return Grid(lo, hi, tuple(cells))


# --- sampling a field on a grid -------------------------------------------------------------------


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


def interpolate(values: np.ndarray, grid: Grid, x: np.ndarray) -> np.ndarray:
    """Multilinear interpolation of node ``values`` at points ``x (n, d)`` (clamped to the box)."""
    idx = grid.to_index(x)
    idx = np.clip(idx, 0, np.asarray(grid.cells, dtype=np.float64))
    return ndimage.map_coordinates(values, idx.T, order=1, mode="nearest")


def label_components(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """Face-connected components of a boolean node mask: ``(labels (0 = background), count)``.

    The labelling of :mod:`ginn.topology.components` (face connectivity, as its cubical PH)."""
    from .topology.components import label_components as _label

    return _label(mask, connectivity=1)


# --- boundaries: closed polylines (2D) and meshes (3D) ---------------------------------------------


def _closest_on_segments(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.einsum("...i,...i->...", p - a, ab) / np.maximum(np.einsum("...i,...i->...", ab, ab), 1e-300)
    return a + np.clip(t, 0.0, 1.0)[..., None] * ab


def _closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest points on triangles ``abc`` to points ``p`` (all broadcastable ``(..., 3)``).

    Delegates to :func:`ginn.geometry.mesh.closest_points_on_triangles` (rowwise, ``(n, 3)``).
    """
    from .geometry.mesh import closest_points_on_triangles

    p, a, b, c = np.broadcast_arrays(p, a, b, c)
    shape = p.shape
    flat = [np.ascontiguousarray(t, dtype=np.float64).reshape(-1, 3) for t in (p, a, b, c)]
    return closest_points_on_triangles(*flat).reshape(shape)


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
                c = _closest_on_segments(pp, V[el[..., 0]], V[el[..., 1]])
            else:
                c = _closest_on_triangles(np.broadcast_to(pp, el.shape[:2] + (3,)), V[el[..., 0]], V[el[..., 1]], V[el[..., 2]])
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
    from skimage import measure

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


def grid_volume(mask: np.ndarray, grid: Grid, weights: np.ndarray | None = None) -> float:
    """Trapezoid-rule volume of a node mask ``(grid.shape)``."""
    w = grid.node_weights() if weights is None else weights
    return float(w[mask].sum(dtype=np.float64))
