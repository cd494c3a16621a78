"""Diversity of a set of shapes (paper Section 3.2, Appendix E).

Shape distance (equation 12), estimated on boundary samples::

    d(f_i, f_j) = sqrt( mean_{x in dOmega_i} f_j(x)^2 + mean_{x in dOmega_j} f_i(x)^2 )

We normalise each boundary integral by the number of samples (a mean, i.e. the integral divided
by the boundary's measure), so that ``d`` is a root-mean-square distance when the fields are SDFs
and does not grow with the size of the boundary. Gradients flow through the field values, not
through the sample locations (the boundary sensitivity the paper leaves to future work).

Near a collapse the loss is singular: with the minimal aggregation and ``p = 1/2``,
``d delta / d d_i = sqrt(delta / d_i)`` grows without bound as shape ``i`` and its nearest
neighbour coincide (``d_i -> 0``) while the others stay apart, so at initialisation, where all
latents give nearly the same field, a weight as small as 1e-5 can dominate every other term
(observed: it empties the shapes of a softplus MLP). ``eps > 0`` (``diversity.eps``) smooths the
distance to ``sqrt(d_ij^2 + eps^2)``, which bounds that gradient and leaves distances well above
``eps`` unchanged; ``eps = 0`` is the paper's distance.

Aggregations (equations 9-11): minimal ``(sum_i (min_{j != i} d_ij)^p)^(1/p)`` (the paper's default
with ``p = 1/2``) and total ``(sum_i (sum_j d_ij)^p)^(1/p)``. The loss is ``-delta``.

Cost. The distance matrix needs every shape's field at every shape's boundary points: ``S^2 m``
evaluations. With the minimal aggregation only each shape's nearest neighbour carries gradient,
so :func:`diversity_nearest` finds the nearest pairs without a graph and evaluates only those (at
most ``2 S m`` points) with one: the same value and gradient as :func:`diversity` (tested in
float64), at a cost that grows like ``S m`` for the part that backpropagates.

The nearest pairs are found exactly without the whole matrix (:func:`nearest_neighbours`, branch
and bound): every sum of squares over a shape's boundary samples is at least its sum over a part
of them, so the first quarter of the samples gives every pair a lower bound of ``d_ij^2``. The
pair with the lowest bound in each row is completed to its exact distance, which bounds the row's
nearest distance from above; a pair whose lower bound lies above it cannot be nearest. The other
pairs get the next quarter of their samples, which raises their bounds, are filtered again, and
so on until the pairs left are exact. Shapes that the diversity term has spread evenly have many
pairs within a few times the nearest distance, which one quarter cannot rule out and two or three
do: on a trained 16-shape obstacle (128 samples per shape) about 20 000 evaluations per step
instead of ``S^2 m = 32 768`` (27 000 when every pair left open by the first quarter is
completed at once).
"""

from __future__ import annotations

import torch
from torch import Tensor

from ..fields import Field

_TINY = 1e-12


def aggregate_min(D: Tensor, p: float = 0.5) -> Tensor:
    """Minimal aggregation of a distance matrix ``(S, S)`` (diagonal ignored) -> scalar."""
    S = D.shape[0]
    if S < 2:
        return D.new_zeros(())
    eye = torch.eye(S, dtype=torch.bool, device=D.device)
    nearest = D.masked_fill(eye, float("inf")).min(dim=1).values
    return nearest.clamp_min(_TINY).pow(p).sum().pow(1.0 / p)


def aggregate_sum(D: Tensor, p: float = 1.0) -> Tensor:
    """Total aggregation of a distance matrix ``(S, S)`` -> scalar."""
    if D.shape[0] < 2:
        return D.new_zeros(())
    eye = torch.eye(D.shape[0], dtype=torch.bool, device=D.device)
    return D.masked_fill(eye, 0.0).sum(dim=1).clamp_min(_TINY).pow(p).sum().pow(1.0 / p)


def aggregate(D: Tensor, kind: str = "min", p: float = 0.5) -> Tensor:
    if kind == "min":
        return aggregate_min(D, p)
    if kind == "sum":
        return aggregate_sum(D, p)
    raise ValueError(f"unknown aggregation {kind!r} (min, sum)")


def cross_values(field: Field, xb: Tensor, Z: Tensor) -> Tensor:
    """Values of every shape's field at every shape's boundary points, in one batched pass.

    Arguments:
        xb: boundary points ``(S, m, d)`` (detached; row i samples dOmega_i).
        Z: latent codes ``(S, k)``.

    Returns:
        ``V`` of shape ``(S, S, m)`` with ``V[i, j] = f_j(xb[i])``.
    """
    S, m, d = xb.shape
    k = Z.shape[-1]
    X = xb[:, None, :, :].expand(S, S, m, d).reshape(-1, d)
    ZZ = Z[None, :, None, :].expand(S, S, m, k).reshape(-1, k)
    return field(X, ZZ).reshape(S, S, m)


