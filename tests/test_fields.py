"""The derivative engine against exact, hand-written fields in float64."""

import math

import pytest
import torch

from ginn import fields
from ginn.fields import as_field, evaluate

D = torch.float64


def sphere(r, c=None):
    def f(x):
        cc = torch.zeros(x.shape[-1], dtype=x.dtype) if c is None else torch.as_tensor(c, dtype=x.dtype)
        return (x - cc).norm(dim=-1) - r

    return as_field(f)


def cylinder_z(r):
    return as_field(lambda x: x[:, :2].norm(dim=-1) - r)


def plane(n, off):
    n = torch.tensor(n, dtype=D)
    n = n / n.norm()
    return as_field(lambda x: x @ n - off)


def points_on_sphere(m, r, d=3, gen=None):
    p = torch.randn(m, d, dtype=D, generator=gen)
    return r * p / p.norm(dim=-1, keepdim=True)


@pytest.mark.parametrize("r", [0.3, 1.0, 2.5])
def test_sphere_sdf(r, gen):
    x = points_on_sphere(200, r, gen=gen) * 1.3  # off the surface too: level sets are spheres
    rad = x.norm(dim=-1)
    v = evaluate(sphere(r), x, hessian_at=True, create_graph=False)
    assert torch.allclose(v.grad.norm(dim=-1), torch.ones(200, dtype=D), atol=1e-10)
    kH = fields.mean_curvature(v.hessian_grad, v.hessian)
    assert torch.allclose(kH, 1 / rad, atol=1e-6)
    assert torch.allclose(fields.divergence_of_normal(v.hessian_grad, v.hessian), 2 / rad, atol=1e-6)
    assert torch.allclose(fields.surface_strain(v.hessian_grad, v.hessian), 2 / rad**2, atol=1e-6)
    assert torch.allclose(fields.gaussian_curvature(v.hessian_grad, v.hessian), 1 / rad**2, atol=1e-6)
    k = fields.principal_curvatures(v.hessian_grad, v.hessian)
    assert torch.allclose(k, (1 / rad)[:, None].expand(-1, 2), atol=1e-6)
    assert torch.allclose(fields.laplacian(v.hessian), 2 / rad, atol=1e-6)


def test_cylinder_strain(gen):
    r = 0.7
    p = torch.randn(100, 3, dtype=D, generator=gen)
    p[:, :2] = r * p[:, :2] / p[:, :2].norm(dim=-1, keepdim=True)
    v = evaluate(cylinder_z(r), p, hessian_at=True, create_graph=False)
    assert torch.allclose(fields.surface_strain(v.grad, v.hessian), torch.full((100,), 1 / r**2, dtype=D), atol=1e-6)
    assert torch.allclose(fields.mean_curvature(v.grad, v.hessian), torch.full((100,), 0.5 / r, dtype=D), atol=1e-6)
    assert torch.allclose(fields.gaussian_curvature(v.grad, v.hessian), torch.zeros(100, dtype=D), atol=1e-6)


def test_plane_all_zero(gen):
    x = torch.randn(50, 3, dtype=D, generator=gen)
    v = evaluate(plane([1.0, 2.0, -0.5], 0.3), x, hessian_at=True, create_graph=False)
    for q in (fields.mean_curvature, fields.surface_strain, fields.gaussian_curvature):
        assert q(v.grad, v.hessian).abs().max() < 1e-10
    n = torch.tensor([1.0, 2.0, -0.5], dtype=D)
    assert torch.allclose(fields.unit_normal(v.grad), (n / n.norm()).expand(50, 3), atol=1e-12)


def test_circle_curvature_2d(gen):
    r = 0.4
    x = points_on_sphere(64, r, d=2, gen=gen)
    v = evaluate(sphere(r), x, hessian_at=True, create_graph=False)
    assert torch.allclose(fields.mean_curvature(v.grad, v.hessian), torch.full((64,), 1 / r, dtype=D), atol=1e-6)
    assert torch.allclose(fields.surface_strain(v.grad, v.hessian), torch.full((64,), 1 / r**2, dtype=D), atol=1e-6)


