"""Evaluation of a Plateau GINN against the independent discrete minimal surface.

The GINN's surface is the zero level set of its field. It is extracted by marching cubes
(:mod:`ginn.extract`) on a grid over the bounding box of ``Gamma``, *clipped exactly* to the convex
hull of ``Gamma`` (a minimal surface lies in the convex hull of its boundary; outside it the zero set
of the field is an arbitrary continuation), and compared with the reference mesh of
:mod:`ginn.eval.reference.minimal_surface`:

* ``cd2_to_reference``: two-sided chamfer discrepancy CD2 (paper eq. 4-5) between the surfaces, from
  area-uniform samples of each to the exact (point-to-triangle) distance to the other mesh;
* ``area_relative_error``: ``(area - reference_area) / reference_area``;
* ``mean_abs_mean_curvature``: mean ``|kappa_H|`` (:func:`ginn.fields.mean_curvature`) at samples of
  the clipped surface projected onto ``f = 0`` (the "boundary points" of the shape);
* ``interface_cd1``: CD1 of ``Gamma`` to the surface (RMS distance from samples of ``Gamma``).

Public names: :func:`evaluate_plateau`, :func:`extract_plateau_surface`, :func:`reference_surface`,
:func:`hull_halfspaces`, :func:`clip_mesh`, :func:`chamfer_cd2`, :data:`PLATEAU_REFERENCE_AREA`, and
:class:`ReferenceVerdict`, the verdict that holds each shape to the reference (a shape task adds it
to the verdicts of a problem with ``reference: minimal-surface``); the result files and renders
are :mod:`ginn.viz.plateau`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from scipy.spatial import ConvexHull
from torch import Tensor

from ..constraints.verdict import Verdict, Violation, number_text
from ..extract.boundary import Boundary, extract_boundary
from ..extract.grid import make_grid
from ..extract.sampling import field_dtype_device, sample_field
from ..fields import Field, evaluate, mean_curvature
from ..geometry.base import Box
from ..levelset import project_to_zero
from ..problems.problem import Problem
from .reference.minimal_surface import (
    PLATEAU_AREA_ESTIMATE,
    MinimalSurface,
    disk_minimal_surface,
    plateau_polygon,
    plateau_reference,
    polygon_curve,
    sample_surface,
    triangle_areas,
)

# Area of the minimal surface spanning the paper's polygon (see ginn.eval.reference.minimal_surface)
PLATEAU_REFERENCE_AREA = PLATEAU_AREA_ESTIMATE


# --- geometry helpers ---------------------------------------------------------------------------


def hull_halfspaces(points: np.ndarray, eps: float = 0.0, slab: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """The convex hull of ``points`` ``(k, 3)`` as half-spaces ``A x <= b`` (``A (h, 3)`` unit rows).

    A planar point set gives its 2D hull in its plane and a slab ``|n . (x - c)| <= slab`` around it.
    Every half-space is relaxed by ``eps``.
    """
    P = np.asarray(points, dtype=np.float64)
    c = P.mean(axis=0)
    _, s, Vt = np.linalg.svd(P - c)
    scale = max(float(s[0]), 1e-300)
    if s[2] <= 1e-9 * scale:  # planar
        e1, e2, n = Vt
        Q = np.stack([(P - c) @ e1, (P - c) @ e2], axis=1)
        hull = ConvexHull(Q)
        eq = hull.equations  # (h, 3): a . q + d <= 0 inside
        A = eq[:, :1] * e1 + eq[:, 1:2] * e2
        b = -eq[:, 2] + A @ c
        A = np.concatenate([A, n[None], -n[None]])
        b = np.concatenate([b, [n @ c + slab, -(n @ c) + slab]])
    else:
        eq = ConvexHull(P).equations
        A, b = eq[:, :3], -eq[:, 3]
    # merge coplanar facets (a cube's 12 triangles give 6 planes)
    key = np.round(np.concatenate([A, b[:, None]], axis=1), 9)
    _, idx = np.unique(key, axis=0, return_index=True)
    idx = np.sort(idx)
    return A[idx], b[idx] + eps


def _clip_soup(T: np.ndarray, a: np.ndarray, b: float) -> np.ndarray:
    """Clip a triangle soup ``(m, 3, 3)`` to the half-space ``a . x <= b``."""
    if T.shape[0] == 0:
        return T
    s = T @ a - b  # (m, 3)
    inside = s <= 0
    k = inside.sum(axis=1)
    out = [T[k == 3]]
    # one vertex inside: rotate it first -> (v0, p01, p02)
    for want, in_count in ((True, 1), (False, 2)):
        sel = np.flatnonzero(k == in_count)
        if sel.size == 0:
            continue
        c = np.argmax(inside[sel] == want, axis=1)  # the odd vertex
        order = (c[:, None] + np.arange(3)[None]) % 3
        R = np.take_along_axis(T[sel], order[:, :, None], axis=1)
        sr = np.take_along_axis(s[sel], order, axis=1)
        v0, v1, v2 = R[:, 0], R[:, 1], R[:, 2]
        s0, s1, s2 = sr[:, 0:1], sr[:, 1:2], sr[:, 2:3]
        p01 = v0 + s0 / (s0 - s1) * (v1 - v0)
        p02 = v0 + s0 / (s0 - s2) * (v2 - v0)
        if in_count == 1:
            out.append(np.stack([v0, p01, p02], axis=1))
        else:  # v0 outside, v1 and v2 inside: quad (v1, v2, p02, p01)
            out.append(np.stack([v1, v2, p02], axis=1))
            out.append(np.stack([v1, p02, p01], axis=1))
    return np.concatenate(out, axis=0)


def clip_mesh(V: np.ndarray, F: np.ndarray, A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exactly clip a triangle mesh to the convex polytope ``A x <= b``.

    Returns:
        ``(V, F)`` of the clipped mesh (vertices welded to 1e-12).
    """
    T = np.asarray(V, dtype=np.float64)[np.asarray(F)]
    for a, bb in zip(np.asarray(A, dtype=np.float64), np.asarray(b, dtype=np.float64)):
        T = _clip_soup(T, a, float(bb))
    if T.shape[0] == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    flat = T.reshape(-1, 3)
    _, first, inv = np.unique(np.round(flat, 12), axis=0, return_index=True, return_inverse=True)
    Fc = inv.reshape(-1, 3).astype(np.int64)
    Vc = flat[first]
    keep = (Fc[:, 0] != Fc[:, 1]) & (Fc[:, 1] != Fc[:, 2]) & (Fc[:, 0] != Fc[:, 2])
    return Vc, Fc[keep]


