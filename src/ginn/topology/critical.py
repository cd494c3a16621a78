"""Critical points of a neural field, for all shapes of a batch at once (Appendix C.2, steps 1-2).

Pipeline (:func:`find_critical_points`):

1. **Seeds**: a jittered cell-centred grid over the domain for every shape, optionally reduced to
   the cells in which every component of ``grad f`` changes sign among the cell's corners (one
   batched gradient pass over the corners), plus the previous critical points (warm start).
2. **Convergence to grad f = 0**: trust-region Newton steps ``dx = -H^{-1} grad f`` (the Hessian's
   eigenvalues are regularised away from 0, keeping their sign, so that saddles are reached too).
   A step is accepted only if ``|grad f|`` decreases; otherwise the point's trust radius shrinks.
   The Newton direction is a descent direction of the paper's objective ``|grad f|^2`` (its
   gradient is ``H grad f``), so with a small enough radius this is gradient descent on
   ``|grad f|^2`` with a Newton metric: it cannot diverge, and it converges quadratically near the
   point.
3. **Removal** of points that leave the domain box, whose trust radius collapsed, or whose
   ``|grad f|`` stays above the tolerance.
4. **Clustering** of duplicates with scikit-learn's DBSCAN (``min_samples=1``), per shape: the
   shape index is appended as an extra coordinate scaled far beyond the merge radius, so one
   DBSCAN call clusters all shapes without mixing them. Each cluster keeps its member with the
   smallest ``|grad f|``.
5. **Classification** by the eigenvalues of the Hessian: the Morse index is the number of
   negative eigenvalues (0 minimum, ``d`` maximum, otherwise a saddle).

All derivatives come from :mod:`ginn.fields` (no autograd here); everything returned is detached.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from sklearn.cluster import DBSCAN
from torch import Tensor

from ..extract.grid import Grid, proportional_counts
from ..fields import Field, gradient, hessian
from ..geometry.base import Box

MINIMUM, SADDLE, MAXIMUM = 0, 1, 2


@dataclass(frozen=True)
class CriticalPointOptions:
    """Numerical settings of the critical-point search (sensible defaults for ``[-1, 1]^d`` boxes).

    Attributes:
        seed_filter: start Newton only in the grid cells where every component of ``grad f``
            changes sign among the cell's corners (one gradient pass over the cell corners; much
            cheaper); False starts Newton in every cell. (Local minima of ``|grad f|`` are *not*
            a usable filter: an approximate SDF has ``|grad f| ~ 1`` almost everywhere.)
        jitter: seed jitter as a fraction of a grid cell (uniform in ``±jitter/2``).
        newton_steps: Newton iterations of a full search.
        tol: a point has converged when ``|grad f| <= tol``.
        max_step: largest Newton step as a fraction of a grid cell (initial trust radius).
        min_step: a point is dropped when its trust radius falls below this fraction of a cell.
        merge_radius: DBSCAN ``eps`` as a fraction of a grid cell.
        eig_tol: eigenvalues with ``|lambda| <= eig_tol`` are regularised to ``±eig_tol`` in the
            Newton step and flag the point as degenerate.
    """

    seed_filter: bool = True
    jitter: float = 0.5
    newton_steps: int = 25
    tol: float = 1e-4
    max_step: float = 1.0
    min_step: float = 1e-4
    merge_radius: float = 0.1
    eig_tol: float = 1e-6


@dataclass
class CriticalPoints:
    """Critical points of all shapes of a batch (detached tensors, ``m`` points).

    Attributes:
        x: positions ``(m, d)``.
        shape: index of the shape each point belongs to ``(m,)`` (long).
        f: values ``(m,)``.
        grad_norm: ``|grad f|`` ``(m,)``.
        eigvals: Hessian eigenvalues, ascending ``(m, d)``.
        eigvecs: matching unit eigenvectors as columns ``(m, d, d)``.
    """

    x: Tensor
    shape: Tensor
    f: Tensor
    grad_norm: Tensor
    eigvals: Tensor
    eigvecs: Tensor

    @property
    def m(self) -> int:
        return int(self.x.shape[0])

    @property
    def dim(self) -> int:
        return int(self.x.shape[1])

    @property
    def index(self) -> Tensor:
        """Morse index (number of negative eigenvalues), ``(m,)`` long."""
        return (self.eigvals < 0).sum(-1)

    @property
    def kind(self) -> Tensor:
        """``MINIMUM`` (0), ``SADDLE`` (1) or ``MAXIMUM`` (2) per point, ``(m,)`` long."""
        idx = self.index
        k = torch.full_like(idx, SADDLE)
        k[idx == 0] = MINIMUM
        k[idx == self.dim] = MAXIMUM
        return k

    def degenerate(self, eig_tol: float) -> Tensor:
        """Boolean ``(m,)``: some Hessian eigenvalue is (numerically) zero."""
        return self.eigvals.abs().min(-1).values <= eig_tol

    def select(self, mask: Tensor) -> CriticalPoints:
        """The subset selected by a boolean mask or an index tensor."""
        return CriticalPoints(
            self.x[mask], self.shape[mask], self.f[mask], self.grad_norm[mask], self.eigvals[mask], self.eigvecs[mask]
        )

    def counts(self, n_shapes: int) -> dict[str, np.ndarray]:
        """Number of minima, saddles and maxima per shape, each ``(n_shapes,)``."""
        k = self.kind.cpu().numpy()
        s = self.shape.cpu().numpy()
        return {
            name: np.bincount(s[k == code], minlength=n_shapes)
            for name, code in (("minima", MINIMUM), ("saddles", SADDLE), ("maxima", MAXIMUM))
        }

    @staticmethod
    def empty(d: int, device=None, dtype=torch.float32) -> CriticalPoints:
        z = torch.zeros(0, device=device, dtype=dtype)
        return CriticalPoints(
            torch.zeros(0, d, device=device, dtype=dtype),
            torch.zeros(0, dtype=torch.long, device=device),
            z,
            z.clone(),
            torch.zeros(0, d, device=device, dtype=dtype),
            torch.zeros(0, d, d, device=device, dtype=dtype),
        )


def cell_size(box: Box, grid: int) -> float:
    """Edge length of one seed-grid cell along the longest axis."""
    ext = np.asarray(box.hi, dtype=float) - np.asarray(box.lo, dtype=float)
    return float(ext.max() / grid)


def latents_of(Z: Tensor | None, shape: Tensor) -> Tensor | None:
    """Per-point latent codes ``Z[shape]`` ``(n, k)``, or None for a single latent-free shape."""
    return None if Z is None else Z[shape]


def seed_grid(
    box: Box,
    grid: int,
    n_shapes: int,
    jitter: float = 0.5,
    generator: torch.Generator | None = None,
    device=None,
    dtype=torch.float32,
) -> tuple[Tensor, tuple[int, ...]]:
    """Jittered cell-centred seeds, the same grid pattern for every shape.

    Arguments:
        box: the domain.
        grid: cells along the longest axis (the others proportionally, at least 2).
        n_shapes: ``S``.
        jitter: jitter amplitude as a fraction of a cell (each seed moves by ``U(-j/2, j/2)`` cells
            per axis, independently per shape).

    Returns:
        seeds ``(S, G, d)`` (C order of the cell grid ``shape`` within each shape) and ``shape``.
    """
    shape = proportional_counts(box, grid)
    lo = torch.tensor(box.lo, device=device, dtype=dtype)
    hi = torch.tensor(box.hi, device=device, dtype=dtype)
    h = (hi - lo) / torch.tensor(shape, device=device, dtype=dtype)
    axes = [torch.arange(n, device=device, dtype=dtype) + 0.5 for n in shape]
    cells = torch.stack([m.reshape(-1) for m in torch.meshgrid(*axes, indexing="ij")], dim=-1)  # (G, d)
    pts = cells.unsqueeze(0).expand(n_shapes, -1, -1)
    if jitter > 0:
        u = torch.rand(pts.shape, generator=generator, dtype=dtype).to(device) - 0.5
        pts = pts + jitter * u
    return lo + pts * h, shape


def sign_change_cells(grad_nodes: Tensor, node_shape: tuple[int, ...]) -> Tensor:
    """Cells of a vertex grid in which every gradient component changes sign (or vanishes) among
    the cell's ``2^d`` corners: the cells that can contain a zero of a nearly linear gradient.

    Arguments:
        grad_nodes: ``grad f`` at the grid nodes ``(S, prod(node_shape), d)``.
        node_shape: nodes per axis ``(n_1 + 1, ..., n_d + 1)``.

    Returns:
        boolean ``(S, prod(cell_shape))`` with ``cell_shape = (n_1, ..., n_d)`` (C order).
    """
    S, _, d = grad_nodes.shape
    g = grad_nodes.reshape(S, *node_shape, d)
    lo = hi = None
    for corner in range(2**d):
        sl = [slice(None)]
        for i in range(d):
            sl.append(slice(1, None) if (corner >> i) & 1 else slice(None, -1))
        c = g[tuple(sl)]
        lo = c if lo is None else torch.minimum(lo, c)
        hi = c if hi is None else torch.maximum(hi, c)
    flagged = ((lo <= 0) & (hi >= 0)).all(dim=-1)
    return flagged.reshape(S, -1)


def _newton_direction(g: Tensor, H: Tensor, eig_tol: float) -> Tensor:
    """``-H^{-1} g`` with eigenvalues pushed away from 0 (sign kept), ``(n, d)``."""
    lam, V = torch.linalg.eigh(H)
    sign = torch.where(lam < 0, -1.0, 1.0).to(lam.dtype)
    lam = sign * lam.abs().clamp_min(eig_tol)
    coef = torch.einsum("nji,nj->ni", V, g) / lam
    return -torch.einsum("nij,nj->ni", V, coef)


@dataclass
class NewtonResult:
    """Output of :func:`newton_refine` (detached).

    Attributes:
        x, f, grad_norm, hessian: final positions ``(n, d)``, values ``(n,)``, ``|grad f|`` ``(n,)``
            and Hessians ``(n, d, d)``.
        converged: ``|grad f| <= tol`` and inside the box, ``(n,)``.
        lost: left the box or the trust radius collapsed, ``(n,)``.
    """

    x: Tensor
    f: Tensor
    grad_norm: Tensor
    hessian: Tensor
    converged: Tensor
    lost: Tensor


def newton_refine(
    field: Field,
    x: Tensor,
    z: Tensor | None,
    box: Box,
    *,
    steps: int,
    tol: float,
    max_step: float,
    min_step: float,
    eig_tol: float = 1e-6,
) -> NewtonResult:
    """Converge points to ``grad f = 0`` with trust-region Newton steps (all points at once).

    Arguments:
        field: ``(x, z) -> (n,)``.
        x: start points ``(n, d)``; z: their latents ``(n, k)`` or None.
        box: points leaving it are dropped.
        steps: iterations (each costs one Hessian evaluation at the still-active points).
        tol: convergence threshold on ``|grad f|``.
        max_step: initial and largest trust radius (absolute length).
        min_step: a point whose radius shrinks below this is given up (``lost``).
        eig_tol: eigenvalue regularisation of the Newton step.

    Returns:
        :class:`NewtonResult`.
    """
    lo, hi = box.tensors(x.device, x.dtype)
    x = x.detach().clone()
    n = x.shape[0]
    if n == 0:
        d = x.shape[1]
        e = torch.zeros(0, dtype=torch.bool, device=x.device)
        return NewtonResult(x, x.new_zeros(0), x.new_zeros(0), x.new_zeros(0, d, d), e, e.clone())
    f, g, H = hessian(field, x, z)
    gn = g.norm(dim=-1)
    radius = torch.full((n,), float(max_step), dtype=x.dtype, device=x.device)
    lost = ~box.contains(x)
    for _ in range(steps):
        active = (gn > tol) & ~lost
        idx = torch.nonzero(active, as_tuple=False).squeeze(-1)
        if idx.numel() == 0:
            break
        dx = _newton_direction(g[idx], H[idx], eig_tol)
        L = dx.norm(dim=-1).clamp_min(1e-30)
        scale = (radius[idx] / L).clamp(max=1.0)
        xn = x[idx] + dx * scale[:, None]
        fn, gn_new, Hn = hessian(field, xn, None if z is None else z[idx])
        gnn = gn_new.norm(dim=-1)
        inside = ((xn >= lo) & (xn <= hi)).all(-1)
        accept = (gnn < gn[idx]) & inside
        a = idx[accept]
        x[a], f[a], g[a], H[a], gn[a] = xn[accept], fn[accept], gn_new[accept], Hn[accept], gnn[accept]
        full = scale[accept] >= 1.0
        radius[a] = torch.where(full, radius[a], (2 * radius[a]).clamp(max=max_step))
        r = idx[~accept]
        radius[r] = radius[r] * 0.25
        # a rejected step that left the box: the point is heading out of the domain
        out = idx[~accept & ~inside & (scale >= 1.0)]
        lost[out] = True
        lost |= radius < min_step
    converged = (gn <= tol) & ~lost
    return NewtonResult(x, f.detach(), gn.detach(), H.detach(), converged, lost)


def cluster(x: Tensor, shape: Tensor, grad_norm: Tensor, radius: float) -> Tensor:
    """Indices of one representative per DBSCAN cluster (per shape), ``(m',)`` long.

    Arguments:
        x: points ``(m, d)``; shape: their shape indices ``(m,)``; grad_norm: ``|grad f|`` ``(m,)``
            (the representative is the member with the smallest value).
        radius: DBSCAN ``eps``.
    """
    m = x.shape[0]
    if m == 0:
        return torch.zeros(0, dtype=torch.long, device=x.device)
    xs = x.detach().cpu().double().numpy()
    span = float(np.ptp(xs, axis=0).max()) + 10 * radius + 1.0
    aug = np.concatenate([xs, shape.cpu().numpy()[:, None].astype(float) * 10 * span], axis=1)
    labels = DBSCAN(eps=radius, min_samples=1).fit(aug).labels_
    order = np.lexsort((grad_norm.detach().cpu().double().numpy(), labels))  # by label, then |g|
    first = np.ones(m, dtype=bool)
    first[1:] = labels[order][1:] != labels[order][:-1]
    keep = np.sort(order[first])
    return torch.from_numpy(keep).to(x.device)


def classify(x: Tensor, shape: Tensor, f: Tensor, grad_norm: Tensor, H: Tensor) -> CriticalPoints:
    """Eigen-decompose the Hessians ``(m, d, d)`` and pack a :class:`CriticalPoints`."""
    lam, V = torch.linalg.eigh(H)
    return CriticalPoints(x, shape, f, grad_norm, lam, V)


def find_critical_points(
    field: Field,
    Z: Tensor | None,
    box: Box,
    grid: int = 16,
    previous: CriticalPoints | None = None,
    options: CriticalPointOptions = CriticalPointOptions(),
    generator: torch.Generator | None = None,
    device=None,
    dtype=torch.float32,
) -> CriticalPoints:
    """All critical points of every shape of a batch.

    Arguments:
        field: ``(x, z) -> (n,)`` (a model or an analytic field).
        Z: latent codes ``(S, k)`` or None (a single shape).
        box: the domain X.
        grid: seed cells along the longest axis.
        previous: critical points of an earlier step, added to the seeds (warm start).
        options: numerical settings.
        generator: for the seed jitter.
        device, dtype: of the seeds (taken from ``Z`` when given).

    Returns:
        :class:`CriticalPoints`, sorted by shape.
    """
    if Z is not None:
        device, dtype = Z.device, Z.dtype
    S = 1 if Z is None else Z.shape[0]
    h = cell_size(box, grid)
    seeds, gshape = seed_grid(box, grid, S, options.jitter, generator, device, dtype)
    G = seeds.shape[1]
    sh = torch.arange(S, device=device).repeat_interleave(G)
    x = seeds.reshape(S * G, -1)
    if options.seed_filter:
        ngrid = Grid(np.asarray(box.lo, dtype=np.float64), np.asarray(box.hi, dtype=np.float64), gshape)
        nodes, nshape = ngrid.tensor_points(device, dtype), ngrid.shape
        Nn = nodes.shape[0]
        nsh = torch.arange(S, device=device).repeat_interleave(Nn)
        _, g = gradient(field, nodes.repeat(S, 1), latents_of(Z, nsh))
        keep = sign_change_cells(g.reshape(S, Nn, -1), nshape).reshape(-1)
        x, sh = x[keep], sh[keep]
    if previous is not None and previous.m > 0:
        ok = previous.shape < S
        x = torch.cat([x, previous.x[ok].to(device=device, dtype=dtype)])
        sh = torch.cat([sh, previous.shape[ok].to(device)])
    res = newton_refine(
        field,
        x,
        latents_of(Z, sh),
        box,
        steps=options.newton_steps,
        tol=options.tol,
        max_step=options.max_step * h,
        min_step=options.min_step * h,
        eig_tol=options.eig_tol,
    )
    c = res.converged
    keep = cluster(res.x[c], sh[c], res.grad_norm[c], options.merge_radius * h)
    sel = torch.nonzero(c, as_tuple=False).squeeze(-1)[keep]
    sel = sel[torch.argsort(sh[sel], stable=True)]
    return classify(res.x[sel], sh[sel], res.f[sel], res.grad_norm[sel], res.hessian[sel])
