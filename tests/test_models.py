import pytest
import torch

from ginn.fields import evaluate
from ginn.models import MLP, FourierMLP, PeriodicEncoding, ResMLP, Siren


def make_models(d, k, out=1):
    return [
        Siren(d, [32, 32, 32], latent_dim=k, out_dim=out, w0_first=2.0),
        ResMLP(d, width=32, n_blocks=3, latent_dim=k, out_dim=out, beta=10.0),
        MLP(d, [16, 16], latent_dim=k, out_dim=out),
        FourierMLP(d, [32, 32], latent_dim=k, out_dim=out, sigma=3.0, n_features=16),
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