def _as_boundary(V: np.ndarray, F: np.ndarray) -> Boundary:
    return Boundary(np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64), np.ones(len(V), dtype=bool))


def chamfer_cd2(V1, F1, V2, F2, n_samples: int = 20000, seed: int = 0) -> tuple[float, float, float]:
    """Two-sided chamfer discrepancy between two triangle meshes (paper eq. 4-5).

    ``CD1(P, Q) = sqrt(mean_{x ~ Q} d(x, P)^2)`` with ``x`` area-uniform samples of ``Q`` and ``d`` the
    exact distance to the mesh ``P``; ``CD2 = sqrt(CD1(P, Q)^2 + CD1(Q, P)^2)``.

    Returns:
        ``(CD2, CD1(mesh1, samples of mesh2), CD1(mesh2, samples of mesh1))``; inf when a mesh is empty.
    """
    if len(F1) == 0 or len(F2) == 0:
        return float("inf"), float("inf"), float("inf")
    rng = np.random.default_rng(seed)
    x1 = sample_surface(V1, F1, n_samples, rng)
    x2 = sample_surface(V2, F2, n_samples, rng)
    d12 = _as_boundary(V1, F1).distance(x2)  # samples of 2 to mesh 1
    d21 = _as_boundary(V2, F2).distance(x1)
    c12, c21 = float(np.sqrt(np.mean(d12**2))), float(np.sqrt(np.mean(d21**2)))
    return float(np.hypot(c12, c21)), c12, c21


# --- extraction and evaluation ------------------------------------------------------------------


def gamma_of(problem_or_gamma) -> np.ndarray:
    """The polygon's vertices ``(k, 3)`` from a Problem (its closed polyline interface) or an array."""
    if hasattr(problem_or_gamma, "interfaces"):
        for itf in problem_or_gamma.interfaces:
            pts = getattr(itf, "points", None)
            if pts is not None and getattr(itf, "closed", False) and getattr(itf, "dim", 0) == 3:
                return np.asarray(pts.detach().cpu().numpy() if torch.is_tensor(pts) else pts, dtype=np.float64)
        raise ValueError(f"problem {getattr(problem_or_gamma, 'name', '?')!r} has no closed 3D polyline interface")
    G = np.asarray(problem_or_gamma, dtype=np.float64)
    if G.ndim != 2 or G.shape[1] != 3 or G.shape[0] < 3:
        raise ValueError(f"Gamma must be (k >= 3, 3) polygon vertices, got shape {G.shape}")
    return G