def pair_values(field: Field, x: Tensor, z: Tensor) -> Tensor:
    """Values of pair ``p``'s field at pair ``p``'s points: ``x (P, n, d)``, ``z (P, k)`` -> ``(P, n)``
    (``x`` the samples of one shape, ``z`` the latent code of another)."""
    P, n, d = x.shape
    return field(x.reshape(-1, d), z[:, None, :].expand(P, n, z.shape[-1]).reshape(-1, z.shape[-1])).reshape(P, n)


def distance_matrix(V: Tensor, mask: Tensor | None = None, eps: float = 0.0) -> Tensor:
    """Equation 12 from cross values ``V (S, S, m)`` (``V[i, j] = f_j`` on dOmega_i).

    ``mask (S, m)`` marks valid boundary samples of each shape (None: all valid); ``eps``
    smooths the distance to ``sqrt(. + eps^2)`` (module docstring; 0: the paper's).
    Returns the symmetric ``(S, S)`` distance matrix.
    """
    sq = V * V
    if mask is None:
        A = sq.mean(dim=-1)
    else:
        w = mask.to(V.dtype)
        A = (sq * w[:, None, :]).sum(-1) / w.sum(-1).clamp_min(1.0)[:, None]
    if eps > 0:
        return (A + A.T + eps * eps).sqrt()
    return (A + A.T).clamp_min(_TINY).sqrt()


def diversity(
    field: Field, xb: Tensor, Z: Tensor, mask: Tensor | None = None, kind: str = "min", p: float = 0.5, eps: float = 0.0
) -> Tensor:
    """The diversity ``delta`` of the shapes ``{f(., z_i)}`` from their boundary samples ``xb (S, m, d)``
    (the full ``S x S`` computation; see :func:`diversity_nearest` for the cheap exact form of the
    minimal aggregation)."""
    D = distance_matrix(cross_values(field, xb, Z), mask, eps)
    return aggregate(D, kind, p)


def _mean_sq(V: Tensor, w: Tensor | None) -> Tensor:
    """``mean_x V^2`` per row of ``V (P, m)``, over the valid samples ``w (P, m)`` when given."""
    sq = V * V
    if w is None:
        return sq.mean(dim=-1)
    return (sq * w).sum(-1) / w.sum(-1).clamp_min(1.0)


