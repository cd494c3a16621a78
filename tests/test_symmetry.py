"""Symmetry by construction: the fold is exactly invariant, smooth and a local isometry; the
symmetry error metric on analytic fields; the verdict and a symmetric training run."""

import math

import numpy as np
import pytest
import torch

from ginn import fields
from ginn.eval.feasibility import check_feasibility, violations
from ginn.eval.metrics import extract_shape, symmetry_error
from ginn.extract.grid import make_grid
from ginn.fields import as_field
from ginn.geometry.base import Box
from ginn.geometry.symmetry import Mirror, Rotation, Symmetry
from ginn.models import Siren, SymmetricField

EPS = 0.02

GROUPS = {
    "one mirror": Symmetry((Mirror((0.1, -0.2), (1.0, 2.0)),)),
    "two mirrors": Symmetry((Mirror((0.1, 0.0), (1.0, 1.0)), Mirror((0.0, 0.3), (1.0, -1.0)))),
    "rotation 5": Symmetry(rotation=Rotation((0.2, -0.1), 5)),
    "dihedral 3": Symmetry((Mirror((0.2, -0.1), (math.cos(0.4), math.sin(0.4))),), Rotation((0.2, -0.1), 3)),
    "3D mirrors": Symmetry((Mirror((0.0, 0.0, 0.1), (0.0, 0.0, 1.0)), Mirror((0.2, 0.0, 0.0), (1.0, 0.0, 0.0)))),
    "3D rotation 4, both mirrors": Symmetry(
        (Mirror((0.1, 0.0, 0.3), (0.0, 1.0, 0.0)), Mirror((0.3, 0.0, 0.1), (1.0, 0.0, -1.0))),
        Rotation((0.1, 0.0, 0.3), 4, (1.0, 0.0, -1.0))),
}


def _t(v) -> torch.Tensor:
    return torch.tensor(v, dtype=torch.float64)


def _points(dim: int, n: int = 500, seed: int = 0) -> torch.Tensor:
    return torch.rand(n, dim, generator=torch.Generator().manual_seed(seed), dtype=torch.float64) * 2 - 1


@pytest.mark.parametrize("name", list(GROUPS))
def test_fold_is_exactly_invariant_under_every_generator(name):
    sym = GROUPS[name]
    x = _points(sym.dim)
    fx = sym.fold(x, EPS)
    assert fx.shape == (500, sym.fold_dim)
    for gname, T in sym.generators():
        assert torch.allclose(sym.fold(T(x), EPS), fx, atol=1e-12, rtol=0), gname
        # the generators are isometries of order 2 (mirrors) or n (rotation)
        assert torch.allclose((T(x) - T(x[:1])).norm(dim=-1), (x - x[:1]).norm(dim=-1), atol=1e-12)


@pytest.mark.parametrize("name", list(GROUPS))
def test_fold_is_a_local_isometry_away_from_mirrors_and_axis(name):
    # J^T J = I up to n eps^2 / dist^2 (2 for mirrors alone) at points farther than 10 eps from
    # every mirror and the axis
    sym = GROUPS[name]
    x = _points(sym.dim, 20000, seed=1)
    dist = torch.full((x.shape[0],), math.inf, dtype=torch.float64)
    rot = sym.rotation
    for m in sym.mirrors:
        normals = [_t(m.normal)]
        contains_axis = rot is not None and (rot.dim == 2 or abs(float(_t(m.normal) @ _t(rot.axis))) < 1e-9)
        if contains_axis:  # with the rotation, n mirrors k pi / n apart
            half = Rotation(rot.center, 2 * rot.n, rot.axis)
            normals = [half.matrix(k) @ _t(m.normal) for k in range(rot.n)]
        for nrm in normals:
            dist = torch.minimum(dist, ((x - _t(m.point)) @ nrm).abs())
    if rot is not None:
        q = x - _t(rot.center)
        if sym.dim == 3:
            a = _t(rot.axis)
            q = q - (q @ a)[:, None] * a
        dist = torch.minimum(dist, q.norm(dim=-1))
    keep = dist > 10 * EPS
    x, dist = x[keep][:200], dist[keep][:200]
    J = torch.func.vmap(torch.func.jacrev(lambda p: sym.fold(p[None], EPS)[0]))(x)  # (n, fold_dim, d)
    G = J.transpose(1, 2) @ J
    order = sym.rotation.n if sym.rotation is not None else 2
    err = (G - torch.eye(sym.dim, dtype=torch.float64)).abs().amax(dim=(1, 2))
    assert (err <= order * (EPS / dist) ** 2).all()
    assert err.max() > 0  # the bound is not vacuous: the fold does bend


def test_fold_is_smooth_on_the_axis_and_the_mirror():
    # finite first and second derivatives where the fold creases (the rotation centre, the mirror line)
    sym = GROUPS["dihedral 3"]
    c = _t([[0.2, -0.1], [0.2 + 0.3 * math.sin(0.4), -0.1 - 0.3 * math.cos(0.4)]])
    for p in c:
        H = torch.func.hessian(lambda q: sym.fold(q[None], EPS)[0].sum())(p)
        assert torch.isfinite(H).all() and H.abs().max() < 10 / EPS


