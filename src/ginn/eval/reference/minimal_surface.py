"""Discrete minimal surfaces: an independent, classical reference for Plateau's problem.

A triangle mesh ``(V, F)`` with its boundary vertices fixed on a prescribed curve is driven to a
critical point of its area by the Pinkall-Polthier iteration (Pinkall & Polthier 1993): given the
current mesh ``M_i``, the next one is the discrete harmonic map from ``M_i`` with the same boundary,

    L(M_i)[I, I] V_{i+1}[I] = -L(M_i)[I, B] V[B],

where ``L(M)`` is the cotangent Laplacian of ``M`` (sparse, solved with SciPy) and ``I``, ``B`` are the
interior and boundary vertices. It is the ``dt -> infinity`` limit of implicit mean-curvature flow;
a step that would increase the area is damped (``V <- V + alpha (V_new - V)``, ``alpha`` halved).

Refinement: meshes of the disk are built at any resolution from a ring triangulation of the unit
disk (Delaunay), mapped harmonically onto the curve (the initial mesh); areas at several
resolutions are extrapolated (Richardson, ``O(h^2)``) for the Plateau reference area.

Public names: :func:`cotangent_laplacian`, :func:`vertex_areas`, :func:`mesh_area`,
:func:`minimize_area`, :class:`MinimalSurface`, :func:`disk_minimal_surface`,
:func:`annulus_minimal_surface`, :func:`polygon_curve`, :func:`circle_curve`,
:func:`plateau_polygon`, :func:`plateau_reference`, :data:`PLATEAU_AREA_ESTIMATE`, :func:`catenoid_area`,
:func:`sample_surface`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import scipy.sparse as sp
from scipy.optimize import brentq
from scipy.sparse.linalg import splu
from scipy.spatial import Delaunay

Curve = Callable[[np.ndarray], np.ndarray]  # t in [0, 1) (n,) -> points (n, 3), periodic in t


# --- discrete operators -------------------------------------------------------------------------


def _cotangents(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Cotangent of the angle at each corner of each triangle, ``(m, 3)``; column ``c`` is the angle
    at vertex ``F[:, c]`` (opposite the edge ``F[:, c+1], F[:, c+2]``)."""
    out = np.empty(F.shape, dtype=np.float64)
    for c in range(3):
        a, b, o = V[F[:, (c + 1) % 3]], V[F[:, (c + 2) % 3]], V[F[:, c]]
        u, w = a - o, b - o
        cr = np.linalg.norm(np.cross(u, w), axis=1)
        out[:, c] = np.einsum("ij,ij->i", u, w) / np.maximum(cr, 1e-300)
    return out


def cotangent_laplacian(V: np.ndarray, F: np.ndarray) -> sp.csr_matrix:
    """The (positive semi-definite) cotangent Laplacian ``L = D - W``, ``(n, n)`` sparse.

    ``W_ij = (cot alpha_ij + cot beta_ij) / 2`` over the angles opposite edge ``ij``; ``D = diag(W 1)``.
    ``x^T L x / 2`` is the Dirichlet energy of the piecewise linear function ``x`` on ``(V, F)``.

    Arguments:
        V: vertices ``(n, 3)``; F: triangles ``(m, 3)`` (int).
    """
    n = V.shape[0]
    cot = _cotangents(V, F)
    rows, cols, vals = [], [], []
    for c in range(3):
        i, j = F[:, (c + 1) % 3], F[:, (c + 2) % 3]
        w = 0.5 * cot[:, c]
        rows += [i, j]
        cols += [j, i]
        vals += [w, w]
    W = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()


def triangle_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Areas ``(m,)``."""
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


def mesh_area(V: np.ndarray, F: np.ndarray) -> float:
    """Total area of a triangle mesh."""
    return float(triangle_areas(V, F).sum())


def vertex_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Barycentric (lumped) vertex areas ``(n,)``: a third of each incident triangle."""
    a = triangle_areas(V, F) / 3.0
    return np.bincount(F.ravel(), weights=np.repeat(a, 3), minlength=V.shape[0])