def nearest_neighbours(field: Field, xb: Tensor, Z: Tensor, mask: Tensor | None = None,
                       prefix: int | None = None) -> Tensor:
    """Each shape's nearest other shape under the distance of equation 12, exactly, without a graph
    (module docstring: lower bounds from blocks of ``prefix`` samples, refined block by block for
    the pairs that can still be nearest).

    Arguments:
        field: ``(x, z) -> (n,)``.
        xb: boundary points ``(S, m, d)``, ``S >= 2``; Z: latent codes ``(S, k)``.
        mask: valid boundary samples ``(S, m)`` or None.
        prefix: samples per block (None: a quarter of ``m``, at least 1).

    Returns:
        ``(S,)`` indices: the argmin over ``j != i`` of ``d_ij``.
    """
    S, m, _ = xb.shape
    b = max(1, m // 4) if prefix is None else min(max(1, int(prefix)), m)
    with torch.no_grad():
        w = torch.ones(S, m, dtype=xb.dtype, device=xb.device) if mask is None else mask.to(xb.dtype)
        n = w.sum(-1).clamp_min(1.0)  # (S,) the mean's denominator over all samples
        V1 = cross_values(field, xb[:, :b].contiguous(), Z)  # (S, S, b)
        part = (V1 * V1 * w[:, None, :b]).sum(-1) / n[:, None]  # A_ij over the samples seen so far
        eye = torch.eye(S, dtype=torch.bool, device=xb.device)
        bound = (part + part.T).masked_fill(eye, float("inf"))  # <= d_ij^2 (before eps)
        if b == m:
            return bound.argmin(dim=1)

        def add(rows: Tensor, cols: Tensor, lo: int, hi: int) -> Tensor:
            """Samples ``lo:hi`` added to the partial sums of the pairs (rows, cols) and (cols, rows);
            returns the ``(S, S)`` mask of the pairs added in both directions."""
            key = torch.unique(torch.cat([rows * S + cols, cols * S + rows]))
            r, c = key // S, key % S
            V = pair_values(field, xb[r, lo:hi], Z[c])
            part[r, c] += (V * V * w[r, lo:hi]).sum(-1) / n[r]
            done = torch.zeros(S, S, dtype=torch.bool, device=part.device)
            done[r, c] = True
            return done & done.T

        i = torch.arange(S, device=xb.device)
        first = bound.argmin(dim=1)
        exact = torch.full_like(bound, float("inf"))
        both = add(i, first, b, m)  # only these pairs' sums go past the first block
        exact[both] = (part + part.T)[both]
        best = exact.min(dim=1).values  # (S,) an upper bound of each row's nearest d^2
        # the pairs whose bound is below their row's best, one more block at a time: a bound only
        # grows and a best only falls, so the pairs still open at a block were open at the last
        for lo in range(b, m, b):
            hi = min(m, lo + b)
            open_ = (bound <= best[:, None]) & ~torch.isfinite(exact)
            if not open_.any():
                break
            r, c = open_.nonzero(as_tuple=True)
            both = add(r, c, lo, hi)
            bound = torch.where(both, part + part.T, bound)
            if hi == m:
                exact[both] = bound[both]
                best = exact.min(dim=1).values
        return exact.argmin(dim=1)


def diversity_nearest(
    field: Field, xb: Tensor, Z: Tensor, mask: Tensor | None = None, p: float = 0.5, eps: float = 0.0
) -> Tensor:
    """The minimal-aggregation diversity, with a graph only through each shape's nearest pair.

    Arguments:
        field: ``(x, z) -> (n,)``.
        xb: boundary points ``(S, m, d)`` (detached; row i samples dOmega_i).
        Z: latent codes ``(S, k)``.
        mask: valid boundary samples ``(S, m)`` or None.
        p, eps: as in :func:`diversity`.

    Returns:
        the scalar ``delta``, equal in value and gradient to ``diversity(..., kind="min")``.
    """
    S = xb.shape[0]
    if S < 2:
        return xb.new_zeros(())
    near = nearest_neighbours(field, xb, Z, mask)  # (S,)
    i = torch.arange(S, device=near.device)
    # ordered pairs (row shape r, field of shape c): A[i, n(i)] and A[n(i), i] for every i
    key = torch.cat([i * S + near, near * S + i])
    pairs, inverse = torch.unique(key, return_inverse=True)
    rows, cols = pairs // S, pairs % S
    V = pair_values(field, xb[rows], Z[cols])
    A = _mean_sq(V, None if mask is None else mask[rows].to(V.dtype))
    a_in, a_out = A[inverse[:S]], A[inverse[S:]]  # A[i, n(i)], A[n(i), i]
    nearest = (a_in + a_out + eps * eps).sqrt() if eps > 0 else (a_in + a_out).clamp_min(_TINY).sqrt()
    return nearest.clamp_min(_TINY).pow(p).sum().pow(1.0 / p)


class _Take(torch.autograd.Function):
    """``src.reshape(-1)[index]`` whose gradient adds the duplicates of ``index`` in their order.

    The gradient of advanced indexing adds the values of repeated indices on several threads at
    once on the CPU, in an order that changes from one call to the next: the same step gave other
    weights on every run on two threads. A one-dimensional ``index_add_`` adds them one after
    another, as the indexing's gradient does on one thread (the same bits there)."""

    @staticmethod
    def forward(ctx, src: Tensor, index: Tensor) -> Tensor:
        ctx.save_for_backward(index)
        ctx.shape = src.shape
        return src.reshape(-1)[index]

    @staticmethod
    def backward(ctx, grad: Tensor):
        (index,) = ctx.saved_tensors
        out = grad.new_zeros(ctx.shape.numel())
        out.index_add_(0, index.reshape(-1), grad.reshape(-1))
        return out.view(ctx.shape), None


def take(src: Tensor, index: Tensor) -> Tensor:
    """``src.reshape(-1)[index]`` (``index``: flat positions, any shape), its gradient the same on
    every call and thread count (:class:`_Take`)."""
    return _Take.apply(src, index)


def shape_shares(D: Tensor) -> Tensor:
    """Each shape's mean distance to the others, ``(1/(S-1)) sum_{j != i} D_ij``, of a distance
    matrix ``(S, S)`` (diagonal ignored) -> ``(S,)``: the rows that equation 6 aggregates."""
    S = D.shape[0]
    if S < 2:
        return D.new_zeros((S,))
    eye = torch.eye(S, dtype=torch.bool, device=D.device)
    return D.masked_fill(eye, 0.0).sum(dim=1) / (S - 1)


def mean_diversity(D: Tensor) -> Tensor:
    """Equation 6, ``[mean_i ((1/(S-1)) sum_{j != i} D_ij)^(1/2)]^2``, of a distance matrix ``(S, S)``
    (diagonal ignored) -> scalar: the aggregation ``ginn eval`` reports as ``diversity_mean``."""
    if D.shape[0] < 2:
        return D.new_zeros(())
    return shape_shares(D).clamp_min(_TINY).sqrt().mean().square()


def boundary_distances(x: Tensor, mask: Tensor | None, f: Tensor, grad: Tensor, chunk: int = 1 << 24) -> Tensor:
    """The distance from each boundary sample of each shape to every other shape's boundary,
    ``V (S, S, m)`` with ``V[i, j, k]`` the distance from sample ``k`` of shape ``i`` to shape ``j``.

    Arguments:
        x: boundary samples ``(S, m, d)`` (detached; ``f = 0`` there up to the projection's tolerance).
        mask: valid samples ``(S, m)`` or None.
        f: the field of each shape at its own samples ``(S, m)``, with its graph.
        grad: its gradient there ``(S, m, d)`` (detached).

    Value: with ``y`` the nearest valid sample of the other shape, ``n`` its unit normal and ``h``
    the distance from ``y`` to the nearest other sample of its own shape (the spacing of the
    samples there), ``max(|(x - y) . n|, |x - y| - h)``: the distance to the boundary's tangent at
    ``y`` where ``x`` faces it, so that a shape's distance to a copy of itself sampled elsewhere is
    its curvature's sagitta rather than the samples' spacing, and never below the distance to
    ``y`` less ``h`` (where the boundary ends or bends away). Gradient: the boundary sensitivity;
    the field of shape ``j`` moved by ``df`` at ``y`` moves its boundary by ``-df / |grad f|``
    along ``n`` and the distance by ``(df / |grad f|) n . u``, ``u`` the distance's gradient in
    ``x``; the sample's own shape moves ``x`` likewise, with the opposite sign. The field terms
    enter as ``f - f.detach()``, so the value is the distance above exactly.
    """
    S, m, d = x.shape
    valid = torch.ones(S, m, dtype=torch.bool, device=x.device) if mask is None else mask.bool()
    gn = grad.norm(dim=-1).clamp_min(_TINY)  # (S, m)
    n = grad / gn[..., None]
    moved = (f - f.detach()) / gn  # (S, m): the boundary's displacement against its normal, zero in value
    Y = x.reshape(S * m, d)
    far = torch.where(valid.reshape(1, S * m), 0.0, float("inf")).to(x.dtype)
    rows = max(1, chunk // max(m * S * m, 1))  # shapes per block of at most ``chunk`` distances
    near = []
    with torch.no_grad():
        own = torch.cdist(x, x, compute_mode="donot_use_mm_for_euclid_dist")  # (S, m, m)
        own = own + torch.where(valid[:, None, :], 0.0, float("inf")).to(x.dtype)
        own.diagonal(dim1=1, dim2=2).fill_(float("inf"))
        h = own.min(dim=-1).values  # (S, m): each sample's spacing
        h = torch.where(torch.isfinite(h), h, torch.zeros_like(h))
        for lo in range(0, S, rows):
            dist = torch.cdist(x[lo: lo + rows], Y[None].expand(min(rows, S - lo), S * m, d),
                               compute_mode="donot_use_mm_for_euclid_dist") + far  # (r, m, S m)
            near.append(dist.reshape(-1, m, S, m).min(dim=-1))
        k = torch.cat([v.indices for v in near]).permute(0, 2, 1)  # (S_i, S_j, m): the nearest sample of shape j
        j = torch.arange(S, device=x.device)[:, None].expand(S, m)[None].expand(S, S, m)
        r = x[:, None] - x[j, k]  # (S, S, m, d): from y to x
        ny = n[j, k]
        along = (r * ny).sum(-1)
        dist = r.norm(dim=-1)
        tangent = along.abs() >= dist - h[j, k]
        u = torch.where(tangent[..., None], along.sign()[..., None] * ny, r / dist.clamp_min(_TINY)[..., None])
        d0 = torch.where(tangent, along.abs(), dist - h[j, k])
        at_y = j * m + k  # (S_i, S_j, m): y's flat position among the samples
    mine = moved[:, None] * (n[:, None] * u).sum(-1)  # shape i's sample moves
    other = take(moved, at_y) * (ny * u).sum(-1)  # shape j's boundary moves at y
    return d0 + other - mine
