"""The one derivative engine: values, gradients and Hessians of a field at points.

Every loss, the critical-point search and the metrics get ``f``, ``grad f`` and the Hessian from
here; nothing else in ginn calls :func:`torch.autograd.grad` on a field.

A *field* is any callable ``field(x, z) -> (n,)`` (a :class:`ginn.models.NeuralField`, an exact
SDF wrapped with :func:`as_field`, ...).

Two modes:

* ``create_graph=True`` (training): results stay differentiable w.r.t. the model parameters.
* ``create_graph=False`` (critical points, metrics): results are detached, nothing is kept.

Hessians are computed only at the points asked for (``hessian_at``), by a separate forward pass
on those points followed by ``d`` reverse passes through the gradient (eager double backward),
which measured faster on CPU than ``torch.func`` ``vmap(jacrev(jacrev))``
(see ``benchmarks/derivatives.py``).

Curvature conventions (``n = grad f / |grad f|`` points out of the shape ``{f <= 0}``):

* ``divergence_of_normal`` = ``div n`` = sum of the principal curvatures (the Table 1 quantity);
  positive for a convex shape: ``2 / r`` for a sphere, ``1 / r`` for a circle.
* ``mean_curvature`` = ``div n / (d - 1)``: ``1 / r`` for a sphere *and* a circle.
  (Goldman 2005 defines kappa_M with the opposite sign; we use the outward-normal convention.)
* ``gaussian_curvature`` (3D) = ``kappa_1 kappa_2``: ``1 / r^2`` for a sphere.
* ``surface_strain`` = ``kappa_1^2 + kappa_2^2`` (3D) or ``kappa^2`` (2D): ``2 / r^2`` for a
  sphere, ``1 / r^2`` for a cylinder.

All follow from the shape operator ``S = P H P / |grad f|`` with ``P = I - n n^T``: its eigenvalues
are the principal curvatures (and 0 along ``n``), so ``div n = tr S`` and strain ``= ||S||_F^2``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch
from torch import Tensor

Field = Callable[[Tensor, "Tensor | None"], Tensor]

_EPS = 1e-12


@dataclass
class FieldValues:
    """Derivatives of a field at ``n`` points.

    Attributes:
        x: the points, ``(n, d)`` (requires grad when derivatives were taken).
        f: values, ``(n,)``.
        grad: gradients w.r.t. ``x``, ``(n, d)``, or ``None``.
        hessian: Hessians at the points selected by ``hessian_index``, ``(m, d, d)``, or ``None``.
        hessian_index: indices into ``x`` of the Hessian rows, ``(m,)``, or ``None``.
        hessian_grad: gradients at those points, ``(m, d)`` (from the same pass as the Hessian).
    """

    x: Tensor
    f: Tensor
    grad: Tensor | None = None
    hessian: Tensor | None = None
    hessian_index: Tensor | None = None
    hessian_grad: Tensor | None = None


def _as_index(sel: Tensor | slice | bool | None, n: int, device: torch.device) -> Tensor | None:
    if sel is None or sel is False:
        return None
    if sel is True:
        return torch.arange(n, device=device)
    if isinstance(sel, slice):
        return torch.arange(n, device=device)[sel]
    sel = torch.as_tensor(sel, device=device)
    if sel.dtype == torch.bool:
        return torch.nonzero(sel, as_tuple=False).squeeze(-1)
    return sel.long()


def _grad_of(f: Tensor, x: Tensor, create_graph: bool) -> Tensor:
    (g,) = torch.autograd.grad(f.sum(), x, create_graph=create_graph, retain_graph=True)
    return g


def _hessian_rows(g: Tensor, x: Tensor, create_graph: bool) -> Tensor:
    """Hessian ``(m, d, d)`` from gradients ``g`` (m, d) that depend on ``x`` (m, d), pointwise."""
    d = x.shape[-1]
    if not g.requires_grad:  # the gradient does not depend on x (an affine field)
        return x.new_zeros((x.shape[0], d, d))
    rows = []
    for i in range(d):
        (hi,) = torch.autograd.grad(
            g[:, i].sum(), x, create_graph=create_graph, retain_graph=True, allow_unused=True, materialize_grads=True
        )
        rows.append(hi)
    return torch.stack(rows, dim=1)


def evaluate(
    field: Field,
    x: Tensor,
    z: Tensor | None = None,
    *,
    grad: bool = True,
    hessian_at: Tensor | slice | bool | None = None,
    create_graph: bool = True,
    fast: bool = True,
) -> FieldValues:
    """Value, gradient and (optionally, at a subset) Hessian of ``field`` at ``x``.

    Arguments:
        field: callable ``(x, z) -> (n,)``.
        x: points ``(n, d)``.
        z: latent codes ``(n, k)`` or ``None``; constants w.r.t. ``x``.
        grad: compute ``grad f`` at every point.
        hessian_at: ``None`` (no Hessian), ``True`` (every point), an index tensor ``(m,)`` or a
            boolean mask ``(n,)`` selecting the points that need a Hessian.
        create_graph: keep results differentiable w.r.t. the parameters (training); when False
            everything returned is detached.
        fast: let a field with a ``value_and_grad(x, z)`` method (a SIREN) compute ``f`` and
            ``grad f`` at the non-Hessian points itself (same numbers, hand-written backward);
            False forces autograd everywhere (for comparisons).

    Returns:
        :class:`FieldValues`.
    """
    n = x.shape[0]
    idx = _as_index(hessian_at, n, x.device)
    if idx is not None and 0 < idx.numel():
        split = _split_hessian_points(idx, n)
        if split is not None:
            return _evaluate_split(field, x, z, grad, idx, split, create_graph, fast)
    if grad and fast and idx is None and (vg := _fast_value_grad(field, x, z, create_graph)) is not None:
        return FieldValues(x=x.detach(), f=vg[0], grad=vg[1])
    with torch.enable_grad():
        xr = x.detach().requires_grad_(True) if grad else x.detach()
        f = field(xr, z)
        _check_values(f)
        out = FieldValues(x=xr, f=f)
        if grad:
            out.grad = _grad_of(f, xr, create_graph)
        if idx is not None:  # here: an empty selection, or repeated indices (not split)
            if idx.numel() > 0:
                h = _hessian_pass(field, x.detach()[idx], None if z is None else z[idx], create_graph)
                out.hessian, out.hessian_grad = h.hessian, h.hessian_grad
            else:
                d = x.shape[-1]
                out.hessian, out.hessian_grad = x.new_zeros((0, d, d)), x.new_zeros((0, d))
            out.hessian_index = idx
    return _detached(out) if not create_graph else out


def _fast_value_grad(field: Field, x: Tensor, z: Tensor | None, create_graph: bool) -> tuple[Tensor, Tensor] | None:
    """``(f, grad f)`` from the field's own ``value_and_grad``, or ``None`` where it has none."""
    method = getattr(field, "value_and_grad", None)
    if method is None:
        return None
    x = x.detach()
    if create_graph:
        with torch.enable_grad():
            return method(x, z)
    with torch.no_grad():
        return method(x, z)


