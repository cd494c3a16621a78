"""Value and input gradient of a SIREN in one pass, with a hand-written backward.

The engine's generic path gets ``grad_x f`` by ``torch.autograd.grad(create_graph=True)`` and the
loss then back-propagates through that gradient graph (double backward). For a SIREN the same
numbers follow from a short explicit recursion, and its adjoint can be written out once:

Forward (layer ``l = 1..L``, effective weights ``W_l`` with omega folded in, ``h_0 = [x, z]``)::

    a_l = h_{l-1} W_l^T + b_l,   s_l = sin a_l,   c_l = cos a_l,   h_l = s_l
    f   = h_L w^T + b
    delta_L = w,   u_l = delta_l * c_l,   delta_{l-1} = u_l W_l,   grad_x f = u_1 W_1[:, :d]

Backward (given ``f_bar``, ``g_bar``): the adjoint of the gradient recursion runs forward through
the layers (``u_bar_1 = g_bar W_1[:, :d]^T``, ``c_bar_l = u_bar_l * delta_l``,
``delta_bar_l = u_bar_l * c_l``, ``u_bar_{l+1} = delta_bar_l W_{l+1}^T``), then the adjoint of
the forward recursion runs back (``a_bar_l = h_bar_l * c_l - c_bar_l * s_l``,
``h_bar_{l-1} = a_bar_l W_l``), accumulating the weight gradients on the way.

It does the same six matrix products per hidden layer as autograd's double backward but about
half the elementwise passes over ``(n, width)`` arrays, which bound the speed on a CPU
(``benchmarks/derivatives.py``). The result is differentiable once w.r.t. the weights and the
inputs (what a loss of ``f`` and ``grad f`` needs); the engine keeps the generic path for
Hessians.

With ``compiled=True`` both recursions run as ``torch.compile`` kernels, which fuse the
elementwise passes of each layer (sine, cosine and the products) into one loop over the
activations: the same numbers to float32 rounding in fewer passes over memory
(``benchmarks/derivatives.py --compile``). The first call with a new shape compiles (a few
seconds; torch keeps the kernels in its on-disk cache for later processes). Where compiling
fails (no C++ compiler, no Triton for the GPU) the eager kernels take over for the rest of the
process, with one warning.
"""

from __future__ import annotations

import warnings

import torch
from torch import Tensor


def _forward(h0: Tensor, d: int, weights: list[Tensor], biases: list[Tensor], w: Tensor, b: Tensor):
    """``f (n,)``, ``g (n, d)`` and the intermediates the backward needs."""
    S = [h0]
    C = []
    h = h0
    for W, bb in zip(weights, biases):
        a = torch.addmm(bb, h, W.t())
        h = torch.sin(a)
        C.append(torch.cos(a))
        S.append(h)
    f = torch.addmm(b, h, w.t()).squeeze(-1)
    L = len(weights)
    U: list[Tensor] = [None] * L  # type: ignore[list-item]
    D: list[Tensor] = [None] * L  # type: ignore[list-item]  # delta_l, the input to u_l (D[L-1] = w)
    delta = w
    for l in range(L - 1, -1, -1):
        D[l] = delta
        U[l] = delta * C[l]
        if l > 0:
            delta = U[l] @ weights[l]
    g = U[0] @ weights[0][:, :d]
    return f, g, S, C, U, D


def _backward(f_bar, g_bar, d, weights, w, S, C, U, D, need_h0: bool):
    L = len(weights)
    dW = [None] * L
    db = [None] * L
    dw = torch.zeros_like(w)
    # adjoint of the gradient recursion: forward through the layers
    c_bar: list[Tensor | None] = [None] * L
    if g_bar is not None:
        dW0 = torch.zeros_like(weights[0])
        dW0[:, :d] = U[0].t() @ g_bar
        dW[0] = dW0
        u_bar = g_bar @ weights[0][:, :d].t()
        for l in range(L):
            delta = D[l]
            c_bar[l] = u_bar * delta
            delta_bar = u_bar * C[l]
            if l < L - 1:
                dW[l + 1] = U[l + 1].t() @ delta_bar
                u_bar = delta_bar @ weights[l + 1].t()
            else:
                dw = dw + delta_bar.sum(0, keepdim=True)
    # adjoint of the forward recursion: back through the layers
    h_bar = None
    if f_bar is not None:
        h_bar = f_bar[:, None] * w
        dw = dw + (f_bar[None, :] @ S[L])
        db_out = f_bar.sum().reshape(1)
    else:
        db_out = torch.zeros(1, dtype=w.dtype, device=w.device)
    dh0 = None
    for l in range(L - 1, -1, -1):
        if h_bar is None and c_bar[l] is None:
            a_bar = None
        elif c_bar[l] is None:
            a_bar = h_bar * C[l]
        elif h_bar is None:
            a_bar = -(c_bar[l] * S[l + 1])
        else:
            a_bar = torch.addcmul(h_bar * C[l], c_bar[l], S[l + 1], value=-1.0)
        if a_bar is None:
            h_bar = None
            continue
        gW = a_bar.t() @ S[l]
        dW[l] = gW if dW[l] is None else dW[l] + gW
        db[l] = a_bar.sum(0)
        if l > 0:
            h_bar = a_bar @ weights[l]
        elif need_h0:
            dh0 = a_bar @ weights[0]
    for l in range(L):
        if dW[l] is None:
            dW[l] = torch.zeros_like(weights[l])
        if db[l] is None:
            db[l] = torch.zeros(weights[l].shape[0], dtype=w.dtype, device=w.device)
    return dh0, dW, db, dw, db_out