def extract_plateau_surface(
    field: Field, gamma: np.ndarray, resolution: int = 128, margin: float = 0.05, z: Tensor | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The zero level set of ``field`` (at the code ``z (k,)``, if any) near ``gamma`` (marching cubes
    over gamma's bounding box grown by ``margin`` times its diameter), clipped exactly to the convex
    hull of ``gamma``.

    Returns:
        ``(V (n, 3), F (m, 3))``.
    """
    G = np.asarray(gamma, dtype=np.float64)
    lo, hi = G.min(axis=0), G.max(axis=0)
    pad = margin * float(np.linalg.norm(hi - lo))
    grid = make_grid(Box(tuple(lo - pad), tuple(hi + pad)), resolution)
    values = sample_field(field, grid, z)
    bnd = extract_boundary(values, grid, close=False)
    # marching cubes returns float32 vertices: relax the hull by 1e-3 cells (a planar gamma's slab)
    A, b = hull_halfspaces(G, slab=1e-3 * float(grid.spacing.min()))
    return clip_mesh(bnd.vertices, bnd.elements, A, b)


def reference_surface(gamma: np.ndarray, rings: int = 32) -> tuple[MinimalSurface, float]:
    """The reference surface spanning ``gamma`` and its area.

    For the paper's polygon: the cached :func:`plateau_reference` mesh and :data:`PLATEAU_REFERENCE_AREA`;
    otherwise a :func:`disk_minimal_surface` at ``rings`` and its discrete area.
    """
    G = np.asarray(gamma, dtype=np.float64)
    P = plateau_polygon()
    if G.shape == P.shape and np.allclose(G, P):
        return plateau_reference(rings), PLATEAU_REFERENCE_AREA
    s = disk_minimal_surface(polygon_curve(G), rings)
    return s, s.area


def mean_abs_mean_curvature(
    field: Field, V: np.ndarray, F: np.ndarray, A: np.ndarray, b: np.ndarray, n: int = 2048, seed: int = 0,
    z: Tensor | None = None,
) -> tuple[float, int]:
    """Mean ``|kappa_H|`` at ``n`` area-uniform samples of ``(V, F)`` projected onto ``f = 0`` of
    ``field`` (at the code ``z (k,)``, if any), kept when converged and inside ``A x <= b``.
    Returns ``(value, number of points used)``."""
    if len(F) == 0:
        return float("nan"), 0
    dtype, device = field_dtype_device(field)
    x0 = torch.as_tensor(sample_surface(V, F, n, np.random.default_rng(seed)), dtype=dtype, device=device)
    tol = 1e-4 if dtype == torch.float32 else 1e-9
    code = None if z is None else torch.as_tensor(z, dtype=dtype, device=device).reshape(1, -1)
    proj = project_to_zero(field, x0, None if code is None else code.expand(x0.shape[0], -1), steps=8, tol=tol)
    x, _ = proj.select()
    if x.shape[0] == 0:
        return float("nan"), 0
    xn = x.detach().cpu().double().numpy()
    inside = np.all(xn @ A.T <= b + 1e-6, axis=1)
    x = x[torch.as_tensor(inside, device=x.device)]
    if x.shape[0] == 0:
        return float("nan"), 0
    v = evaluate(field, x, None if code is None else code.expand(x.shape[0], -1), grad=False, hessian_at=True,
                 create_graph=False)
    kh = mean_curvature(v.hessian_grad, v.hessian)
    return float(kh.abs().mean().item()), int(x.shape[0])


def evaluate_plateau(
    field: Field,
    problem_or_gamma,
    *,
    resolution: int = 128,
    n_samples: int = 20000,
    n_curvature: int = 2048,
    seed: int = 0,
    reference: tuple[MinimalSurface, float] | None = None,
    z: Tensor | None = None,
) -> dict[str, float]:
    """Plateau metrics of a trained field (``(x, z) -> (n,)``, surface ``{f = 0}``).

    Arguments:
        field: the trained model.
        problem_or_gamma: a :class:`ginn.problems.Problem` whose interface is the closed polygon, or the
            polygon's vertices ``(k, 3)``.
        resolution: marching-cubes cells along the longest axis of gamma's (padded) bounding box.
        n_samples: samples per surface for the chamfer discrepancy.
        n_curvature: surface samples for the mean curvature.
        reference: ``(MinimalSurface, area)`` to compare with (default :func:`reference_surface`).
        z: the code ``(k,)`` of the shape of a generative model (None: a single shape).

    Returns:
        ``cd2_to_reference``, ``area``, ``reference_area``, ``area_relative_error`` (signed),
        ``mean_abs_mean_curvature``, ``n_curvature_points``, ``interface_cd1``.
    """
    G = gamma_of(problem_or_gamma)
    V, F = extract_plateau_surface(field, G, resolution, z=z)
    ref, ref_area = reference if reference is not None else reference_surface(G)
    cd2, _, _ = chamfer_cd2(V, F, ref.V, ref.F, n_samples, seed)
    area = float(triangle_areas(V, F).sum()) if len(F) else 0.0
    diam = float(np.linalg.norm(G.max(0) - G.min(0)))
    A, b = hull_halfspaces(G, eps=1e-6 * diam, slab=1e-4 * diam)
    kh, n_kh = mean_abs_mean_curvature(field, V, F, A, b, n_curvature, seed, z=z)
    # Gamma to the surface: RMS distance from samples along the polygon
    curve = polygon_curve(G)
    gs = curve(np.random.default_rng(seed).random(4096))
    icd = float(np.sqrt(np.mean(_as_boundary(V, F).distance(gs) ** 2))) if len(F) else float("inf")
    return {
        "cd2_to_reference": cd2,
        "area": area,
        "reference_area": float(ref_area),
        "area_relative_error": float((area - ref_area) / ref_area),
        "mean_abs_mean_curvature": kh,
        "n_curvature_points": n_kh,
        "interface_cd1": icd,
    }


def _code(z) -> tuple[float, ...] | None:
    """A latent code as a hashable key (None: a single shape)."""
    return None if z is None else tuple(float(v) for v in torch.as_tensor(z).detach().reshape(-1).cpu())


class ReferenceVerdict(Verdict):
    """A problem with a reference solution (``reference: minimal-surface``): each shape's surface
    within ``tolerances.reference`` of it, the CD2 between the two surfaces and the relative
    difference of their areas (:func:`evaluate_plateau`). Such a problem's objective is the point of
    it (Plateau's: the least area spanning the polygon), and a surface that meets the polygon
    with a fraction of the minimal surface's area meets every geometric bound; this verdict is the
    objective's quality in the verdict. ``reference``: ``(MinimalSurface, area)`` to compare with
    (default :func:`reference_surface` of the problem's polygon, computed at the first use)."""

    name = "reference"
    # the area is lost where the surface misses the polygon (docs/plateau.md): a violation off
    # track raises the interface's multiplier
    enforced_by = ("interface",)

    def __init__(self, problem: Problem, reference: tuple[MinimalSurface, float] | None = None):
        super().__init__(problem)
        self.metrics = ("cd2_to_reference", "area_relative_error")
        self.bound = problem.tolerances.reference
        self._reference = reference
        self._last: tuple[tuple[float, ...] | None, dict[str, Any]] | None = None

    def measure(self, shape, context, field, z) -> dict[str, Any]:
        if self._reference is None:
            self._reference = reference_surface(gamma_of(self.problem))
        z = None if z is None else torch.as_tensor(z).reshape(-1)
        m = evaluate_plateau(field, self.problem, reference=self._reference, z=z)
        self._last = (_code(z), m)
        return {k: m[k] for k in ("cd2_to_reference", "area_relative_error")}

    def last(self, z: Tensor | None) -> dict[str, Any] | None:
        """The whole :func:`evaluate_plateau` of the last shape measured, if it was that of the code
        ``z`` (None: a single shape), else None: ``ginn eval`` reports it without measuring again."""
        if self._last is None or self._last[0] != _code(z):
            return None
        return dict(self._last[1])

    def _parts(self, metrics: Mapping) -> tuple[float, float] | None:
        cd2, err = metrics.get("cd2_to_reference"), metrics.get("area_relative_error")
        if cd2 is None or err is None:
            return None
        return float(cd2), float(err)

    def violation(self, metrics: Mapping) -> Violation | None:
        parts = self._parts(metrics)
        if parts is None or (parts[0] <= self.bound.cd2 and abs(parts[1]) <= self.bound.area):
            return None
        return Violation({"cd2": parts[0], "area": parts[1]}, {"cd2": self.bound.cd2, "area": self.bound.area})

    def ratio(self, metrics: Mapping) -> float | None:
        """The larger of CD2 over its bound and |area error| over its bound."""
        parts = self._parts(metrics)
        if parts is None:
            return None
        return max(parts[0] / self.bound.cd2, abs(parts[1]) / self.bound.area)

    @classmethod
    def describe(cls, v: Violation) -> str:
        """``reference: CD2 0.209 > 0.02, area -42.5 % (bound 2 %)``."""
        out = []
        if v.value["cd2"] > v.bound["cd2"]:
            out.append(f"CD2 {number_text(v.value['cd2'])} > {number_text(v.bound['cd2'])}")
        if abs(v.value["area"]) > v.bound["area"]:
            out.append(f"area {100 * v.value['area']:+.1f} % (bound {100 * v.bound['area']:.3g} %)")
        return f"{cls.name}: " + ", ".join(out)