def _check_values(f: Tensor) -> None:
    if f.dim() != 1:
        raise ValueError(f"a field must return values of shape (n,), got {tuple(f.shape)}")


def _split_hessian_points(idx: Tensor, n: int) -> Tensor | None:
    """Indices of the points *not* in ``idx``, or ``None`` when ``idx`` repeats a point.

    With distinct indices the Hessian pass also yields ``f`` and ``grad f`` at its points, so the
    main pass runs only on the others (no point goes through the network twice).
    """
    mask = torch.zeros(n, dtype=torch.bool, device=idx.device)
    mask[idx] = True
    if int(mask.sum()) != idx.numel():
        return None
    return torch.nonzero(~mask, as_tuple=False).squeeze(-1)


def _hessian_pass(field: Field, xh: Tensor, zh: Tensor | None, create_graph: bool) -> FieldValues:
    """``f``, ``grad f`` and the Hessian at every point of ``xh`` (one forward, ``1 + d`` reverse passes)."""
    xh = xh.detach().requires_grad_(True)
    fh = field(xh, zh)
    _check_values(fh)
    gh = _grad_of(fh, xh, True)
    H = _hessian_rows(gh, xh, create_graph)
    return FieldValues(x=xh, f=fh, grad=gh, hessian=H, hessian_grad=gh)