def mean_curvature_normal(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Discrete mean-curvature vector ``H n`` at each vertex, ``(n, 3)``: ``-L V / (2 A_v)``
    (``H`` = mean of the principal curvatures; zero at interior vertices of a minimal surface)."""
    L = cotangent_laplacian(V, F)
    return -(L @ V) / (2.0 * np.maximum(vertex_areas(V, F), 1e-300))[:, None]


# --- the area minimisation ----------------------------------------------------------------------


@dataclass
class MinimizeInfo:
    """History of :func:`minimize_area`: ``areas`` per iteration, ``converged``, ``iterations``."""

    areas: list[float] = field(default_factory=list)
    converged: bool = False
    iterations: int = 0


def _harmonic_step(V: np.ndarray, F: np.ndarray, interior: np.ndarray, boundary: np.ndarray, L=None) -> np.ndarray:
    L = cotangent_laplacian(V, F) if L is None else L
    LII = L[interior][:, interior].tocsc()
    rhs = -(L[interior][:, boundary] @ V[boundary])
    out = V.copy()
    out[interior] = splu(LII).solve(rhs)
    return out


def minimize_area(
    V: np.ndarray,
    F: np.ndarray,
    fixed: np.ndarray,
    *,
    max_iter: int = 500,
    tol: float = 1e-11,
) -> tuple[np.ndarray, MinimizeInfo]:
    """Minimise the area of ``(V, F)`` keeping the vertices ``fixed`` in place (Pinkall-Polthier).

    Arguments:
        V: initial vertices ``(n, 3)`` float64; F: triangles ``(m, 3)``.
        fixed: boolean ``(n,)``, the boundary vertices.
        max_iter: iteration limit.
        tol: stop when the relative area decrease of an iteration is below ``tol``.

    Returns:
        ``(V, info)``: the final vertices ``(n, 3)`` and a :class:`MinimizeInfo`.
    """
    V = np.array(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    fixed = np.asarray(fixed, dtype=bool)
    interior, boundary = np.flatnonzero(~fixed), np.flatnonzero(fixed)
    info = MinimizeInfo(areas=[mesh_area(V, F)])
    if interior.size == 0:
        info.converged = True
        return V, info
    for it in range(max_iter):
        target = _harmonic_step(V, F, interior, boundary)
        a0 = info.areas[-1]
        alpha, Vn, an = 1.0, target, mesh_area(target, F)
        while not (an <= a0) and alpha > 1e-4:  # damp a step that does not decrease the area
            alpha *= 0.5
            Vn = V + alpha * (target - V)
            an = mesh_area(Vn, F)
        info.iterations = it + 1
        if not (an <= a0):
            info.converged = True  # no descent left at machine precision
            break
        V = Vn
        info.areas.append(an)
        if a0 - an <= tol * a0:
            info.converged = True
            break
    return V, info


# --- boundary curves ----------------------------------------------------------------------------


def polygon_curve(points: np.ndarray) -> Curve:
    """A closed polygon through ``points`` ``(k, 3)``, parametrised by arc length over ``[0, 1)``."""
    P = np.asarray(points, dtype=np.float64)
    Q = np.roll(P, -1, axis=0)
    seg = np.linalg.norm(Q - P, axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)]) / seg.sum()

    def curve(t: np.ndarray) -> np.ndarray:
        t = np.mod(np.asarray(t, dtype=np.float64), 1.0)
        j = np.clip(np.searchsorted(s, t, side="right") - 1, 0, len(seg) - 1)
        u = (t - s[j]) / (s[j + 1] - s[j])
        return P[j] + u[:, None] * (Q[j] - P[j])

    return curve


def circle_curve(center=(0.0, 0.0, 0.0), radius: float = 1.0, normal=(0.0, 0.0, 1.0)) -> Curve:
    """A circle of ``radius`` around ``center`` in the plane orthogonal to ``normal``; ``t in [0, 1)``."""
    c = np.asarray(center, dtype=np.float64)
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    a = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)

    def curve(t: np.ndarray) -> np.ndarray:
        th = 2.0 * np.pi * np.asarray(t, dtype=np.float64)
        return c + radius * (np.cos(th)[:, None] * a + np.sin(th)[:, None] * b)

    return curve


def plateau_polygon() -> np.ndarray:
    """The paper's Plateau boundary: the closed 8-edge skew polygon through unit-cube corners ``(8, 3)``."""
    return np.array(
        [[0, 0, 0], [1, 0, 0], [1, 0, 1], [1, 1, 1], [1, 1, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]], dtype=np.float64
    )


# --- meshes -------------------------------------------------------------------------------------


def unit_disk_mesh(rings: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A triangulation of the unit disk: ring ``k`` (``k = 0..rings``) holds ``max(1, 6k)`` vertices at
    radius ``k / rings``; Delaunay triangles.

    Returns:
        ``(P, F, t)``: 2D vertices ``(n, 2)``, triangles ``(m, 3)`` (counter-clockwise), and for the
        ``6 rings`` boundary vertices (the last ones) their angle as a fraction of a turn, else -1.
    """
    pts, ts = [np.zeros((1, 2))], [np.array([-1.0])]
    for k in range(1, rings + 1):
        m = 6 * k
        tk = np.arange(m) / m + (0.0 if k == rings else 0.5 / m * (k % 2))
        th = 2 * np.pi * tk
        pts.append(np.stack([np.cos(th), np.sin(th)], axis=1) * (k / rings))
        ts.append(tk if k == rings else np.full(m, -1.0))
    P = np.concatenate(pts)
    F = Delaunay(P).simplices.astype(np.int64)
    e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    flip = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    F[flip] = F[flip][:, [0, 2, 1]]
    return P, F, np.concatenate(ts)


@dataclass
class MinimalSurface:
    """A discrete minimal surface: vertices ``V (n, 3)``, triangles ``F (m, 3)``, ``boundary (n,)`` mask,
    ``area`` and the :class:`MinimizeInfo` of the iteration."""

    V: np.ndarray
    F: np.ndarray
    boundary: np.ndarray
    area: float
    info: MinimizeInfo

    def interior_mean_curvature(self) -> np.ndarray:
        """``|H|`` at the interior vertices (discrete, ``(k,)``)."""
        return np.linalg.norm(mean_curvature_normal(self.V, self.F), axis=1)[~self.boundary]


def disk_minimal_surface(curve: Curve, rings: int = 16, *, max_iter: int = 500, tol: float = 1e-11) -> MinimalSurface:
    """The discrete minimal disk spanning a closed curve.

    Arguments:
        curve: ``t in [0, 1) -> (n, 3)`` (for a polygon, the corners fall on vertices when ``6 rings``
            is a multiple of the number of equal-length edges).
        rings: mesh resolution (``6 rings`` boundary vertices, ``~6 rings^2`` triangles).

    Returns:
        :class:`MinimalSurface`. The initial mesh is the harmonic map of the flat disk mesh onto the curve.
    """
    P, F, t = unit_disk_mesh(rings)
    bnd = t >= 0
    V = np.zeros((P.shape[0], 3))
    V[bnd] = curve(t[bnd])
    V0 = np.concatenate([P, np.zeros((P.shape[0], 1))], axis=1)
    V = _harmonic_step(V, F, np.flatnonzero(~bnd), np.flatnonzero(bnd), L=cotangent_laplacian(V0, F))
    V, info = minimize_area(V, F, bnd, max_iter=max_iter, tol=tol)
    return MinimalSurface(V, F, bnd, mesh_area(V, F), info)


def annulus_minimal_surface(
    curve_a: Curve, curve_b: Curve, n_around: int = 64, n_between: int = 16, *, max_iter: int = 500, tol: float = 1e-11
) -> MinimalSurface:
    """The discrete minimal annulus spanning two closed curves (two boundary components).

    The initial mesh joins ``curve_a(t)`` to ``curve_b(t)`` by straight segments (``n_between`` cells),
    ``n_around`` cells around, quads split into triangles.
    """
    t = np.arange(n_around) / n_around
    A, B = curve_a(t), curve_b(t)
    s = np.linspace(0.0, 1.0, n_between + 1)
    V = (A[None] * (1 - s)[:, None, None] + B[None] * s[:, None, None]).reshape(-1, 3)
    k, j = np.meshgrid(np.arange(n_between), np.arange(n_around), indexing="ij")
    v00 = k * n_around + j
    v01 = k * n_around + (j + 1) % n_around
    v10 = v00 + n_around
    v11 = v01 + n_around
    F = np.concatenate([np.stack([v00, v01, v11], -1).reshape(-1, 3), np.stack([v00, v11, v10], -1).reshape(-1, 3)])
    bnd = np.zeros(V.shape[0], dtype=bool)
    bnd[:n_around] = bnd[-n_around:] = True
    V, info = minimize_area(V, F, bnd, max_iter=max_iter, tol=tol)
    return MinimalSurface(V, F, bnd, mesh_area(V, F), info)


def catenoid_area(radius: float, half_height: float) -> tuple[float, float]:
    """Area of the stable catenoid ``r(z) = a cosh(z / a)``, ``|z| <= h``, spanning two coaxial circles of
    ``radius`` at ``z = +-h``: ``pi a (2 h + a sinh(2 h / a))``. Returns ``(area, a)``.

    Raises ValueError when no catenoid exists (``h / radius`` above about 0.6627).
    """
    h, R = float(half_height), float(radius)
    # a cosh(h / a) = R: the stable (larger) root lies between the turning point and R
    g = lambda a: a * np.cosh(h / a) - R  # noqa: E731
    # turning point: d/da [a cosh(h/a)] = cosh(u) - u sinh(u) = 0 with u = h / a, u* ~ 1.19968
    u_star = brentq(lambda u: np.cosh(u) - u * np.sinh(u), 0.5, 2.0)
    a_star = h / u_star
    if g(a_star) > 0:
        raise ValueError("no catenoid spans these circles")
    a = brentq(g, a_star, R)
    return float(np.pi * a * (2 * h + a * np.sinh(2 * h / a))), float(a)


# --- the Plateau reference ----------------------------------------------------------------------


# Area of the minimal surface spanning :func:`plateau_polygon`: Richardson extrapolation (``O(h^2)``)
# of Pinkall-Polthier meshes with 16..48 rings (docs/mirror-plateau.md); uncertainty about 1e-4.
PLATEAU_AREA_ESTIMATE = 2.4674


def plateau_reference(rings: int = 32, max_iter: int = 100) -> MinimalSurface:
    """The discrete minimal surface spanning :func:`plateau_polygon` (cached per arguments).

    Arguments:
        rings: resolution, a multiple of 4 so that the 8 corners are mesh vertices
            (32 rings: 6,144 triangles, about 4 s here).
        max_iter: Pinkall-Polthier iterations (the shape converges in a few; the remaining ones only
            slide vertices tangentially, lowering the discrete area by ``O(h^2)``).
    """
    if int(rings) % 4:
        raise ValueError("rings must be a multiple of 4 (the polygon's corners must be mesh vertices)")
    return _plateau_reference(int(rings), int(max_iter))


@lru_cache(maxsize=4)
def _plateau_reference(rings: int, max_iter: int) -> MinimalSurface:
    return disk_minimal_surface(polygon_curve(plateau_polygon()), rings, max_iter=max_iter, tol=1e-12)


def sample_surface(V: np.ndarray, F: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniformly distributed by area on a triangle mesh, ``(n, 3)``."""
    w = triangle_areas(V, F)
    e = rng.choice(F.shape[0], size=n, p=w / w.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    T = F[e]
    return V[T[:, 0]] * (1 - s)[:, None] + V[T[:, 1]] * (s * (1 - r2))[:, None] + V[T[:, 2]] * (s * r2)[:, None]