def test_symmetric_field_is_exactly_symmetric_with_fd_derivatives():
    sym = GROUPS["dihedral 3"]
    inner = Siren(3, [32, 32], latent_dim=1, w0_first=10.0)
    f = SymmetricField(inner, sym, EPS).double()
    x = _points(2, 300)
    z = torch.full((300, 1), 0.05, dtype=torch.float64)
    for _, T in sym.generators():
        assert torch.allclose(f(T(x), z), f(x, z), atol=1e-12, rtol=0)
    v = fields.evaluate(f, x, z, grad=True, create_graph=False)
    h = 1e-6
    fd = torch.stack([(f(x + h * e, z) - f(x - h * e, z)) / (2 * h) for e in torch.eye(2, dtype=torch.float64)], dim=-1)
    assert torch.allclose(v.grad, fd, atol=1e-6)


def _disk(c, r):
    c = _t(c)
    return as_field(lambda x, z=None: (x - c.to(x.dtype)).norm(dim=-1) - r)


def test_symmetry_error_of_analytic_disks():
    box = Box((-1.0, -1.0), (1.0, 1.0))
    grid = make_grid(box, 256)
    mirror = Symmetry((Mirror((0.0, 0.0), (1.0, 0.0)),))
    # centred: symmetric; off by 0.2 along the normal: the image of the circle is the circle about
    # (-0.2, 0), whose points lie | |y - c| - r | from the circle about c
    assert symmetry_error(_disk((0.0, 0.1), 0.5), None, extract_shape(_disk((0.0, 0.1), 0.5), None, grid).boundary,
                          mirror, box) < 1e-6
    f = _disk((0.2, 0.0), 0.5)
    got = symmetry_error(f, None, extract_shape(f, None, grid).boundary, mirror, box, n_samples=20000)
    t = np.linspace(0, 2 * np.pi, 200000, endpoint=False)
    y = np.stack([-(0.2 + 0.5 * np.cos(t)), 0.5 * np.sin(t)], axis=1)
    exact = np.sqrt(np.mean((np.linalg.norm(y - [0.2, 0.0], axis=1) - 0.5) ** 2))
    assert got == pytest.approx(exact, rel=0.02)
    # a rotation: a disk centred off the rotation centre is off by its displacement's rotation
    rot = Symmetry(rotation=Rotation((0.0, 0.0), 4))
    assert symmetry_error(f, None, extract_shape(f, None, grid).boundary, rot, box) > 0.1


def test_symmetry_verdict():
    from ginn.geometry.interfaces import Circle
    from ginn.problems.problem import Problem

    box = Box((-1.0, -1.0), (1.0, 1.0))
    P = Problem("t", box, interfaces=(Circle((0.0, 0.0), 0.5),), symmetry=Symmetry(rotation=Rotation((0.0, 0.0), 3)))
    ok = check_feasibility(_disk((0.0, 0.0), 0.5), None, P, 128)
    assert ok.feasible == 1 and ok.ratios["symmetry"] < 1e-3
    # displaced by 0.006: CD1 = 0.006 / sqrt(2) = 4.2e-3 passes; the image under the rotation is
    # displaced by 0.006 sqrt(3) from it, at RMS distance 0.006 sqrt(3) / sqrt(2) = 7.3e-3
    off = check_feasibility(_disk((0.006, 0.0), 0.5), None, P, 128)
    assert off.feasible == 0 and set(off.violations[0]) == {"symmetry"}
    d = off.violations[0]["symmetry"]
    assert d.bound == pytest.approx(5e-3) and d.value == pytest.approx(0.006 * math.sqrt(1.5), rel=0.03)
    good = {"interface_cd1": 1e-3, "b0_in_design_region": 1, "connected_interfaces_share": 1.0, "volume_outside": 0.0}
    assert violations({**good, "symmetry_error": 4.9e-3}, P) == {}
    assert set(violations({**good, "symmetry_error": 5.1e-3}, P)) == {"symmetry"}


def test_incompatible_generators_are_refused():
    with pytest.raises(ValueError, match="orthogonal"):
        Symmetry((Mirror((0.0, 0.0), (1.0, 0.0)), Mirror((0.0, 0.0), (1.0, 1.0))))
    with pytest.raises(ValueError, match="rotation centre"):
        Symmetry((Mirror((0.5, 0.0), (1.0, 0.0)),), Rotation((0.0, 0.0), 4))
    with pytest.raises(ValueError, match="at most one mirror"):
        Symmetry((Mirror((0.0, 0.0), (1.0, 0.0)), Mirror((0.0, 0.0), (0.0, 1.0))), Rotation((0.0, 0.0), 4))
    with pytest.raises(ValueError, match=">= 2"):
        Rotation((0.0, 0.0), 1)
    with pytest.raises(ValueError, match="non-zero"):
        Rotation((0.0, 0.0, 0.0), 3, (0.0, 0.0, 0.0))


def test_wheel_trains_symmetric_and_resumes_the_same_field(tmp_path):
    from ginn import runs

    sets = ["latents.n_shapes=2", "model.hidden=[16,16]", "sampling.n_domain=128", "sampling.n_outside=64",
            "sampling.n_interface=32", "sampling.n_boundary=32", "training.threads=1"]
    spec, cfg = runs.resolve("wheel", None, {"training": {"iterations": 4}}, sets=sets)
    assert spec.build().symmetry.rotation.n == 5
    runs.train(spec, cfg, tmp_path / "w", progress=False, results=False)
    run = runs.load_run(tmp_path / "w")
    model, Z = run.model.double(), run.task.Z.double()
    x = _points(2, 400) * 1.1
    z = Z[1].expand(400, -1)
    rot = spec.build().symmetry.rotation
    for k in range(1, 5):
        assert torch.allclose(model(rot.rotate(x, k), z), model(x, z), atol=1e-12, rtol=0)
    assert model(x, z).std() > 0  # not symmetric by being constant
