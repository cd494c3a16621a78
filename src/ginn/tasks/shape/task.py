"""Training task of a shape problem (obstacle, bracket, Plateau, user specs): the GINN losses.

Per iteration and shape, fresh samples: uniform points in X (eikonal), points in X \\ E (design
region), inside obstacles, on the interfaces (interface and normal), optionally in a band around
the interfaces. All shapes and all point sets go through the network in one batched pass with
gradients; Hessians are taken only at boundary points (curvature, strain), which are found by
projecting the domain samples closest to ``f = 0`` onto the zero level set.
"""

from __future__ import annotations

import math
from pathlib import Path

import torch
from scipy.spatial import cKDTree
from torch import Tensor, nn

from .. import fields
from ..config import LossTerm, RunConfig, default_resolution
from ..errors import ConfigError, GinnError, SpecError
from ..eval.feasibility import FeasibilityCheck, verdict_text
from ..eval.plateau import evaluate_plateau
from ..eval.shapes import evaluate_shapes, format_table
from ..extract.export import CONTOUR_FORMATS, export_shapes, latent_label, shape_boundary
from ..extract.grid import check_grid_memory, make_grid
from ..geometry import sampling
from ..geometry.base import Region
from ..geometry.lookup import fastest_membership
from ..levelset import project_to_zero
from ..losses import constraints as C
from ..losses.diversity import aggregate, distance_matrix, diversity, diversity_nearest
from ..models.factory import build_model
from ..models.frame import DomainFrame
from ..models.latents import fixed_latents, latent_dim, random_latents
from ..models.symmetric import FOLD_SMOOTHING, SymmetricField
from ..problems.derived import length_scale
from ..problems.problem import Problem
from ..topology import ConnectednessLossBase, make_connectedness_loss
from ..topology.holes import HoleCountLoss
from ..train.distributed import DistContext, cross_values_sharded
from ..train.task import Task
from ..viz.explorer import write_explorer
from ..viz.plateau import write_plateau_results
from ..viz.plot import plot_run, save_shape_figure