def test_quadratic_hessian(gen):
    A = torch.tensor([[2.0, 0.5, -1.0], [0.5, 3.0, 0.2], [-1.0, 0.2, 1.0]], dtype=D)
    b = torch.tensor([0.1, -0.2, 0.3], dtype=D)
    q = as_field(lambda x: 0.5 * torch.einsum("ni,ij,nj->n", x, A, x) + x @ b)
    x = torch.randn(30, 3, dtype=D, generator=gen)
    v = evaluate(q, x, hessian_at=torch.arange(0, 30, 3), create_graph=False)
    assert torch.allclose(v.grad, x @ A + b, atol=1e-12)
    assert v.hessian.shape == (10, 3, 3)
    assert torch.allclose(v.hessian, A.expand(10, 3, 3), atol=1e-12)
    assert torch.equal(v.hessian_index, torch.arange(0, 30, 3))


def test_hessian_mask_and_empty(gen):
    x = torch.randn(10, 2, dtype=D, generator=gen)
    mask = torch.zeros(10, dtype=torch.bool)
    v = evaluate(sphere(1.0), x, hessian_at=mask, create_graph=False)
    assert v.hessian.shape == (0, 2, 2)
    mask[3] = True
    v = evaluate(sphere(1.0), x, hessian_at=mask, create_graph=False)
    assert v.hessian.shape == (1, 2, 2)
    assert torch.allclose(v.hessian_grad[0], v.grad[3])


def test_differentiable_wrt_parameters():
    """create_graph=True: curvature losses backpropagate to the weights; gradcheck through the engine."""
    torch.manual_seed(0)
    lin1 = torch.nn.Linear(2, 8).double()
    lin2 = torch.nn.Linear(8, 1).double()
    x = torch.randn(5, 2, dtype=D)

    def loss_of(w1):
        def fld(p, z=None):
            return lin2(torch.tanh(torch.nn.functional.linear(p, w1, lin1.bias))).squeeze(-1)

        v = evaluate(fld, x, hessian_at=True, create_graph=True)
        return fields.divergence_of_normal(v.hessian_grad, v.hessian).pow(2).sum() + (v.grad.norm(dim=-1) - 1).pow(2).sum()

    w = lin1.weight.detach().clone().requires_grad_(True)
    assert torch.autograd.gradcheck(loss_of, (w,), eps=1e-6, atol=1e-5)


def test_detached_mode_keeps_no_graph(gen):
    model = torch.nn.Sequential(torch.nn.Linear(2, 4), torch.nn.Tanh(), torch.nn.Linear(4, 1))
    fld = lambda p, z=None: model(p).squeeze(-1)  # noqa: E731
    v = evaluate(fld, torch.randn(7, 2, generator=gen), hessian_at=True, create_graph=False)
    for t in (v.f, v.grad, v.hessian):
        assert not t.requires_grad


def test_broadcast_latents():
    x = torch.arange(6.0).reshape(3, 2)
    z = torch.tensor([[10.0], [20.0]])
    X, Z = fields.broadcast_latents(x, z)
    assert X.shape == (6, 2) and Z.shape == (6, 1)
    assert torch.equal(X[3:], x) and torch.all(Z[:3] == 10) and torch.all(Z[3:] == 20)
    with pytest.raises(ValueError):
        fields.broadcast_latents(torch.zeros(3, 4, 2), z)


def test_value_chunked_equals_unchunked(gen):
    f = sphere(0.5)
    x = torch.randn(1000, 3, dtype=D, generator=gen)
    assert torch.equal(fields.value(f, x, chunk=128), fields.value(f, x))


def test_full_hessian_helper(gen):
    x = torch.randn(4, 3, dtype=D, generator=gen)
    f, g, H = fields.hessian(sphere(1.0), x)
    rad = x.norm(dim=-1)
    expect = (torch.eye(3, dtype=D) - (x / rad[:, None])[:, :, None] * (x / rad[:, None])[:, None, :]) / rad[:, None, None]
    assert torch.allclose(H, expect, atol=1e-10)
    assert math.isclose(float(f[0]), float(rad[0] - 1), abs_tol=1e-12)