def _evaluate_split(
    field: Field, x: Tensor, z: Tensor | None, grad: bool, idx: Tensor, rest: Tensor, create_graph: bool, fast: bool
) -> FieldValues:
    """:func:`evaluate` with the Hessian points in their own pass and the others in the main one."""
    with torch.enable_grad():
        h = _hessian_pass(field, x[idx], None if z is None else z[idx], create_graph)
        if rest.numel() == 0:
            order, f, g = idx, h.f, h.grad
        elif grad and fast and (vg := _fast_value_grad(field, x[rest], None if z is None else z[rest], create_graph)) is not None:
            order = torch.cat([rest, idx])
            f = torch.cat([vg[0], h.f])
            g = torch.cat([vg[1], h.grad])
        else:
            xr = x.detach()[rest]
            if grad:
                xr.requires_grad_(True)
            fr = field(xr, None if z is None else z[rest])
            _check_values(fr)
            order = torch.cat([rest, idx])
            f = torch.cat([fr, h.f])
            g = torch.cat([_grad_of(fr, xr, create_graph), h.grad]) if grad else None
        if not torch.equal(order, torch.arange(order.numel(), device=order.device)):
            inv = torch.empty_like(order)
            inv[order] = torch.arange(order.numel(), device=order.device)
            f = f[inv]
            g = None if g is None else g[inv]
    out = FieldValues(
        x=x.detach(), f=f, grad=g if grad else None, hessian=h.hessian, hessian_index=idx, hessian_grad=h.hessian_grad
    )
    return _detached(out) if not create_graph else out


def _detached(out: FieldValues) -> FieldValues:
    for name in ("x", "f", "grad", "hessian", "hessian_grad"):
        t = getattr(out, name)
        if t is not None:
            setattr(out, name, t.detach())
    return out


def value(field: Field, x: Tensor, z: Tensor | None = None, chunk: int | None = None) -> Tensor:
    """Field values without any graph, ``(n,)``; evaluated in chunks of ``chunk`` points."""
    with torch.no_grad():
        if chunk is None or x.shape[0] <= chunk:
            return field(x, z)
        parts = []
        for s in range(0, x.shape[0], chunk):
            parts.append(field(x[s : s + chunk], None if z is None else z[s : s + chunk]))
        return torch.cat(parts)


def gradient(field: Field, x: Tensor, z: Tensor | None = None, create_graph: bool = False) -> tuple[Tensor, Tensor]:
    """``(f, grad f)`` with shapes ``(n,)`` and ``(n, d)``."""
    v = evaluate(field, x, z, grad=True, create_graph=create_graph)
    assert v.grad is not None
    return v.f, v.grad


def hessian(
    field: Field, x: Tensor, z: Tensor | None = None, create_graph: bool = False
) -> tuple[Tensor, Tensor, Tensor]:
    """``(f, grad f, Hessian)`` at every point: ``(n,)``, ``(n, d)``, ``(n, d, d)``."""
    with torch.enable_grad():
        xr = x.detach().requires_grad_(True)
        f = field(xr, z)
        g = _grad_of(f, xr, True)
        h = _hessian_rows(g, xr, create_graph)
    if not create_graph:
        return f.detach(), g.detach(), h.detach()
    return f, g, h


# --- derived quantities (pure functions of grad and Hessian) ------------------------------------


def unit_normal(grad: Tensor) -> Tensor:
    """``grad f / |grad f|``, ``(n, d) -> (n, d)`` (outward for the shape ``{f <= 0}``)."""
    return grad / grad.norm(dim=-1, keepdim=True).clamp_min(_EPS)


def shape_operator(grad: Tensor, hess: Tensor) -> Tensor:
    """``S = P H P / |grad f|`` with ``P = I - n n^T``; ``(m, d), (m, d, d) -> (m, d, d)``.

    Its eigenvalues are the principal curvatures of the level set through each point (and 0).
    """
    gn = grad.norm(dim=-1).clamp_min(_EPS)
    n = grad / gn[:, None]
    eye = torch.eye(grad.shape[-1], dtype=grad.dtype, device=grad.device)
    P = eye - n[:, :, None] * n[:, None, :]
    return P @ hess @ P / gn[:, None, None]