class ShapeTask(Task):
    """A GINN shape problem: a (generative) implicit shape trained from constraints.

    Arguments:
        problem: the geometry (domain, design region, interfaces, obstacles).
        cfg, device, dtype: see :class:`ginn.train.task.Task`.

    The problem's ``reference`` (``minimal-surface``: Plateau) adds the comparison with the
    reference surface to the evaluation and to the result files.
    """

    kind = "shape"

    def __init__(self, problem: Problem, cfg: RunConfig, device, dtype):
        super().__init__(cfg, device, dtype)
        self.problem = problem
        self.d = problem.dim
        self.Z = fixed_latents(cfg.latents, self.device, dtype)
        self.lo, self.hi = problem.domain.tensors(self.device, dtype)
        self._conn: ConnectednessLossBase | None = None
        self._holes: HoleCountLoss | None = None
        self._membership: Region | None = None
        self._check: FeasibilityCheck | None = None
        self._iface_cloud: cKDTree | None = None  # a dense sample of the interfaces
        s = cfg.sampling
        self.design_loss = C.DesignRegionLoss(power=cfg.losses.containment_power)
        self.obstacle_loss = C.ObstacleLoss(power=cfg.losses.containment_power)
        self.interface_loss = C.InterfaceLoss()
        self.normal_loss = C.NormalLoss()
        self.eikonal_loss = C.EikonalLoss()
        self.curv_loss = C.MeanCurvatureLoss()
        self.strain_loss = C.StrainLoss(clip=s.strain_clip)
        self.has_normals = any(getattr(i, "has_normals", True) for i in problem.interfaces)
        corners = sampling.interface_corners(problem.interfaces, self.device, dtype) if problem.interfaces else None
        self.corners = corners if corners is not None and corners.shape[0] > 0 else None
        self.dist: DistContext | None = None  # when trained data-parallel (see distribute)
        self.shard: tuple[int, int] | None = None

    @classmethod
    def from_spec(cls, spec, cfg: RunConfig) -> ShapeTask:
        """The task of a shape spec: its geometry built (meshes loaded, interfaces checked).

        Raises:
            SpecError: the problem has no interface (the shape would attach to nothing).
        """
        problem = spec.build()
        if not problem.interfaces:
            raise SpecError("spec field 'geometry.interfaces': a shape problem needs at least one interface "
                            "(the shape has nothing to attach to)")
        return cls(problem, cfg, cfg.device, cfg.torch_dtype)

    # --- Task API ----------------------------------------------------------------------------

    def build_model(self) -> nn.Module:
        """The field of ``cfg.model``; with ``model.frame: domain`` in the domain's frame
        (:class:`ginn.models.frame.DomainFrame`); symmetric by construction where the problem
        states a symmetry (:class:`ginn.models.symmetric.SymmetricField`, folds smoothed over
        :data:`FOLD_SMOOTHING` of the domain's half longest side)."""
        sym = self.problem.symmetry
        model = build_model(self.cfg.model, self.d if sym is None else sym.fold_dim, latent_dim(self.cfg.latents))
        dom = self.problem.domain
        center, scale = [0.5 * (a + b) for a, b in zip(dom.lo, dom.hi)], length_scale(self.problem)
        if self.cfg.model.frame == "domain":
            if sym is not None:
                model = SymmetricField(model, sym.in_frame(center, scale), FOLD_SMOOTHING)
            return DomainFrame(model, center, scale)
        if sym is not None:
            model = SymmetricField(model, sym, FOLD_SMOOTHING * scale)
        return model

    def terms(self) -> dict[str, LossTerm]:
        L = self.cfg.losses
        out = {
            "interface": L.interface,
            "eikonal": L.eikonal,
            "mean_curvature": L.mean_curvature,
            "strain": L.strain,
            "connectedness": L.connectedness,
        }
        if self.problem.design_region is not None:
            out["design_region"] = L.design_region
        if self.problem.obstacles:
            out["obstacle"] = L.obstacle
        if self.has_normals:
            out["normal"] = L.normal
        if self.cfg.latents.n_shapes > 1:
            out["diversity"] = L.diversity
        if not self.problem.interfaces:
            out.pop("interface")
        if self.problem.topology.targets:
            out["topology"] = L.topology
        return out

    def latents(self) -> Tensor | None:
        return self.Z

    def state_dict(self) -> dict:
        out = {"connectedness": self._conn.state_dict()} if self._conn is not None else {}
        if self._holes is not None:
            out["topology"] = self._holes.state_dict()
        return out

    def load_state_dict(self, state: dict) -> None:
        if "connectedness" in state and state["connectedness"]:
            self.connectedness_loss().load_state_dict(state["connectedness"])
        if state.get("topology"):
            self.hole_loss().load_state_dict(state["topology"])

    def distribute(self, ctx: DistContext) -> None:
        """Train only this rank's slice of the shapes (``ginn.train.distributed``)."""
        if self.cfg.latents.n_shapes == 1:
            raise ConfigError("distributed training shards the shapes of a generative model: set latents.n_shapes > 1")
        self.dist, self.shard = ctx, ctx.shard(self.cfg.latents.n_shapes)

    @property
    def membership(self) -> Region | None:
        """The design region E, or its grid lookup where that answers ``contains`` faster with the
        same answers (:func:`ginn.geometry.lookup.fastest_membership`): asked about every
        candidate of the samples outside E at every step, and about every point of every
        connectedness path. None without a design region."""
        if self._membership is None and self.problem.design_region is not None:
            self._membership = fastest_membership(self.problem.design_region, self.problem.domain, device=self.device)
        return self._membership

    def connectedness_loss(self) -> ConnectednessLossBase:
        if self._conn is None:
            restrict = self.cfg.connectedness.restrict_to_design_region
            self._conn = make_connectedness_loss(
                self.problem.domain,
                self.problem.design_region if restrict else None,
                self.cfg.connectedness,
                self.device,
                self.dtype,
                membership=self.membership if restrict else None,
            )
        return self._conn

    def hole_loss(self) -> HoleCountLoss:
        """The loss toward the problem's target Betti numbers (:mod:`ginn.topology.holes`)."""
        if self._holes is None:
            t = self.cfg.topology
            self._holes = HoleCountLoss(self.problem.domain, self.problem.design_region, self.problem.topology.targets,
                                        t.grid, t.every, self.device, self.dtype)
        return self._holes

    # --- sampling ----------------------------------------------------------------------------

    def _step_latents(self, gen: torch.Generator) -> Tensor | None:
        if self.cfg.latents.n_shapes == 1:
            return None
        if self.cfg.latents.random:
            return random_latents(self.cfg.latents, gen, self.device, self.dtype)
        return self.Z

    def sample(self, S: int, active: set[str], gen: torch.Generator) -> dict[str, Tensor]:
        """Fresh per-shape samples, each ``(S, n, d)`` (normals ``(S, n, d)``)."""
        s, p, kw = self.cfg.sampling, self.problem, dict(device=self.device, dtype=self.dtype)
        d = self.d
        out: dict[str, Tensor] = {}
        out["domain"] = sampling.sample_box(p.domain, S * s.n_domain, gen, **kw).reshape(S, -1, d)
        if "design_region" in active and s.n_outside > 0:
            out["outside"] = sampling.sample_outside(self.membership, p.domain, S * s.n_outside, gen, **kw).reshape(S, -1, d)
        if "obstacle" in active and s.n_obstacle > 0:
            # split among the obstacles per shape, so that every shape gets the same number
            per = max(1, s.n_obstacle // len(p.obstacles))
            obs = [sampling.sample_inside(o, p.domain, S * per, gen, **kw) for o in p.obstacles]
            out["obstacle"] = torch.cat([o.reshape(S, -1, d) for o in obs], dim=1)
        if p.interfaces and ({"interface", "normal"} & active):
            xi, ni = sampling.sample_interfaces(p.interfaces, S * s.n_interface, gen, **kw)
            # the samplers return points grouped interface by interface: shuffle before splitting
            # them among the shapes, or each shape would see only some of the interfaces
            perm = self._perm(xi.shape[0], gen)
            out["interface"], out["normals"] = xi[perm].reshape(S, -1, d), ni[perm].reshape(S, -1, d)
        if s.n_band > 0 and p.interfaces and p.interface_band > 0:
            xb = sampling.sample_band(p.interfaces, S * s.n_band, p.interface_band, gen, box=p.domain, **kw)
            out["band"] = xb[self._perm(xb.shape[0], gen)].reshape(S, -1, d)
        return out

    def _perm(self, n: int, gen: torch.Generator) -> Tensor:
        return torch.randperm(n, generator=gen, device=gen.device).to(self.device)

    # --- losses ------------------------------------------------------------------------------

    def loss_terms(self, model: nn.Module, step: int, active: set[str], gen: torch.Generator) -> dict[str, Tensor]:
        Z = self._step_latents(gen)
        S = 1 if Z is None else Z.shape[0]
        pts = self.sample(S, active, gen)
        if self.shard is not None:  # distributed: every rank samples all shapes, keeps its slice
            lo, hi = self.shard
            Z, pts, S = Z[lo:hi], {k: v[lo:hi] for k, v in pts.items()}, hi - lo
        # the outside and obstacle samples enter only through their values: a value-only pass is
        # about a third of a value-and-gradient one (forward and backward)
        part_f, part_g = self._main_pass(model, Z, pts, ("domain", "band", "interface"), grad=True)
        part_f.update(self._main_pass(model, Z, pts, ("outside", "obstacle"), grad=False)[0])
        out: dict[str, Tensor] = {}
        if "eikonal" in active:
            ge = part_g["domain"] if "band" not in part_g else torch.cat([part_g["domain"], part_g["band"]], dim=1)
            out["eikonal"] = self.eikonal_loss(ge.reshape(-1, self.d))
        if "design_region" in active and "outside" in part_f:
            out["design_region"] = part_f["outside"]  # replaced below, with the surface samples outside E
        if "obstacle" in active and "obstacle" in part_f:
            fo = part_f["obstacle"].reshape(-1)
            out["obstacle"] = self.obstacle_loss(fo - self._containment_floor(pts["obstacle"], self.problem.obstacles, -1.0))
        if "interface" in active:
            fi = part_f["interface"].reshape(-1)
            if self.corners is not None and self.cfg.sampling.interface_corner_weight > 1:
                fc = self._corner_values(model, Z)
                w = torch.cat([torch.ones_like(fi), torch.full_like(fc, self.cfg.sampling.interface_corner_weight)])
                out["interface"] = self.interface_loss(torch.cat([fi, fc]), w)
            else:
                out["interface"] = self.interface_loss(fi)
        if "normal" in active:
            ni = pts["normals"].reshape(-1, self.d)
            has = ni.norm(dim=-1) > 0.5
            out["normal"] = self.normal_loss(part_g["interface"].reshape(-1, self.d)[has], ni[has])
        need_boundary = {"mean_curvature", "strain", "diversity"} & active
        surface_containment = "design_region" in out and self.cfg.losses.containment_slope > 0
        if need_boundary or surface_containment:
            xb, mask = self.boundary_points(model, Z, pts["domain"], part_f["domain"], part_g["domain"])
            out.update(self._boundary_losses(model, Z, xb, mask, active))
        if "design_region" in out:
            if surface_containment:
                out["design_region"] = self._containment_with_surface(model, Z, part_f["outside"], pts["outside"], xb, mask)
            else:
                E = self.problem.design_region
                out["design_region"] = self.design_loss(part_f["outside"].reshape(-1)
                                                        - self._containment_floor(pts["outside"], E, 1.0))
        if "connectedness" in active:
            margin = self.cfg.connectedness.margin
            field = model if margin == 0 else fields.Shifted(model, margin)
            out["connectedness"] = self.connectedness_loss()(field, Z)
        if "topology" in active:
            out["topology"] = self.hole_loss()(model, Z)
        return out

    def _main_pass(self, model: nn.Module, Z: Tensor | None, pts: dict[str, Tensor], groups: tuple[str, ...],
                   grad: bool) -> tuple[dict[str, Tensor], dict[str, Tensor]]:
        """One batched evaluation of the sample groups ``groups`` of ``pts`` (each ``(S, n_k, d)``)
        that are present: their values ``(S, n_k)`` and, with ``grad``, gradients ``(S, n_k, d)``,
        differentiable w.r.t. the parameters."""
        names = [k for k in groups if k in pts]
        if not names:
            return {}, {}
        sizes = [pts[k].shape[1] for k in names]
        X = torch.cat([pts[k] for k in names], dim=1)  # (S, N, d)
        S, N = X.shape[:2]
        Xf, Zf = (X.reshape(-1, self.d), None) if Z is None else fields.broadcast_latents(X, Z)
        v = fields.evaluate(model, Xf, Zf, grad=grad, create_graph=True)
        part_f = dict(zip(names, torch.split(v.f.reshape(S, N), sizes, dim=1)))
        if not grad:
            return part_f, {}
        return part_f, dict(zip(names, torch.split(v.grad.reshape(S, N, self.d), sizes, dim=1)))

    def _containment_with_surface(self, model: nn.Module, Z: Tensor | None, f_out: Tensor, x_out: Tensor,
                                  xb: Tensor, mask: Tensor) -> Tensor:
        """The design-region loss over the uniform samples of X \\ E (``x_out (S, n, d)``, values
        ``f_out (S, n)``) and the samples of the shapes' surfaces that lie outside E (``xb (S, m, d)``,
        converged where ``mask``), each against its containment floor.

        Where a shape overhangs E by a thin sliver, few uniform samples fall into it and their
        penalty is as thin as the sliver; every surface sample on the sliver is penalised by its
        depth outside E, so the push scales with the overhang's area instead of its volume. The
        surface samples are the ones the boundary losses use (no extra projection). Used with a
        containment floor (``losses.containment_slope > 0``): without one a surface sample, where
        ``f = 0``, carries no penalty."""
        E = self.problem.design_region
        fo = f_out.reshape(-1) - self._containment_floor(x_out, E, 1.0)
        flat = xb.reshape(-1, self.d)
        with torch.no_grad():
            out = mask.reshape(-1) & ~self.membership.contains(flat)
        if bool(out.any()):
            xs = flat[out]
            zs = None if Z is None else Z[:, None, :].expand(*xb.shape[:2], Z.shape[-1]).reshape(-1, Z.shape[-1])[out]
            fs = model(xs, zs) - self._containment_floor(xs[None], E, 1.0)
            fo = torch.cat([fo, fs])
        return self.design_loss(fo)

    def _containment_floor(self, x: Tensor, regions, sign: float) -> Tensor | float:
        """``losses.containment_slope`` times the distance of each sample ``x (S, n, d)`` into the
        forbidden set: outside E (``sign = 1``: the design region's SDF) or into an obstacle
        (``sign = -1``: minus the obstacle's SDF, the largest over the obstacles). A signed distance
        field of any shape inside E is at least this distance there, so the floor is exact for
        ``slope = 1``; returns 0 (the paper's loss) when the slope is 0."""
        slope = self.cfg.losses.containment_slope
        if slope == 0:
            return 0.0
        flat = x.reshape(-1, self.d)
        regions = regions if isinstance(regions, (list, tuple)) else [regions]
        depth = torch.stack([sign * r.sdf(flat) for r in regions]).amax(dim=0)
        return slope * depth.clamp_min(0.0).detach()

    def _corner_values(self, model: nn.Module, Z: Tensor | None) -> Tensor:
        c = self.corners
        if Z is None:
            return model(c, None)
        Xc, Zc = fields.broadcast_latents(c, Z)
        return model(Xc, Zc)

    def boundary_points(
        self, model: nn.Module, Z: Tensor | None, xd: Tensor, fd: Tensor, gd: Tensor
    ) -> tuple[Tensor, Tensor]:
        """Per-shape points on ``f = 0``: the ``n_boundary`` domain samples with the smallest
        ``|f| / |grad f|`` (distance estimate), moved by one Newton step with the values and
        gradients already computed in the main pass (no extra evaluation), then by
        ``sampling.projection_steps`` further Newton steps, which also check convergence.

        Returns points ``(S, m, d)`` (detached) and a validity mask ``(S, m)``.
        """
        S = xd.shape[0]
        m = min(self.cfg.sampling.n_boundary, xd.shape[1])
        with torch.no_grad():
            fd, gd = fd.detach(), gd.detach()
            g2 = (gd * gd).sum(-1).clamp_min(1e-12)
            dist = fd.abs() / g2.sqrt()
            idx = dist.topk(m, dim=1, largest=False).indices  # (S, m)
            take = lambda t: torch.gather(t, 1, idx[:, :, None].expand(S, m, t.shape[-1]))  # noqa: E731
            step = (fd / g2)[:, :, None] * gd
            x0 = take(xd.detach() - step)
        X = x0.reshape(-1, self.d)
        Zf = None if Z is None else fields.broadcast_latents(x0, Z)[1]
        # converged within a thousandth of the problem's length scale (absolute, a problem drawn in
        # other units would keep other samples)
        tol = 1e-3 * length_scale(self.problem)
        proj = project_to_zero(model, X, Zf, steps=self.cfg.sampling.projection_steps, tol=tol, bounds=(self.lo, self.hi))
        return proj.x.reshape(S, m, self.d), proj.converged.reshape(S, m)

    def _boundary_losses(self, model, Z, xb: Tensor, mask: Tensor, active: set[str]) -> dict[str, Tensor]:
        out: dict[str, Tensor] = {}
        S, m, d = xb.shape
        out["_boundary_converged"] = mask.float().mean()
        if {"mean_curvature", "strain"} & active:
            sel = mask
            Xf = xb.reshape(-1, d)
            Zf = None if Z is None else Z[:, None, :].expand(S, m, Z.shape[-1]).reshape(-1, Z.shape[-1])
            v = fields.evaluate(model, Xf, Zf, grad=False, hessian_at=sel.reshape(-1), create_graph=True)
            gh, hh = v.hessian_grad, v.hessian
            if "mean_curvature" in active:
                out["mean_curvature"] = self.curv_loss(gh, hh)
            if "strain" in active:
                keep = self._away_from_interfaces(Xf[v.hessian_index], self.cfg.sampling.strain_interface_clearance)
                out["strain"] = self.strain_loss(gh[keep], hh[keep])
        if "diversity" in active and Z is not None:
            dv = self.cfg.diversity
            if self.dist is not None:  # all shapes' cross values, exact gradients
                V, M = cross_values_sharded(model, xb, Z, mask, self.dist)
                out["diversity"] = -aggregate(distance_matrix(V, M, dv.eps), dv.aggregation, dv.p)
            else:
                out["diversity"] = -(diversity_nearest(model, xb, Z, mask, p=dv.p, eps=dv.eps) if dv.aggregation == "min"
                                     else diversity(model, xb, Z, mask, kind=dv.aggregation, p=dv.p, eps=dv.eps))
        return out

    def _away_from_interfaces(self, x: Tensor, c: float) -> Tensor:
        """``(n,)``: whether each point of ``x (n, d)`` is farther than ``c`` from every interface."""
        if c <= 0 or not self.problem.interfaces:
            return torch.ones(x.shape[0], dtype=torch.bool, device=x.device)
        if self._iface_cloud is None:  # a dense fixed sample of I and its KD-tree, for distances
            g = torch.Generator(device=self.device).manual_seed(12345)
            cloud, _ = sampling.sample_interfaces(self.problem.interfaces, 20000, g, device=self.device, dtype=self.dtype)
            self._iface_cloud = cKDTree(cloud.detach().cpu().double().numpy())
        dist, _ = self._iface_cloud.query(x.detach().cpu().double().numpy(), distance_upper_bound=c)
        return torch.from_numpy(dist > c).to(x.device)

    # --- results -----------------------------------------------------------------------------

    def _output_resolution(self, resolution: int | None = None) -> int:
        return self._checked(resolution or self.cfg.output.resolution or default_resolution("output", self.d), 32)

    def _checked(self, resolution: int, bytes_per_node: int) -> int:
        """``resolution`` if it is a grid this machine can hold (a one-line ConfigError otherwise)."""
        if isinstance(resolution, bool) or not isinstance(resolution, int) or resolution < 2:
            raise ConfigError(f"resolution {resolution!r}: must be an integer >= 2")
        check_grid_memory(make_grid(self.problem.domain, resolution).n_nodes, bytes_per_node, f"resolution {resolution}")
        return resolution

    def finalize(self, model: nn.Module, run_dir: Path) -> list[Path]:
        """``shapes/`` (2D: contour polylines and drawings per shape; 3D: one STL per shape),
        ``figures/`` (shapes, superposition and interpolation in 2D, views in 3D, loss curves, the
        latent-space explorer ``explorer.html``) and,
        for a problem with a minimal-surface reference, ``plateau/``."""
        run_dir = Path(run_dir)
        model.eval()
        res = self._output_resolution()
        paths = self._write_shapes(model, self.Z, run_dir / "shapes", res, "stl")
        paths += self.plot(model, run_dir, res)
        paths.append(write_explorer(model, self.Z, self.problem, run_dir / "figures" / "explorer.html",
                                    title=f"{self.problem.name}: {run_dir.name}"))
        if self.problem.reference == "minimal-surface":
            paths += write_plateau_results(model, self.problem, run_dir, resolution=res)
        return paths

    def constraint_targets(self) -> dict[str, float]:
        """Targets of the constraint terms from the problem's tolerances (``balancing.method:
        adaptive``). With ``d = tolerances.interface * unit_scale / 2`` (half the CD1 bound: the
        field's value on an interface is its distance there only up to ``|grad f|``):

        * ``interface`` (mean ``f^2`` on the interfaces): ``d^2``;
        * ``normal`` (mean ``|n - n_prescribed|^2 = 2 (1 - cos angle)``): ``2 (1 - cos normal_angle)``;
        * ``design_region``, ``obstacle`` (mean penalty over samples where the shape must not be):
          ``volume_outside * d^p`` (``p = losses.containment_power``): at most that share of the
          samples inside the shape, by at most ``d``;
        * ``connectedness``: 0 (no penalised saddle).
        """
        t, p = self.problem.tolerances, self.cfg.losses.containment_power
        d = 0.5 * t.interface * self.problem.unit_scale
        out = {"interface": d * d, "normal": 2.0 * (1.0 - math.cos(math.radians(t.normal_angle))),
               "design_region": t.volume_outside * d ** p, "obstacle": t.volume_outside * d ** p,
               "eikonal": 0.01}
        if t.connected:
            out["connectedness"] = 0.0
        return out

    def constraint_terms(self) -> dict[str, tuple[str, ...]]:
        """The verdict's constraints (:func:`ginn.eval.feasibility.ratios`) and the loss terms
        that enforce them: the interface values, the containment terms (the volume outside E
        counts the obstacles), the connectedness loss, the hole-count loss and, with a stated
        minimum, the diversity term."""
        groups = {"interface": ("interface",), "volume_outside": ("design_region", "obstacle"),
                  "connected": ("connectedness",), "topology": ("topology",)}
        if self.problem.tolerances.diversity is not None:
            groups["diversity"] = ("diversity",)
        return groups

    def bounded_objectives(self) -> tuple[str, ...]:
        """The diversity, where the spec states a minimum (``tolerances.diversity``)."""
        return ("diversity",) if self.problem.tolerances.diversity is not None else ()

    def feasibility(self, model: nn.Module) -> dict | None:
        """The problem's tolerances checked on a coarse grid (``RESOLUTION['check']``), with the
        definitions of ``ginn eval`` (:class:`ginn.eval.feasibility.FeasibilityCheck`)."""
        return self._checker()(model, self.Z)

    def _checker(self) -> FeasibilityCheck:
        """The coarse-grid check, its metric context built once per task."""
        if self._check is None:
            self._check = FeasibilityCheck(self.problem, default_resolution("check", self.d), seed=self.cfg.seed)
        return self._check

    def evaluate(self, model: nn.Module, resolution: int | None = None, out_dir: Path | None = None) -> dict:
        """The Appendix B.1 metrics of every shape (:func:`ginn.eval.shapes.evaluate_shapes`), and the
        comparison with the reference surface where the problem has one."""
        res = evaluate_shapes(model, self.Z, self.problem, self._checked(resolution or default_resolution("eval", self.d), 64))
        if self.problem.reference == "minimal-surface":
            res.update(evaluate_plateau(model, self.problem))
        return res

    def format_metrics(self, metrics: dict) -> str:
        text = format_table(metrics)
        extra = {k: v for k, v in metrics.items()
                 if k not in ("problem", "n_shapes", "shapes", "mean", "diversity_mean", "feasibility")}
        if extra:
            text += "\n" + "\n".join(f"{k}: {v}" for k, v in extra.items())
        return text

    def export(self, model: nn.Module, latents: Tensor | list[list[float]] | None, out_dir: Path,
               resolution: int | None = None, mesh_format: str | None = None) -> list[Path]:
        """Meshes (3D, ``mesh_format`` stl (default), ply or obj) or contours (2D) for ``latents``
        ``(S, k)`` (None: the trained latents)."""
        if self.d == 2 and mesh_format is not None:
            raise GinnError(f"--format {mesh_format}: a 2D run exports contours (json, csv, npz, svg, png); "
                            "--format chooses the mesh format of a 3D run")
        Z = self.Z
        if latents is not None:
            if Z is None:
                raise GinnError("--latent: this run trained a single shape (no latent codes)")
            rows = latents.tolist() if isinstance(latents, Tensor) else latents
            k = Z.shape[1]
            if any(len(v) != k for v in rows):
                raise GinnError(f"--latent: this model takes {k} latent value(s) per shape")
            if not all(math.isfinite(float(x)) for v in rows for x in v):
                raise GinnError("--latent: latent values must be finite numbers")
            Z = torch.tensor(rows, dtype=Z.dtype, device=Z.device)
        return self._write_shapes(model, Z, Path(out_dir), self._output_resolution(resolution), mesh_format or "stl")

    def _write_shapes(self, model: nn.Module, Z: Tensor | None, out_dir: Path, resolution: int, mesh_format: str) -> list[Path]:
        """Each shape of ``Z (S, k)`` (None: the single shape): a mesh in 3D; in 2D its contours, and
        a drawing over the problem titled with its feasibility verdict (coarse-grid check)."""
        if self.d == 3:
            return export_shapes(model, Z, self.problem.domain, out_dir, resolution, mesh_format=mesh_format)
        paths = export_shapes(model, Z, self.problem.domain, out_dir, resolution,
                              contour_formats=[f for f in CONTOUR_FORMATS if f != "png"])
        summary = self._checker()(model, Z)
        codes = [None] if Z is None else [Z[i] for i in range(Z.shape[0])]
        for i, (z, violated) in enumerate(zip(codes, summary["violations"])):
            boundary, _, _ = shape_boundary(model, z, self.problem.domain, resolution)
            name = "shape.png" if z is None else f"shape_{i:03d}_{latent_label(z)}.png"
            label = "" if z is None else f"shape {i} (z = {', '.join(f'{float(v):.3g}' for v in z)}): "
            paths.append(save_shape_figure(boundary, self.problem, out_dir / name, label + verdict_text(violated)))
        return paths

    def plot(self, model: nn.Module, run_dir: Path, resolution: int | None = None) -> list[Path]:
        """The paper-style figures into ``run_dir/figures`` (:func:`ginn.viz.plot.plot_run`)."""
        run_dir = Path(run_dir)
        if resolution is not None:
            self._checked(resolution, 32)
        titles = None
        if self.d == 3:  # each shape's views titled with its verdict (the coarse-grid check)
            summary = self._checker()(model, self.Z)
            codes = [None] if self.Z is None else [self.Z[i] for i in range(self.Z.shape[0])]
            titles = [("" if z is None else f"shape {i} (z = {', '.join(f'{float(v):.3g}' for v in z)}): ")
                      + verdict_text(v) for i, (z, v) in enumerate(zip(codes, summary["violations"]))]
        return plot_run(model, self.Z, self.problem, run_dir / "figures", metrics_jsonl=run_dir / "metrics.jsonl",
                        resolution=resolution, view_titles=titles)