@pytest.mark.parametrize("sel", ["subset", "duplicates", "all"])
def test_hessian_points_split_from_the_main_pass(sel, gen):
    """Hessian points go through the network once: f, grad f and the parameter gradients equal
    those of separate full passes (a latent-conditioned field, float64)."""
    torch.manual_seed(1)
    net = torch.nn.Sequential(torch.nn.Linear(3, 16), torch.nn.Tanh(), torch.nn.Linear(16, 1)).double()
    fld = lambda p, z: net(torch.cat([p, z], dim=-1)).squeeze(-1)  # noqa: E731
    x = torch.randn(40, 2, dtype=D, generator=gen)
    z = torch.randn(40, 1, dtype=D, generator=gen)
    idx = {"subset": torch.tensor([31, 2, 17, 5]), "duplicates": torch.tensor([3, 3, 9]), "all": torch.arange(40)}[sel]

    def loss(v):
        div = fields.divergence_of_normal(v.hessian_grad, v.hessian)
        return (v.grad.norm(dim=-1) - 1).pow(2).sum() + v.f.pow(3).sum() + div.pow(2).sum()

    v = evaluate(fld, x, z, hessian_at=idx, create_graph=True)
    g_split = torch.autograd.grad(loss(v), list(net.parameters()))
    ref = evaluate(fld, x, z, grad=True, create_graph=True)  # no Hessian: one plain pass
    f_h, g_h, H = fields.hessian(fld, x[idx], z[idx], create_graph=True)
    assert torch.allclose(v.f, ref.f, atol=1e-14) and torch.allclose(v.grad, ref.grad, atol=1e-14)
    assert torch.allclose(v.hessian, H, atol=1e-14) and torch.equal(v.hessian_index, idx)
    ref.hessian, ref.hessian_grad = H, g_h
    g_ref = torch.autograd.grad(loss(ref), list(net.parameters()))
    for a, b in zip(g_split, g_ref):
        assert torch.allclose(a, b, atol=1e-12)
    w = evaluate(fld, x, z, grad=False, hessian_at=idx, create_graph=False)
    assert w.grad is None and torch.allclose(w.f, ref.f.detach(), atol=1e-14)


@pytest.mark.parametrize("hessian_at", [None, "subset"])
@pytest.mark.parametrize("block", [None, 7])
def test_siren_fast_path_equals_autograd(hessian_at, block, monkeypatch, gen):
    """The SIREN's hand-written value-and-gradient pass gives the autograd numbers: f, grad f and
    the parameter gradients of a loss of both (float64, latents, omega_0 != 1, in blocks of 7
    rows as well as in one block)."""
    from ginn.models import Siren, siren_grad

    if block is not None:
        monkeypatch.setattr(siren_grad, "block_rows", lambda width: block)
    torch.manual_seed(2)
    net = Siren(3, [24, 16, 16], latent_dim=2, w0_first=8.0, w0_hidden=2.0).double()
    x = torch.rand(40, 3, dtype=D, generator=gen) * 2 - 1
    z = torch.rand(40, 2, dtype=D, generator=gen)
    idx = torch.tensor([3, 29, 11]) if hessian_at else None

    def loss(v):
        out = (v.grad.norm(dim=-1) - 1).pow(2).sum() + v.f.pow(3).sum() + (v.f * v.grad[:, 1]).sum()
        return out if v.hessian is None else out + v.hessian.pow(2).sum()

    fast = evaluate(net, x, z, hessian_at=idx, create_graph=True)
    slow = evaluate(net, x, z, hessian_at=idx, create_graph=True, fast=False)
    assert torch.allclose(fast.f, slow.f, atol=1e-13) and torch.allclose(fast.grad, slow.grad, atol=1e-12)
    g_fast = torch.autograd.grad(loss(fast), list(net.parameters()))
    g_slow = torch.autograd.grad(loss(slow), list(net.parameters()))
    for a, b in zip(g_fast, g_slow):
        assert torch.allclose(a, b, rtol=1e-10, atol=1e-11)
    detached = evaluate(net, x, z, create_graph=False)
    assert not detached.grad.requires_grad and torch.allclose(detached.grad, slow.grad, atol=1e-12)


def test_siren_fast_path_gradcheck(gen):
    """First derivatives of the hand-written backward, inputs and every parameter (gradcheck)."""
    from ginn.models.siren_grad import _SirenValueGrad

    torch.manual_seed(3)
    h0 = torch.rand(6, 4, dtype=D, generator=gen).requires_grad_()
    sizes = [4, 5, 3]
    params = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        params += [torch.randn(b, a, dtype=D, requires_grad=True), torch.randn(b, dtype=D, requires_grad=True)]
    params += [torch.randn(1, sizes[-1], dtype=D, requires_grad=True), torch.randn(1, dtype=D, requires_grad=True)]
    assert torch.autograd.gradcheck(lambda h, *p: _SirenValueGrad.apply(h, 3, False, *p), (h0, *params))


def _fast_path_numbers(net, x, z):
    """f, grad f and the parameter gradients of a loss of both, by the SIREN's fast path."""
    v = evaluate(net, x, z, create_graph=True)
    loss = (v.grad.norm(dim=-1) - 1).pow(2).sum() + v.f.pow(3).sum() + (v.f * v.grad[:, 1]).sum()
    return [v.f.detach(), v.grad.detach(), *torch.autograd.grad(loss, list(net.parameters()))]


