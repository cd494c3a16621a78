"""Mesh-backed regions and interfaces (STL / OBJ / PLY via trimesh).

* :func:`load_mesh`: read a triangle mesh, optionally normalised ``p -> (p - center) / scale``.
* :class:`MeshRegion`: a watertight mesh as a solid. ``contains`` is a ray-parity test (a vertical
  ray per point, triangles bucketed on an xy grid, fully vectorised numpy); ``sdf`` is
  **approximate**: its magnitude is the exact distance to the nearest of the candidate triangles
  found through a KD-tree on dense surface samples (exact unless the true nearest triangle has no
  sample among the ``k`` nearest), its sign comes from ``contains``. Evaluated on the CPU in numpy
  and moved to the points' device/dtype; not differentiable w.r.t. ``x``.
* :class:`MeshInterface`: a mesh surface as an interface: area-uniform samples with face normals
  (optionally flipped), components = connected components of the mesh.

No spatial-index package beyond SciPy is needed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from torch import Tensor

from ._tensor import rand
from .base import Interface, Region


def load_mesh(path, center=None, scale: float | None = None):
    """Load a triangle mesh with trimesh and normalise it.

    Arguments:
        path: STL / OBJ / PLY / ... file.
        center: subtracted from the vertices (``(3,)`` or None).
        scale: the vertices are divided by it after centring (None: 1).

    Returns:
        ``trimesh.Trimesh`` (a new object).

    Raises:
        ValueError: the file does not exist, cannot be read as a mesh, or has no triangles.
    """
    import trimesh

    p = Path(path)
    if not p.is_file():
        raise ValueError(f"file not found: {p}")
    try:
        mesh = trimesh.load(str(p), force="mesh", process=True)
    except Exception as e:  # trimesh raises many types for unreadable files
        raise ValueError(f"cannot read {p.name} as a mesh ({type(e).__name__})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"{p.name} is not a triangle mesh (no faces)")
    v = np.asarray(mesh.vertices, dtype=np.float64)
    if center is not None:
        v = v - np.asarray(center, dtype=np.float64).reshape(1, 3)
    if scale is not None:
        if not (np.isfinite(scale) and scale > 0):
            raise ValueError("scale must be > 0")
        v = v / float(scale)
    return trimesh.Trimesh(vertices=v, faces=np.asarray(mesh.faces), process=False)


def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest point of triangle ``(a, b, c)`` to ``p``, rowwise; all ``(n, 3)`` float64.

    Ericson, Real-Time Collision Detection, 5.1.5 (Voronoi regions of vertices, edges, face).
    """

    def dot(u, v):
        return np.einsum("ij,ij->i", u, v)

    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp = p - b
    d3, d4 = dot(ab, bp), dot(ac, bp)
    cp = p - c
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        v_ab = np.nan_to_num(d1 / (d1 - d3))
        w_ac = np.nan_to_num(d2 / (d2 - d6))
        w_bc = np.nan_to_num((d4 - d3) / ((d4 - d3) + (d5 - d6)))
        denom = va + vb + vc
        v_in = np.nan_to_num(vb / denom)
        w_in = np.nan_to_num(vc / denom)
    conds = [
        (d1 <= 0) & (d2 <= 0),
        (d3 >= 0) & (d4 <= d3),
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),
        (d6 >= 0) & (d5 <= d6),
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),
        (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0),
    ]
    choices = [a, b, a + v_ab[:, None] * ab, c, a + w_ac[:, None] * ac, b + w_bc[:, None] * (c - b)]
    inside = a + v_in[:, None] * ab + w_in[:, None] * ac
    out = inside.copy()
    done = np.zeros(len(p), dtype=bool)
    for cond, ch in zip(conds, choices):
        m = cond & ~done
        out[m] = ch[m]
        done |= m
    return out


