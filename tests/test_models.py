import math

import pytest
import torch

from ginn.fields import evaluate
from ginn.models import MLP, FourierMLP, PeriodicEncoding, ResMLP, Siren, Wire


def make_models(d, k, out=1):
    return [
        Siren(d, [32, 32, 32], latent_dim=k, out_dim=out, w0_first=2.0),
        ResMLP(d, width=32, n_blocks=3, latent_dim=k, out_dim=out, beta=10.0),
        MLP(d, [16, 16], latent_dim=k, out_dim=out),
        FourierMLP(d, [32, 32], latent_dim=k, out_dim=out, sigma=3.0, n_features=16),
        Wire(d, [16, 16, 16], latent_dim=k, out_dim=out),
    ]


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("k", [0, 1, 3])
def test_models_run_with_and_without_latents(dtype, k):
    torch.manual_seed(0)
    x = torch.rand(11, 2, dtype=dtype)
    z = torch.rand(11, k, dtype=dtype) if k else None
    for m in make_models(2, k):
        m = m.to(dtype)
        y = m(x, z)
        assert y.shape == (11,) and y.dtype == dtype and torch.isfinite(y).all()
        v = evaluate(m, x, z, hessian_at=True, create_graph=False)
        assert v.hessian.shape == (11, 2, 2) and torch.isfinite(v.hessian).all()


def test_multi_output_and_empty_latent():
    m = Siren(3, [16, 16], out_dim=2)
    assert m(torch.rand(5, 3)).shape == (5, 2)
    assert m(torch.rand(5, 3), torch.zeros(5, 0)).shape == (5, 2)


def test_latent_changes_output_and_bad_shapes_raise():
    torch.manual_seed(0)
    m = Siren(2, [32, 32], latent_dim=1, w0_first=2.0)
    x = torch.rand(8, 2)
    a = m(x, torch.full((8, 1), -1.0))
    b = m(x, torch.full((8, 1), 1.0))
    assert (a - b).abs().max() > 1e-3
    with pytest.raises(ValueError, match="latent"):
        m(x)
    with pytest.raises(ValueError, match="coordinates"):
        m(torch.rand(8, 3), torch.zeros(8, 1))


def test_siren_init_preactivations_stable():
    """Sitzmann et al.: under the SIREN init every hidden pre-activation has ~unit variance."""
    torch.manual_seed(0)
    m = Siren(3, [512] * 6, w0_first=30.0).double()
    x = torch.rand(4096, 3, dtype=torch.float64) * 2 - 1
    with torch.no_grad():
        pre = m.preactivations(x)
    stds = [float(p.std()) for p in pre[1:]]  # hidden layers (first layer depends on w0_first)
    assert len(stds) == 5
    # fixed point: Var = 2 E[sin^2(u)], u ~ N(0, Var) -> std ~0.93; it must neither grow nor decay
    for s in stds:
        assert 0.85 < s < 1.1, stds
    assert max(stds[1:]) / min(stds[1:]) < 1.05


def test_siren_first_layer_frequency_scales_bandwidth():
    torch.manual_seed(0)
    lo = Siren(1, [64, 64], w0_first=1.0)
    torch.manual_seed(0)
    hi = Siren(1, [64, 64], w0_first=30.0)
    x = torch.linspace(-1, 1, 2001)[:, None]
    g_lo = evaluate(lo, x, create_graph=False).grad.abs().mean()
    g_hi = evaluate(hi, x, create_graph=False).grad.abs().mean()
    assert g_hi > 5 * g_lo


def test_periodic_encoding_is_periodic():
    torch.manual_seed(0)
    m = Siren(2, [32, 32], encoding=PeriodicEncoding(), w0_first=3.0).double()
    x = torch.rand(20, 2, dtype=torch.float64)
    shift = torch.tensor([1.0, -2.0], dtype=torch.float64)
    assert torch.allclose(m(x), m(x + shift), atol=1e-12)


def test_softplus_beta_changes_sharpness():
    torch.manual_seed(0)
    m = ResMLP(2, width=8, n_blocks=2, beta=100.0)
    assert m.core[1].beta == 100.0


@pytest.mark.cuda
def test_models_on_cuda():
    for m in make_models(3, 1):
        m = m.cuda()
        x = torch.rand(10, 3, device="cuda")
        z = torch.rand(10, 1, device="cuda")
        v = evaluate(m, x, z, hessian_at=torch.arange(3, device="cuda"), create_graph=True)
        assert v.hessian.device.type == "cuda"