class _SirenValueGrad(torch.autograd.Function):
    """``(h0, d, compiled, W_1, b_1, ..., W_L, b_L, w, b) -> (f (n,), grad_x f (n, d))``."""

    @staticmethod
    def forward(ctx, h0: Tensor, d: int, compiled: bool, *params: Tensor):
        weights, biases = list(params[0:-2:2]), list(params[1:-2:2])
        w, b = params[-2], params[-1]
        f, g, S, C, U, D = KERNELS.get(0, compiled)(h0, d, weights, biases, w, b)
        ctx.d = d
        ctx.L = len(weights)
        ctx.compiled = compiled
        ctx.save_for_backward(w, *weights, *S, *C, *U, *D[:-1])
        ctx.set_materialize_grads(False)
        return f, g

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, f_bar: Tensor | None, g_bar: Tensor | None):
        L, d = ctx.L, ctx.d
        saved = ctx.saved_tensors
        w = saved[0]
        weights = list(saved[1 : 1 + L])
        S = list(saved[1 + L : 2 + 2 * L])
        C = list(saved[2 + 2 * L : 2 + 3 * L])
        U = list(saved[2 + 3 * L : 2 + 4 * L])
        D = list(saved[2 + 4 * L : 1 + 5 * L]) + [w]
        dh0, dW, db, dw, db_out = KERNELS.get(1, ctx.compiled)(f_bar, g_bar, d, weights, w, S, C, U, D,
                                                           ctx.needs_input_grad[0])
        grads: list[Tensor | None] = [dh0, None, None]
        for Wg, bg in zip(dW, db):
            grads += [Wg, bg]
        grads += [dw, db_out]
        return tuple(grads)


def siren_value_and_grad(
    h0: Tensor, d: int, weights: list[Tensor], biases: list[Tensor], w: Tensor, b: Tensor, compiled: bool = False
) -> tuple[Tensor, Tensor]:
    """Value ``(n,)`` and gradient w.r.t. the first ``d`` input columns ``(n, d)`` of the SIREN
    ``h0 -> sin(... sin(h0 W_1^T + b_1) ...) w^T + b``.

    Arguments:
        h0: first-layer input ``(n, p)`` (points in its first ``d`` columns, then latent codes).
        weights, biases: effective sine-layer parameters (omega folded in), ``(m_l, m_{l-1})``, ``(m_l,)``.
        w, b: output layer, ``(1, m_L)`` and ``(1,)``.
        compiled: when autograd is recording, run the ``torch.compile`` kernels (module docstring).

    Differentiable once w.r.t. every argument when autograd is recording; plain tensors otherwise.
    """
    params = [p for pair in zip(weights, biases) for p in pair] + [w, b]
    record = torch.is_grad_enabled() and (h0.requires_grad or any(p.requires_grad for p in params))
    rows = block_rows(max(W.shape[0] for W in weights))
    fs, gs = [], []
    for hc in h0.split(rows) if h0.shape[0] > rows else (h0,):
        if record:
            f, g = _SirenValueGrad.apply(hc, d, compiled, *params)
        else:
            f, g, *_ = _forward(hc, d, weights, biases, w, b)
        fs.append(f)
        gs.append(g)
    if len(fs) == 1:
        return fs[0], gs[0]
    return torch.cat(fs), torch.cat(gs)


def block_rows(width: int) -> int:
    """Rows per block: the points are processed in blocks whose ``(rows, width)`` activations
    (4 MB in float32 at width 256) stay in a CPU's cache between the elementwise passes; measured
    13-20 % faster than one block of 18,000 rows (``benchmarks/derivatives.py``)."""
    return max(256, (1 << 20) // max(width, 1))


class Kernels:
    """The two recursions, eager and compiled: one instance per process (:data:`KERNELS`), since
    torch keeps a compiled function's code per function object.

    Attributes:
        compiled: the forward and backward recursions under ``torch.compile``, made at their first use.
        failed: compiling failed in this process: every later call runs eagerly.
    """

    def __init__(self) -> None:
        self.eager = (_forward, _backward)
        self.compiled: tuple | None = None
        self.failed = False

    def get(self, which: int, compiled: bool):
        """The forward (``which = 0``) or backward (1) recursion, compiled or eager."""
        if not compiled or self.failed:
            return self.eager[which]
        if self.compiled is None:
            # static shapes: the code generated for a kernel depends only on its shapes (a dynamic
            # kernel's depends on the sizes it first saw), so a resumed run, a fresh process, computes
            # with the uninterrupted run's kernels; a training pass has one shape for the whole run
            self.compiled = (torch.compile(_forward, dynamic=False), torch.compile(_backward, dynamic=False))
        return lambda *args: self.call(which, *args)

    def call(self, which: int, *args):
        """A compiled kernel; where compiling fails, this process switches to the eager kernels
        (with one warning) and returns their result."""
        try:
            return self.compiled[which](*args)  # type: ignore[index]
        except Exception as e:  # noqa: BLE001 - any failure of the compiler stack, e.g. no C++ compiler
            self.failed = True
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            warnings.warn(f"torch.compile failed ({first[:200]}); the SIREN derivatives run uncompiled", stacklevel=2)
            return self.eager[which](*args)


#: this process's kernels
KERNELS = Kernels()