def closest_on_segments(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Closest points on segments ``ab`` to points ``p`` (all broadcastable ``(..., d)``)."""
    ab = b - a
    t = np.einsum("...i,...i->...", p - a, ab) / np.maximum(np.einsum("...i,...i->...", ab, ab), 1e-300)
    return a + np.clip(t, 0.0, 1.0)[..., None] * ab


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest points on triangles ``abc`` to points ``p`` (all broadcastable ``(..., 3)``).

    Broadcasting form of :func:`closest_points_on_triangles` (rowwise, ``(n, 3)``).
    """
    p, a, b, c = np.broadcast_arrays(p, a, b, c)
    shape = p.shape
    flat = [np.ascontiguousarray(t, dtype=np.float64).reshape(-1, 3) for t in (p, a, b, c)]
    return closest_points_on_triangles(*flat).reshape(shape)



class _RayParity:
    """Inside test for a closed triangle mesh: parity of crossings of the ray ``+z`` from each point.

    Triangles (their xy projections) are bucketed on a ``G x G`` grid; the query points are
    shifted by a fixed tiny irrational offset so that rays through mesh vertices/edges (e.g. from
    grid-aligned points) are practically impossible.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, grid: int | None = None, chunk_pairs: int = 4_000_000):
        tri = vertices[faces]  # (F, 3, 3)
        xy = tri[:, :, :2]
        e1, e2 = xy[:, 1] - xy[:, 0], xy[:, 2] - xy[:, 0]
        area2 = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        span = float(np.ptp(vertices[:, :2], axis=0).max()) or 1.0
        keep = np.abs(area2) > 1e-14 * span * span  # vertical triangles never cross a vertical ray
        self.tri = tri[keep]
        self.lo = vertices[:, :2].min(0)
        self.hi = vertices[:, :2].max(0)
        self.shift = np.array([0.7071067811865476e-9, 0.3183098861837907e-9]) * span
        nf = len(self.tri)
        g = grid or int(np.clip(np.sqrt(max(nf, 1)) / 1.5, 4, 256))
        self.g = g
        self.cell = (self.hi - self.lo) / g + 1e-300
        flo = self.tri[:, :, :2].min(1)
        fhi = self.tri[:, :, :2].max(1)
        i0 = np.clip(((flo - self.lo) / self.cell).astype(np.int64), 0, g - 1)
        i1 = np.clip(((fhi - self.lo) / self.cell).astype(np.int64), 0, g - 1)
        nx, ny = i1[:, 0] - i0[:, 0] + 1, i1[:, 1] - i0[:, 1] + 1
        counts = nx * ny
        face = np.repeat(np.arange(nf), counts)
        start = np.cumsum(counts) - counts
        local = np.arange(counts.sum()) - np.repeat(start, counts)
        cx = i0[face, 0] + local % nx[face]
        cy = i0[face, 1] + local // nx[face]
        cell_id = cx * g + cy
        order = np.argsort(cell_id, kind="stable")
        self.cell_faces = face[order]
        per_cell = np.bincount(cell_id, minlength=g * g)
        self.cell_start = np.cumsum(per_cell) - per_cell
        self.cell_count = per_cell
        self.chunk_pairs = chunk_pairs

    def contains(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=np.float64)
        out = np.zeros(len(q), dtype=bool)
        qxy = q[:, :2] + self.shift
        inb = np.all((qxy >= self.lo) & (qxy <= self.hi), axis=1)
        idx = np.nonzero(inb)[0]
        if len(idx) == 0:
            return out
        c = np.clip(((qxy[idx] - self.lo) / self.cell).astype(np.int64), 0, self.g - 1)
        cid = c[:, 0] * self.g + c[:, 1]
        cnt = self.cell_count[cid]
        # process in chunks so that the (point, triangle) pair arrays stay bounded
        ends = np.cumsum(cnt)
        s = 0
        while s < len(idx):
            base = ends[s - 1] if s > 0 else 0
            e = int(np.searchsorted(ends, base + self.chunk_pairs, side="right"))
            e = max(e, s + 1)
            out[idx[s:e]] = self._parity(qxy[idx[s:e]], q[idx[s:e], 2], cid[s:e], cnt[s:e])
            s = e
        return out

    def _parity(self, qxy, qz, cid, cnt):
        n = len(qxy)
        total = int(cnt.sum())
        if total == 0:
            return np.zeros(n, dtype=bool)
        pq = np.repeat(np.arange(n), cnt)
        start = np.cumsum(cnt) - cnt
        local = np.arange(total) - np.repeat(start, cnt)
        pf = self.cell_faces[np.repeat(self.cell_start[cid], cnt) + local]
        t = self.tri[pf]  # (P, 3, 3)
        p = qxy[pq]
        p0, p1, p2 = t[:, 0, :2], t[:, 1, :2], t[:, 2, :2]

        def cross(o, a, b):
            return (a[:, 0] - o[:, 0]) * (b[:, 1] - o[:, 1]) - (a[:, 1] - o[:, 1]) * (b[:, 0] - o[:, 0])

        w0 = cross(p1, p2, p)  # opposite vertex 0
        w1 = cross(p2, p0, p)
        w2 = cross(p0, p1, p)
        inside = ((w0 > 0) & (w1 > 0) & (w2 > 0)) | ((w0 < 0) & (w1 < 0) & (w2 < 0))
        tot = w0 + w1 + w2
        with np.errstate(divide="ignore", invalid="ignore"):
            z = (w0 * t[:, 0, 2] + w1 * t[:, 1, 2] + w2 * t[:, 2, 2]) / tot
        hit = inside & (z > qz[pq])
        return (np.bincount(pq[hit], minlength=n) % 2) == 1


class _SurfaceDistance:
    """Approximate unsigned distance to a triangle mesh.

    A KD-tree over *sites* (every face's centroid, edge midpoints and vertices, each tagged with
    its face, plus extra area-uniform samples on large faces) gives ``k`` candidate triangles per
    query; the exact point-triangle distance picks the nearest of them.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, n_extra: int | None = None, k: int = 8, seed: int = 0):
        self.tri = vertices[faces]
        nf = len(faces)
        t = self.tri
        sites = [t.mean(1), t[:, 0], t[:, 1], t[:, 2], (t[:, 0] + t[:, 1]) / 2, (t[:, 1] + t[:, 2]) / 2, (t[:, 2] + t[:, 0]) / 2]
        site_face = [np.arange(nf)] * len(sites)
        areas = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
        n = n_extra if n_extra is not None else 2 * nf
        if n > 0 and areas.sum() > 0:
            rng = np.random.default_rng(seed)
            f = rng.choice(nf, size=n, p=areas / areas.sum())
            r1, r2 = rng.random(n), rng.random(n)
            s = np.sqrt(r1)
            sites.append((1 - s)[:, None] * t[f, 0] + (s * (1 - r2))[:, None] * t[f, 1] + (s * r2)[:, None] * t[f, 2])
            site_face.append(f)
        self.sample_face = np.concatenate(site_face)
        self.tree = cKDTree(np.concatenate(sites), balanced_tree=False, compact_nodes=False)
        self.k = min(k, len(self.sample_face))
        self.ring = self._face_ring(np.asarray(faces, dtype=np.int64))

    def _face_ring(self, faces: np.ndarray) -> np.ndarray:
        """Faces sharing a vertex with each face ``(F, m)``, padded with the face itself."""
        f = faces
        nf = len(f)
        inc_f = np.repeat(np.arange(nf), 3)
        inc_v = f.reshape(-1)
        order = np.argsort(inc_v, kind="stable")
        inc_v, inc_f = inc_v[order], inc_f[order]
        nv = int(f.max()) + 1
        cnt = np.bincount(inc_v, minlength=nv)
        start = np.cumsum(cnt) - cnt
        width = int(cnt.max())
        vf = np.repeat(np.arange(nv), cnt)
        col = np.arange(len(inc_v)) - start[vf]
        table = np.full((nv, width), -1, dtype=np.int64)
        table[inc_v, col] = inc_f
        ring = table[f].reshape(nf, 3 * width)
        own = np.broadcast_to(np.arange(nf)[:, None], ring.shape)
        return np.where(ring < 0, own, ring)

    def _nearest_among(self, q: np.ndarray, cand: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n, k = cand.shape
        flat = cand.reshape(-1)
        qq = np.repeat(q, k, axis=0)
        t = self.tri[flat]
        cp = closest_points_on_triangles(qq, t[:, 0], t[:, 1], t[:, 2])
        d = np.linalg.norm(qq - cp, axis=1).reshape(n, k)
        best = d.argmin(1)
        rows = np.arange(n)
        return d[rows, best], cand[rows, best]

    def query(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(distance (n,), nearest face index (n,))``.

        Candidates: the faces of the ``k`` nearest sites, then the vertex one-ring of the best face
        so far, repeated (up to 3 times) while the best face changes (a local descent over the mesh).
        """
        q = np.asarray(q, dtype=np.float64)
        if len(q) == 0:
            return np.zeros(0), np.zeros(0, dtype=np.int64)
        step = max(1, 2_000_000 // max(self.k, self.ring.shape[1]))  # bound the pair arrays
        d = np.empty(len(q))
        face = np.empty(len(q), dtype=np.int64)
        for s in range(0, len(q), step):
            qs = q[s : s + step]
            _, j = self.tree.query(qs, k=self.k)
            ds, fs = self._nearest_among(qs, self.sample_face[j.reshape(len(qs), self.k)])
            todo = np.arange(len(qs))
            for _ in range(3):  # descend over neighbouring triangles while the best face changes
                d2, f2 = self._nearest_among(qs[todo], self.ring[fs[todo]])
                moved = f2 != fs[todo]
                ds[todo], fs[todo] = d2, f2
                todo = todo[moved]
                if len(todo) == 0:
                    break
            d[s : s + step], face[s : s + step] = ds, fs
        return d, face


def _to_numpy(x: Tensor) -> np.ndarray:
    return x.detach().to("cpu", torch.float64).numpy()


class MeshRegion(Region):
    """A watertight triangle mesh as a solid region (see the module docstring for the accuracy).

    Arguments:
        mesh: a ``trimesh.Trimesh`` (already normalised; see :func:`load_mesh`).
        k: candidate triangles per distance query.

    Raises:
        ValueError: the mesh is not watertight.
    """

    def __init__(self, mesh, k: int = 8):
        if not mesh.is_watertight:
            raise ValueError("mesh is not watertight (a region needs a closed surface)")
        self.mesh = mesh
        self.dim = 3
        v = np.asarray(mesh.vertices, dtype=np.float64)
        f = np.asarray(mesh.faces, dtype=np.int64)
        self._parity = _RayParity(v, f)
        self._dist = _SurfaceDistance(v, f, k=k)

    @classmethod
    def from_file(cls, path, center=None, scale=None, **kw) -> MeshRegion:
        return cls(load_mesh(path, center, scale), **kw)

    def contains(self, x: Tensor) -> Tensor:
        return torch.from_numpy(self._parity.contains(_to_numpy(x))).to(x.device)

    def sdf(self, x: Tensor) -> Tensor:
        q = _to_numpy(x)
        d, _ = self._dist.query(q)
        inside = self._parity.contains(q)
        return torch.from_numpy(np.where(inside, -d, d)).to(device=x.device, dtype=x.dtype)

    def volume(self) -> float:
        return float(self.mesh.volume)

    def bounds(self):
        b = torch.tensor(np.array(self.mesh.bounds, dtype=np.float64))
        return b[0].clone(), b[1].clone()


class MeshInterface(Interface):
    """A triangle mesh surface as an interface.

    Arguments:
        mesh: a ``trimesh.Trimesh`` (already normalised).
        normals: ``"faces"`` (the face normals as stored), ``"flipped"`` (their negatives) or
            ``"none"``.

    ``n_components`` is the number of connected components of the mesh (faces sharing an edge or
    a vertex); ``component_of(x)`` the component of the nearest triangle.
    """

    def __init__(self, mesh, normals: str | None = "faces", k: int = 8):
        mode = "none" if normals is None else str(normals)
        if mode not in ("faces", "flipped", "none"):
            raise ValueError("normals must be 'faces', 'flipped' or 'none'")
        self.mesh = mesh
        self.dim = 3
        self.has_normals = mode != "none"
        self._rim = None  # the open edges (m, 2, 3) and a KD-tree of their midpoints, on first use
        v = np.asarray(mesh.vertices, dtype=np.float64)
        f = np.asarray(mesh.faces, dtype=np.int64)
        self._tri = torch.from_numpy(v[f])  # (F, 3, 3)
        areas = np.asarray(mesh.area_faces, dtype=np.float64)
        self._areas = torch.from_numpy(areas.copy())
        sign = {"faces": 1.0, "flipped": -1.0, "none": 0.0}[mode]
        self._normals = torch.from_numpy(np.asarray(mesh.face_normals, dtype=np.float64) * sign)
        # components: faces sharing a vertex belong together (face-vertex incidence graph)
        nf, nv = len(f), len(v)
        rows = np.repeat(np.arange(nf), 3)
        inc = coo_matrix((np.ones(len(rows)), (rows, f.reshape(-1) + nf)), shape=(nf + nv, nf + nv))
        _, lab = connected_components(inc, directed=False)
        _, self._face_component = np.unique(lab[:nf], return_inverse=True)
        self._n_components = int(self._face_component.max()) + 1
        self._dist = _SurfaceDistance(v, f, k=k)

    @classmethod
    def from_file(cls, path, center=None, scale=None, **kw) -> MeshInterface:
        return cls(load_mesh(path, center, scale), **kw)

    @property
    def n_components(self) -> int:
        return self._n_components

    def measure(self) -> float:
        return float(self._areas.sum())

    def sample(self, n, generator=None, device=None, dtype=torch.float32):
        gdev = generator.device if generator is not None else torch.device("cpu")
        if n == 0:
            z = torch.zeros(0, 3, device=device, dtype=dtype)
            return z, z.clone()
        fi = torch.multinomial(self._areas.to(gdev), n, replacement=True, generator=generator).cpu()
        r = rand(generator, (n, 2), "cpu", torch.float64)
        s = r[:, 0].sqrt()
        t = self._tri[fi]
        x = (1 - s)[:, None] * t[:, 0] + (s * (1 - r[:, 1]))[:, None] * t[:, 1] + (s * r[:, 1])[:, None] * t[:, 2]
        return x.to(device=device, dtype=dtype), self._normals[fi].to(device=device, dtype=dtype)

    def distance(self, x: Tensor) -> Tensor:
        d, _ = self._dist.query(_to_numpy(x))
        return torch.from_numpy(d).to(device=x.device, dtype=x.dtype)

    def rim_distance(self, x: Tensor) -> Tensor:
        """To the nearest open edge (an edge of one face only); ``inf`` for a closed mesh. Exact
        when that edge is among the 8 with the nearest midpoints."""
        if self._rim is None:
            from trimesh.grouping import group_rows

            e = self.mesh.edges_sorted
            v = np.asarray(self.mesh.vertices, dtype=np.float64)
            seg = v[e[group_rows(e, require_count=1)]]  # (m, 2, 3)
            self._rim = (seg, cKDTree(seg.mean(axis=1)) if len(seg) else None)
        seg, tree = self._rim
        if tree is None:
            return torch.full((x.shape[0],), float("inf"), dtype=x.dtype, device=x.device)
        q = _to_numpy(x)
        k = min(8, len(seg))
        _, j = tree.query(q, k=k)
        j = j.reshape(len(q), k)
        pp = q[:, None, :]
        c = closest_on_segments(pp, seg[j, 0], seg[j, 1])
        d = np.linalg.norm(c - pp, axis=-1).min(axis=1)
        return torch.from_numpy(d).to(device=x.device, dtype=x.dtype)

    def nearest(self, x: Tensor) -> tuple[Tensor, Tensor]:
        q = _to_numpy(x)
        d, f = self._dist.query(q)
        t = self._dist.tri[f]
        c = closest_points_on_triangles(q, t[:, 0], t[:, 1], t[:, 2])
        return (torch.from_numpy(d).to(device=x.device, dtype=x.dtype),
                torch.from_numpy(c).to(device=x.device, dtype=x.dtype))

    def component_of(self, x: Tensor) -> Tensor:
        _, f = self._dist.query(_to_numpy(x))
        return torch.from_numpy(self._face_component[f]).to(device=x.device, dtype=torch.long)

    def bounds(self):
        b = torch.tensor(np.array(self.mesh.bounds, dtype=np.float64))
        return b[0].clone(), b[1].clone()