def test_compiled_siren_kernels_equal_the_eager_ones(gen):
    """``compile_derivatives`` runs the value-and-gradient pass and its backward as torch.compile
    kernels: the same f, grad f and parameter gradients as the eager kernels (float64), also on
    a second batch size; a wrapped SIREN is reached and switched back."""
    from ginn.models import DomainFrame, Siren, compile_derivatives, siren_grad

    torch.manual_seed(4)
    net = Siren(2, [16, 16], latent_dim=1, w0_first=6.0).double()
    wrapped = DomainFrame(net, [0.5, 0.0], 2.0)
    for n in (33, 50):
        x = torch.rand(n, 2, dtype=D, generator=gen) * 2 - 1
        z = torch.rand(n, 1, dtype=D, generator=gen)
        assert compile_derivatives(wrapped, False) == 1 and not net.compiled
        eager = _fast_path_numbers(net, x, z)
        assert compile_derivatives(wrapped, True) == 1 and net.compiled
        compiled = _fast_path_numbers(net, x, z)
        if siren_grad.KERNELS.failed:  # warned; the next test covers what runs then
            compile_derivatives(wrapped, False)
            pytest.skip("torch cannot compile on this machine")
        for a, b in zip(compiled, eager):
            assert torch.allclose(a, b, rtol=1e-12, atol=1e-12)
    compile_derivatives(wrapped, False)


def test_compiled_siren_kernels_fall_back_when_compiling_fails(gen, monkeypatch):
    """Where torch cannot compile (no C++ compiler, no Triton), the first call warns once and the
    eager kernels give the numbers, for the rest of the process."""
    from ginn.models import Siren, compile_derivatives, siren_grad

    def broken(*args):
        raise RuntimeError("no working C++ compiler found\nmore detail")

    kernels = siren_grad.Kernels()
    kernels.compiled = (broken, broken)
    monkeypatch.setattr(siren_grad, "KERNELS", kernels)
    torch.manual_seed(5)
    net = Siren(2, [8, 8], latent_dim=1).double()
    x = torch.rand(20, 2, dtype=D, generator=gen)
    z = torch.rand(20, 1, dtype=D, generator=gen)
    eager = _fast_path_numbers(net, x, z)
    compile_derivatives(net, True)
    with pytest.warns(UserWarning, match=r"torch.compile failed \(no working C\+\+ compiler found\)") as record:
        first = _fast_path_numbers(net, x, z)
        again = _fast_path_numbers(net, x, z)
    assert len(record) == 1 and kernels.failed
    for a, b, c in zip(first, again, eager):
        assert torch.equal(a, c) and torch.equal(b, c)


def test_siren_without_fast_path_falls_back(gen):
    """A periodic-encoded SIREN has no fast path; the engine still differentiates it exactly:
    its gradient matches central differences of the network itself."""
    from ginn.models import Siren
    from ginn.models.base import PeriodicEncoding

    net = Siren(1, [8], encoding=PeriodicEncoding()).double()
    x = torch.rand(10, 1, dtype=D, generator=gen)
    assert net.value_and_grad(x) is None
    v = evaluate(net, x, None, create_graph=False)
    eps = 1e-6
    fd = (net(x + eps) - net(x - eps)) / (2 * eps)
    assert torch.allclose(v.grad[:, 0], fd, atol=1e-7)


def test_shifted_field_keeps_derivatives_and_fast_path(gen):
    """``Shifted(f, c)`` is ``f + c`` with the same gradient, through the SIREN's fast path too."""
    from ginn.models import Siren

    torch.manual_seed(4)
    net = Siren(2, [16, 16], w0_first=3.0).double()
    x = torch.rand(30, 2, dtype=D, generator=gen)
    a = evaluate(net, x, None, create_graph=False)
    b = evaluate(fields.Shifted(net, 0.25), x, None, create_graph=False)
    assert fields.Shifted(net, 0.25).value_and_grad(x) is not None
    assert torch.allclose(b.f, a.f + 0.25, atol=1e-14) and torch.allclose(b.grad, a.grad, atol=1e-14)
    c = evaluate(fields.Shifted(as_field(lambda p: p[:, 0] ** 2), -1.0), x, None, create_graph=False)
    assert torch.allclose(c.f, x[:, 0] ** 2 - 1.0) and torch.allclose(c.grad[:, 0], 2 * x[:, 0])