def test_siren_sine_derivatives_of_every_order_match_autograd():
    """The custom sine (derivatives from the saved sin/cos outputs) passes gradcheck to third
    order, and a SIREN's value, gradient and Hessian equal those of plain ``torch.sin``."""
    from ginn import fields
    from ginn.models import siren

    a = torch.randn(6, 3, dtype=torch.float64, requires_grad=True)
    f = lambda a: siren.sine(a).pow(2).sum(-1) * siren.sine(a)[:, 0]  # noqa: E731

    u = torch.randn(6, 3, dtype=torch.float64)

    def hessian_vector(a):  # second derivatives of f, differentiated once more by gradcheck
        (g,) = torch.autograd.grad(f(a).sum(), a, create_graph=True)
        (hv,) = torch.autograd.grad((g * u).sum(), a, create_graph=True)
        return hv

    assert torch.autograd.gradcheck(f, (a,)) and torch.autograd.gradgradcheck(f, (a,))
    assert torch.autograd.gradcheck(hessian_vector, (a,))  # third derivatives

    torch.manual_seed(0)
    model = Siren(2, [32, 32], latent_dim=1, w0_first=3.0, w0_hidden=2.0).double()
    x, z = torch.randn(9, 2, dtype=torch.float64), torch.randn(9, 1, dtype=torch.float64)
    v = fields.evaluate(model, x, z, hessian_at=True, create_graph=True)
    loss = v.f.pow(2).sum() + (v.grad.norm(dim=-1) - 1).pow(2).sum() + fields.divergence_of_normal(v.hessian_grad, v.hessian).pow(2).sum()
    g_custom = torch.autograd.grad(loss, list(model.parameters()))
    orig = siren.sine
    siren.sine = torch.sin  # the reference: autograd's own sine
    try:
        w = fields.evaluate(model, x, z, hessian_at=True, create_graph=True)
        loss_ref = w.f.pow(2).sum() + (w.grad.norm(dim=-1) - 1).pow(2).sum() + fields.divergence_of_normal(w.hessian_grad, w.hessian).pow(2).sum()
        g_ref = torch.autograd.grad(loss_ref, list(model.parameters()))
    finally:
        siren.sine = orig
    assert torch.allclose(v.hessian, w.hessian, atol=1e-12)
    for p, q in zip(g_custom, g_ref):
        assert torch.allclose(p, q, atol=1e-10)


def test_latent_scale_equals_codes_spread_by_the_same_factor():
    """``model.latent_scale = s`` gives exactly the field of the unscaled model at codes ``s * z``
    (same initial weights), for every model kind, in value and in the SIREN's fast gradient path."""
    from ginn.config import ModelConfig
    from ginn.models.factory import build_model

    x = torch.rand(17, 2, dtype=torch.float64) * 2 - 1
    z = torch.linspace(-1, 1, 17, dtype=torch.float64)[:, None]
    for kind in ("siren", "resmlp", "mlp", "fourier"):
        torch.manual_seed(3)
        plain = build_model(ModelConfig(kind=kind, hidden=[16, 16], width=16, n_blocks=2), 2, 1).double()
        torch.manual_seed(3)
        scaled = build_model(ModelConfig(kind=kind, hidden=[16, 16], width=16, n_blocks=2, latent_scale=2.5), 2, 1).double()
        assert torch.allclose(scaled(x, z), plain(x, 2.5 * z), atol=1e-12), kind
        assert not torch.allclose(scaled(x, z), plain(x, z), atol=1e-3), kind  # the scale is not a no-op
        vs = evaluate(scaled, x, z, create_graph=False)
        vp = evaluate(plain, x, 2.5 * z, create_graph=False)
        assert torch.allclose(vs.grad, vp.grad, atol=1e-10), kind


def test_latent_scale_must_be_positive():
    from pydantic import ValidationError

    from ginn.config import ModelConfig
    from ginn.models import ConcatConditioning

    with pytest.raises(ValidationError, match="latent_scale"):
        ModelConfig(latent_scale=0.0)
    with pytest.raises(ValueError, match="positive"):
        ConcatConditioning(-1.0)


def test_domain_frame_scales_values_and_keeps_gradients():
    """f(x) = s g((x - c) / s): values scale by s, gradients are g's at the mapped point, and the
    SIREN fast path agrees with autograd through the frame."""
    from ginn import fields
    from ginn.models import DomainFrame, Siren

    torch.manual_seed(0)
    inner = Siren(2, [32, 32], latent_dim=1, w0_first=5.0).double()
    framed = DomainFrame(inner, [3.0, -1.0], 4.0).double()
    x = torch.randn(50, 2, dtype=torch.float64) * 4 + torch.tensor([3.0, -1.0], dtype=torch.float64)
    z = torch.rand(50, 1, dtype=torch.float64)
    y = (x - torch.tensor([3.0, -1.0], dtype=torch.float64)) / 4.0
    torch.testing.assert_close(framed(x, z), 4.0 * inner(y, z))
    fast = framed.value_and_grad(x, z)
    xr = x.clone().requires_grad_(True)
    f = framed(xr, z)
    (g,) = torch.autograd.grad(f.sum(), xr)
    torch.testing.assert_close(fast[0], f.detach())
    torch.testing.assert_close(fast[1], g)
    torch.testing.assert_close(g, inner.value_and_grad(y, z)[1])
    ev = fields.evaluate(framed, x, z, grad=True)
    torch.testing.assert_close(ev.grad, g)
    assert framed.in_dim == 2 and framed.latent_dim == 1