def divergence_of_normal(grad: Tensor, hess: Tensor) -> Tensor:
    """``div(grad f / |grad f|)`` = sum of principal curvatures, ``(m,)``.

    Computed as ``(|g|^2 tr H - g^T H g) / |g|^3`` (equal to ``tr S``).
    """
    g2 = (grad * grad).sum(-1).clamp_min(_EPS)
    tr = torch.diagonal(hess, dim1=-2, dim2=-1).sum(-1)
    gHg = torch.einsum("mi,mij,mj->m", grad, hess, grad)
    return (g2 * tr - gHg) / g2.pow(1.5)


def mean_curvature(grad: Tensor, hess: Tensor) -> Tensor:
    """Mean curvature ``div n / (d - 1)``, ``(m,)``: ``1 / r`` for a circle and for a sphere."""
    d = grad.shape[-1]
    if d < 2:
        raise ValueError("mean curvature needs d >= 2")
    return divergence_of_normal(grad, hess) / (d - 1)


def surface_strain(grad: Tensor, hess: Tensor) -> Tensor:
    """Sum of squared principal curvatures ``||S||_F^2``, ``(m,)``: ``2 / r^2`` for a sphere."""
    S = shape_operator(grad, hess)
    return (S * S).sum(dim=(-2, -1))


def gaussian_curvature(grad: Tensor, hess: Tensor) -> Tensor:
    """Gaussian curvature ``kappa_1 kappa_2`` of a level set in 3D, ``(m,)``.

    ``((tr S)^2 - ||S||_F^2) / 2`` (the second elementary symmetric function of the curvatures).
    """
    if grad.shape[-1] != 3:
        raise ValueError("Gaussian curvature is defined here for d = 3")
    S = shape_operator(grad, hess)
    tr = torch.diagonal(S, dim1=-2, dim2=-1).sum(-1)
    return 0.5 * (tr * tr - (S * S).sum(dim=(-2, -1)))


def principal_curvatures(grad: Tensor, hess: Tensor) -> Tensor:
    """Principal curvatures in 3D, ``(m, 2)`` sorted ascending (from mean and Gaussian curvature)."""
    H = divergence_of_normal(grad, hess) / 2
    K = gaussian_curvature(grad, hess)
    disc = (H * H - K).clamp_min(0).sqrt()
    return torch.stack([H - disc, H + disc], dim=-1)


def laplacian(hess: Tensor) -> Tensor:
    """Trace of the Hessian, ``(m, d, d) -> (m,)``."""
    return torch.diagonal(hess, dim1=-2, dim2=-1).sum(-1)


def as_field(fn: Callable[[Tensor], Tensor]) -> Field:
    """Wrap a latent-free function ``x -> (n,)`` (an exact SDF, say) as a field ``(x, z) -> (n,)``."""

    def field(x: Tensor, z: Tensor | None = None) -> Tensor:
        return fn(x)

    return field


class Shifted:
    """The field ``f + c`` (a constant ``c``): same gradients and Hessians, a shifted level set.
    Keeps the wrapped field's fast path (``value_and_grad``)."""

    def __init__(self, field: Field, c: float):
        self.field, self.c = field, float(c)

    def __call__(self, x: Tensor, z: Tensor | None = None) -> Tensor:
        return self.field(x, z) + self.c

    def value_and_grad(self, x: Tensor, z: Tensor | None = None) -> tuple[Tensor, Tensor] | None:
        method = getattr(self.field, "value_and_grad", None)
        vg = None if method is None else method(x, z)
        return None if vg is None else (vg[0] + self.c, vg[1])


def broadcast_latents(x: Tensor, z: Tensor) -> tuple[Tensor, Tensor]:
    """All shapes in one batch.

    Arguments:
        x: points shared by all shapes ``(n, d)``, or per-shape points ``(s, n, d)``.
        z: latent codes ``(s, k)``.

    Returns:
        ``(s * n, d)`` points and ``(s * n, k)`` latents, shape-major (rows ``i*n:(i+1)*n`` belong
        to shape ``i``).
    """
    s = z.shape[0]
    if x.dim() == 2:
        x = x.unsqueeze(0).expand(s, -1, -1)
    if x.shape[0] != s:
        raise ValueError(f"got points for {x.shape[0]} shapes but {s} latent codes")
    n = x.shape[1]
    return x.reshape(s * n, x.shape[-1]), z[:, None, :].expand(s, n, z.shape[-1]).reshape(s * n, z.shape[-1])