def _wire_reference(m: Wire, x: torch.Tensor, z: torch.Tensor | None) -> torch.Tensor:
    """The WIRE formula with torch's complex numbers: psi(u) = exp(i omega u - |scale u|^2)."""
    c = m.core
    psi = lambda u: torch.exp(1j * c.omega * u - (c.scale * u).abs() ** 2)  # noqa: E731
    h = psi(c.first(torch.cat([x, z], dim=1) if z is not None else x).to(torch.complex128))
    for layer in [*c.hidden, c.last]:
        W = torch.complex(layer.weight_re, layer.weight_im)
        b = torch.complex(layer.bias_re, layer.bias_im)
        u = h @ W.t() + b
        h = psi(u) if layer is not c.last else u
    return h.real.squeeze(-1)


def test_wire_is_the_complex_gabor_network_in_real_arithmetic():
    torch.manual_seed(1)
    m = Wire(2, [24, 24, 24], latent_dim=2, omega=12.0, scale=4.0).double()
    x, z = torch.rand(40, 2, dtype=torch.float64) * 2 - 1, torch.rand(40, 2, dtype=torch.float64)
    assert torch.allclose(m(x, z), _wire_reference(m, x, z), rtol=1e-12, atol=1e-14)
    # every parameter is real (optimisers, checkpoints, DDP): a complex layer holds two real tensors
    assert all(not p.is_complex() for p in m.parameters())
    assert sum(p.numel() for p in m.core.hidden[0].parameters()) == 2 * (24 * 24 + 24)


def test_wire_modulus_is_bounded_whatever_the_preactivation():
    """|psi(p + i q)| = exp(-omega q - scale^2 (p^2 + q^2)) peaks at p = 0, q = -omega / (2 scale^2)
    with the value exp(omega^2 / (4 scale^2))."""
    from ginn.models.wire import gabor

    omega, scale = 20.0, 10.0
    p = torch.linspace(-3, 3, 601, dtype=torch.float64)[:, None].expand(601, 601)
    q = torch.linspace(-3, 3, 601, dtype=torch.float64)[None, :].expand(601, 601)
    re, im = gabor(p, q, omega, scale)
    mod = torch.sqrt(re * re + im * im)
    assert mod.max().item() == pytest.approx(math.exp(1.0), rel=1e-12)  # attained on the grid: q = -0.1
    assert torch.allclose(mod, torch.exp(-omega * q - scale**2 * (p * p + q * q)), rtol=1e-12)


def test_wire_initialisation_is_pytorch_default_linear():
    torch.manual_seed(0)
    m = Wire(3, [256, 256], latent_dim=1)
    b1 = 1 / math.sqrt(4)
    assert m.core.first.weight.abs().max() <= b1 and m.core.first.bias.abs().max() <= b1
    for layer in [m.core.hidden[0], m.core.last]:
        bound = 1 / math.sqrt(256)
        for t in (layer.weight_re, layer.weight_im):
            assert t.abs().max().item() <= bound
            if t.numel() > 1000:  # U(-c, c) has standard deviation c / sqrt(3)
                assert t.std().item() == pytest.approx(bound / math.sqrt(3), rel=0.03)


def test_wire_derivatives_match_finite_differences():
    """Gradients and Hessians of the engine (autograd through the real arithmetic) against
    central differences in float64."""
    torch.manual_seed(2)
    m = Wire(3, [16, 16, 16], latent_dim=1, omega=6.0, scale=2.0).double()
    x = torch.rand(7, 3, dtype=torch.float64) * 2 - 1
    z = torch.rand(7, 1, dtype=torch.float64)
    v = evaluate(m, x, z, hessian_at=True, create_graph=False)
    h = 1e-6  # the field is steep (|grad f| up to 46 here): central differences err by about 1e-7
    eye = torch.eye(3, dtype=torch.float64)
    with torch.no_grad():
        fd_grad = torch.stack([(m(x + h * e, z) - m(x - h * e, z)) / (2 * h) for e in eye], dim=1)
    assert torch.allclose(v.grad, fd_grad, rtol=1e-7, atol=1e-6)
    grads = [evaluate(m, x + s * h * e, z).grad for e in eye for s in (1, -1)]
    fd_hess = torch.stack([(grads[2 * i] - grads[2 * i + 1]) / (2 * h) for i in range(3)], dim=1)
    assert torch.allclose(v.hessian, fd_hess, rtol=1e-6, atol=1e-4)
    assert torch.allclose(v.hessian, v.hessian.transpose(1, 2), atol=1e-10)


def test_wire_from_the_config():
    from ginn.config import ModelConfig
    from ginn.models.factory import build_model

    m = build_model(ModelConfig(kind="wire", hidden=[8, 8], gabor_omega=5.0, gabor_scale=3.0), 2, latent_dim=1)
    assert isinstance(m, Wire) and (m.omega, m.scale) == (5.0, 3.0) and m.core.last.weight_re.shape == (1, 8)
