"""The surface-network connectedness loss (Appendix C.3, Algorithm 1), cheap across steps.

Per shape, the components of the shape among the critical points, the augmented weighted graph
and the saddle penalties are :mod:`ginn.topology.penalties`; the loss is ``sum_k p_k f(x_k)`` with
the saddle positions ``x_k`` held fixed (detached), so the gradient moves the field, not the
points; the batch loss is the *mean* over the ``S`` shapes, so that its weight does not depend on
the batch size.

Design region: with ``restrict_to_design_region`` and a region, critical points outside it are
removed from the graph (they neither form components nor receive penalties), as in the paper's
bracket experiment.

Cheap across steps (:class:`ConnectednessLoss`): the critical points persist. On a step without a
full build only the *penalised saddles* (the only points the loss depends on) are re-converged
with a few Newton steps on the current field and the loss is evaluated there with the stored
weights; one that fell inside the shape has joined its components, and its weight becomes 0 until
the shape's next full build; so does one that does not converge, leaves the box or changes its
Morse index. Full builds (grid seeds plus the shape's previous critical points, Newton, DBSCAN,
path tracing, grid labels, penalties) run at every ``config.every``-th call, for the shapes due
then, in one batch: a shape is due ``config.every`` calls after a build that penalised something
on it, up to four times later after one that did not (:meth:`ConnectednessLoss._next_interval`).
No shape's build depends on another's, so the others keep their vertices, paths and weights. A
build's cost is mostly fixed (the path-tracing
and Newton loops run as long as their slowest member), so the builds are batched on those calls
rather than run per shape whenever one is due or loses a saddle. Re-converging *all* critical points
is not attempted: on a SIREN one optimiser step moves the flat minima by up to a tenth of the
domain (measured in the obstacle setting), so tracking them is neither cheap nor reliable, while
the saddles the loss needs are well conditioned.

Latents. A shape is judged at the latent code of its last full build until its next one, the
warm updates and the loss included: when the step's codes move (``latents.draw: lattice`` or
``uniform``) the critical points of a code are followed only while the code stays, and each
build takes the code of the step it runs at, so the codes the term judges still sweep the
latent set. Building every shape whenever the codes move cost a full build per step instead
(the obstacle's ``demo`` on the lattice: 7.6 minutes instead of 2.2).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from dataclasses import field as dc_field

import numpy as np
import torch
from torch import Tensor

from ..extract.grid import label_components
from ..geometry.base import Box, Region
from ..geometry.lookup import fast_membership
from .base import ConnectednessLossBase
from .critical import (
    CriticalPointOptions,
    CriticalPoints,
    cell_size,
    find_critical_points,
    latents_of,
    newton_refine,
)
from .penalties import Penalties, batch_penalties
from .persistent import death_points
from .surface_network import PathOptions, SurfaceNetwork, trace_surface_network


@dataclass(frozen=True)
class SurfaceNetworkLossOptions:
    """Numerical settings of :class:`ConnectednessLoss` beyond :class:`ConnectednessConfig`.

    Attributes:
        critical: critical-point search settings.
        paths: integral-path settings.
        warm_steps: Newton steps of a warm update.
        label_grid: the components are also labelled on a vertex grid of ``label_grid *
            config.grid`` nodes along the longest axis (one batched forward pass, no
            derivatives), which finds components that touch the domain or design-region boundary
            (they have no interior minimum); 0 uses the surface network alone.
        fallback: for component pairs with no path in G_a, also penalise the death nodes of the
            cubical persistent homology of that grid (needs ``label_grid > 0``).
        seed: seed of the generator of the seed-grid jitter.
    """

    critical: CriticalPointOptions = dc_field(default_factory=CriticalPointOptions)
    paths: PathOptions = dc_field(default_factory=PathOptions)
    warm_steps: int = 5
    label_grid: int = 2
    fallback: bool = True
    seed: int = 0


class ConnectednessLoss(ConnectednessLossBase):
    """Stateful surface-network connectedness loss for all shapes of a batch (see
    :class:`ConnectednessLossBase`; critical points outside the domain are dropped, paths leaving
    it end).

    Arguments:
        domain, design_region, config, device, dtype: see :class:`ConnectednessLossBase` (uses
            ``config.every``, ``grid``, ``eps``, ``restrict_to_design_region``).
        options: numerical settings (:class:`SurfaceNetworkLossOptions`).
        membership: the region answering ``contains`` with the same answers, faster (None: built
            here with :func:`ginn.geometry.lookup.fast_membership`).
    """

    def __init__(
        self,
        domain: Box,
        design_region: Region | None,
        config,
        device=None,
        dtype=torch.float32,
        options: SurfaceNetworkLossOptions | None = None,
        membership: Region | None = None,
    ):
        options = options or SurfaceNetworkLossOptions()
        super().__init__(domain, design_region, config, device, dtype, resolution=max(options.label_grid, 1) * config.grid)
        # the region is asked about every point of every path at every tracing step: answered
        # from a grid of its SDF where that is exact (geometry.lookup), by the region elsewhere
        self._membership = fast_membership(self.region, domain, device=self.device) if membership is None else membership
        self.options = options
        self.generator = torch.Generator().manual_seed(self.options.seed)
        self.step = 0
        # per shape: the call of its last full build and the calls until its next one
        self.last_full = np.zeros(0, dtype=np.int64)
        self.interval = np.zeros(0, dtype=np.int64)
        self.points: CriticalPoints | None = None
        self.network: SurfaceNetwork | None = None
        self.penalty: np.ndarray | None = None
        self._latents: Tensor | None = None
        self._seeds: tuple[Tensor, Tensor] | None = None
        self._results: list[Penalties] = []
        self._merged = 0
        self._grid_values = np.zeros(0)  # the label grid's values of the last build, raised outside E
        self._grid_top: float | None = None  # the value of the nodes outside E (None without E)
        self._extra: tuple[Tensor, Tensor, np.ndarray] = (torch.zeros(0, domain.dim), torch.zeros(0, dtype=torch.long), np.zeros(0))

    # --- state ---------------------------------------------------------------------------------

    _POINT_FIELDS = ("x", "shape", "f", "grad_norm", "eigvals", "eigvecs")
    _PATH_FIELDS = ("path_start", "path_end", "path_descending", "path_length", "path_outside_length", "path_anchor", "ends")

    FORMAT = 3

    def _state(self) -> dict:
        """The critical points, the surface network's paths, the penalties, the latents they
        belong to, the counters, each shape's schedule and the seed generator's state: a loss
        restored from it continues exactly as the uninterrupted one would."""
        state: dict = {
            "step": self.step,
            "last_full": torch.from_numpy(self.last_full.copy()),
            "interval": torch.from_numpy(self.interval.copy()),
            "latents": (self._latents if self._latents is not None else torch.zeros(0, 0)).detach().cpu(),
            "generator": self.generator.get_state(),
        }
        if self.points is not None and self.network is not None and self.penalty is not None:
            state["points"] = {k: getattr(self.points, k).detach().cpu() for k in self._POINT_FIELDS}
            state["paths"] = {k: torch.from_numpy(np.ascontiguousarray(getattr(self.network, k))) for k in self._PATH_FIELDS}
            state["penalty"] = torch.from_numpy(np.asarray(self.penalty, dtype=np.float64))
            ex, es, ep = self._extra
            state["extra"] = {"x": ex.detach().cpu(), "shape": es.cpu(), "weight": torch.from_numpy(np.asarray(ep, dtype=np.float64))}
            state["components"] = [int(r.n_components) for r in self._results]
            state["unreachable"] = [int(r.unreachable_pairs) for r in self._results]
        return state

    def migrate(self, state: dict) -> dict:
        """An older state in this format: formats 1 and 2 kept one build schedule for all shapes
        (every shape starts from it; format 1 had no interval: ``config.every``), and format 1 kept
        the critical points only (``seeds``: they start the next full build)."""
        lat = state["latents"]
        S = 1 if not lat.numel() else int(lat.shape[0])
        out = {k: v for k, v in state.items() if k not in ("points_x", "points_shape")}
        out["format"] = self.FORMAT
        for key, default in (("last_full", 0), ("interval", self.config.every)):
            v = np.asarray(state.get(key, default), dtype=np.int64).reshape(-1)
            out[key] = torch.from_numpy(np.broadcast_to(v, (S,)).copy() if v.size == 1 else v)
        if "points_x" in state:
            out["seeds"] = {"x": state["points_x"], "shape": state["points_shape"]}
        return out

    def _load(self, state: dict) -> None:
        """A state without the network (written before the first call, or by format 1) seeds the
        next full build with its points instead."""
        self.step = int(state["step"])
        lat = state["latents"]
        self._latents = lat.to(self.device, self.dtype) if lat.numel() else None
        S = 1 if self._latents is None else int(self._latents.shape[0])
        last = np.asarray(state["last_full"], dtype=np.int64).reshape(-1)
        every = np.asarray(state["interval"], dtype=np.int64).reshape(-1)
        self.last_full = last.copy() if last.size == S else np.zeros(0, np.int64)
        self.interval = every.copy() if every.size == S else np.zeros(0, np.int64)
        self.points = self.network = self.penalty = None
        self._seeds = None
        if "generator" in state:
            self.generator.set_state(state["generator"])
        if "points" in state:
            p = state["points"]
            self.points = CriticalPoints(**{
                k: p[k].to(self.device) if k == "shape" else p[k].to(self.device, self.dtype) for k in self._POINT_FIELDS})
            self.network = SurfaceNetwork(self.points, **{k: state["paths"][k].numpy().copy() for k in self._PATH_FIELDS})
            self.penalty = state["penalty"].numpy().copy()
            e = state["extra"]
            self._extra = (e["x"].to(self.device, self.dtype), e["shape"].to(self.device), e["weight"].numpy().copy())
            self._results = [Penalties(np.zeros(0), c, u, np.zeros(0, np.int64))
                             for c, u in zip(state["components"], state["unreachable"])]
        elif "seeds" in state:
            self._seeds = (state["seeds"]["x"].to(self.device, self.dtype), state["seeds"]["shape"].to(self.device))

    # --- work ----------------------------------------------------------------------------------

    def _valid(self, pts: CriticalPoints) -> np.ndarray:
        if self.region is None or pts.m == 0:
            return np.ones(pts.m, dtype=bool)
        return self._membership.contains(pts.x).cpu().numpy().astype(bool)

    def _build(self, field, Z: Tensor | None, sub: np.ndarray | None = None) -> None:
        """A full build of the shapes ``sub`` (``(k,)`` indices; None: every shape): critical points
        (seeded with their previous ones), paths, grid labels, penalties and fallback nodes replace
        theirs; the other shapes keep what they have (no shape's build depends on another's)."""
        S = 1 if Z is None else int(Z.shape[0])
        if sub is not None and len(sub) == S:
            sub = None
        Zs = Z if sub is None or Z is None else Z[torch.from_numpy(sub).to(Z.device)]
        k = S if sub is None else len(sub)
        pts = find_critical_points(
            field, Zs, self.domain, self.config.grid, self._previous(sub, S), self.options.critical, self.generator,
            self.device, self.dtype
        )
        self._seeds = None
        valid = self._valid(pts)
        labels = self._grid_labels(field, Zs)
        net = self._trace(field, Zs, pts, valid)
        penalty, results = batch_penalties(net, valid, k, self.config.eps, labels, self.domain)
        extra = self._fallback(field, Zs, pts, penalty, results, labels is not None)
        if sub is None:
            self.points, self.network, self.penalty, self._results, self._extra = pts, net, penalty, results, extra
        else:
            self._merge(sub, net, penalty, results, extra)

    def _trace(self, field, Z: Tensor | None, pts: CriticalPoints, valid: np.ndarray) -> SurfaceNetwork:
        """The paths from the saddles in E (``valid (m,)``): shape_components and
        saddle_penalties use no other path."""
        return trace_surface_network(field, Z, self.domain, pts, self.config.grid, self.options.paths,
                                     region=self._membership, sources=torch.from_numpy(valid).to(pts.f.device))

    def _previous(self, sub: np.ndarray | None, S: int) -> CriticalPoints | None:
        """The stored critical points of the shapes ``sub`` (None: all), numbered ``0..k-1`` in the
        order of ``sub``: the warm start of their build (the seeds of a restored first-format state
        when there are none)."""
        prev = self.points
        if prev is None and self._seeds is not None:
            x, sh = self._seeds
            d = x.shape[1]
            prev = CriticalPoints(x, sh, x.new_zeros(len(x)), x.new_zeros(len(x)), x.new_zeros(len(x), d),
                                  x.new_zeros(len(x), d, d))
        if prev is None or sub is None:
            return prev
        local = torch.full((S,), -1, dtype=torch.long, device=prev.shape.device)
        local[torch.from_numpy(sub).to(prev.shape.device)] = torch.arange(len(sub), device=prev.shape.device)
        mine = (prev.shape < S) & (local[prev.shape.clamp_max(S - 1)] >= 0)
        return CriticalPoints(prev.x[mine], local[prev.shape[mine]], prev.f[mine], prev.grad_norm[mine],
                              prev.eigvals[mine], prev.eigvecs[mine])

    def _merge(self, sub: np.ndarray, net: SurfaceNetwork, penalty: np.ndarray, results: list[Penalties],
               extra: tuple[Tensor, Tensor, np.ndarray]) -> None:
        """Replace the shapes ``sub``'s vertices, paths, penalties, results and fallback nodes by
        those of their build (``net`` over their vertices, shapes numbered in the order of ``sub``);
        the vertices stay sorted by shape and the paths' vertex indices follow them."""
        assert self.points is not None and self.network is not None and self.penalty is not None
        self.network, kept, order = self.network.with_shapes(sub, net)
        self.points = self.network.points
        self.penalty = np.concatenate([self.penalty[kept], penalty])[order]
        for i, s_ in enumerate(sub):
            self._results[int(s_)] = results[i]
        ex, es, ep = self._extra
        ko = ~np.isin(es.cpu().numpy(), sub)
        kot = torch.from_numpy(np.nonzero(ko)[0]).to(es.device)
        nx, ns, nw = extra
        gsub = torch.from_numpy(sub).to(es.device)
        self._extra = (torch.cat([ex[kot], nx.to(ex.dtype)]), torch.cat([es[kot], gsub[ns]]), np.concatenate([ep[ko], nw]))

    def _grid_labels(self, field, Z: Tensor | None) -> list[np.ndarray] | None:
        """The components of every shape of ``Z`` on the label grid (inside E), or None without
        one; keeps the grid's values for the fallback."""
        if self.options.label_grid <= 0:
            return None
        self._grid_values, self._grid_top = self.grid_values(field, Z)  # nodes outside E raised to _grid_top
        return [label_components(v <= 0)[0] for v in self._grid_values]

    def _fallback(self, field, Z: Tensor | None, points: CriticalPoints, penalty: np.ndarray, results: list[Penalties],
                  have_grid: bool) -> tuple[Tensor, Tensor, np.ndarray]:
        """For shapes with component pairs the surface network cannot join (no path in G_a, e.g.
        the separating saddle lies outside the design region, inside an obstacle; or a path that
        passes no saddle, e.g. a sliver along the boundary of E reached through a path anchor),
        penalise the
        death nodes of the cubical persistent homology of the label grid (restricted to E) that
        are farther than two grid cells from every penalised saddle, with raw weights
        ``1 / (2 f + eps)``, normalised together with the surface-network weights of the shape.

        Two kinds of death node are splits of the grid, not of the shape, and are left out (see
        :meth:`_real_splits`): one outside E (the grid components meet only through nodes outside
        E, where lowering ``f`` cannot join them: E itself is thinner than the grid there), and one
        from which Newton converges to a saddle of the field inside the shape (the components are
        joined between the grid nodes).

        Works on the shapes of ``Z`` (the last :meth:`_grid_labels` call's), their ``points`` and
        surface-network ``penalty`` (rescaled in place where fallback nodes share a shape's weight);
        returns the fallback nodes: positions ``(q, d)``, shapes ``(q,)`` and weights ``(q,)``."""
        xs, ss, ws = [], [], []
        if have_grid and self.options.fallback and any(r.unreachable_pairs for r in results):
            vals = self._grid_values
            h = cell_size(self.domain, self.options.label_grid * self.config.grid)
            shape_np = points.shape.cpu().numpy()
            xall = points.x.detach().cpu().double().numpy()
            deaths = {s: death_points(vals[s]) for s, r in enumerate(results) if r.unreachable_pairs}
            deaths = {s: dp for s, dp in deaths.items() if len(dp.value)}
            if not deaths:
                return self._no_extra()
            pos_all = self.nodes[tuple(torch.from_numpy(np.concatenate([dp.index for dp in deaths.values()])).T)]
            shape_all = np.concatenate([np.full(len(dp.value), s) for s, dp in deaths.items()])
            died = np.concatenate([dp.value for dp in deaths.values()])
            real_all = self._real_splits(field, Z, shape_all, pos_all, died < self._grid_top if self._grid_top is not None
                                         else np.ones(len(died), dtype=bool), h)
            for s, dp in deaths.items():
                r = results[s]
                mine = shape_all == s
                real = real_all[mine]
                if not real.any():
                    continue
                pos, dp_value = pos_all[torch.from_numpy(np.nonzero(mine)[0][real])], dp.value[real]
                sel = np.nonzero((shape_np == s) & (penalty > 0))[0]
                far = np.ones(len(dp_value), dtype=bool)
                if len(sel):
                    dist = np.linalg.norm(pos.detach().cpu().double().numpy()[:, None] - xall[sel][None], axis=-1)
                    far = dist.min(axis=1) > 2 * h
                if not far.any():
                    continue
                raw = 1.0 / (2.0 * dp_value[far] + self.config.eps)
                total = r.raw_total + raw.sum()
                penalty[sel] *= r.raw_total / total
                xs.append(pos[torch.from_numpy(far)])
                ss.append(torch.full((int(far.sum()),), s, dtype=torch.long, device=self.device))
                ws.append(raw / total)
        return (torch.cat(xs), torch.cat(ss), np.concatenate(ws)) if xs else self._no_extra()

    def _no_extra(self) -> tuple[Tensor, Tensor, np.ndarray]:
        return (torch.zeros(0, self.domain.dim, device=self.device, dtype=self.dtype),
                torch.zeros(0, dtype=torch.long, device=self.device), np.zeros(0))

    def _real_splits(self, field, Z: Tensor | None, shape: np.ndarray, pos: Tensor, in_region: np.ndarray,
                     h: float) -> np.ndarray:
        """Which death nodes (of the shapes ``shape (q,)``, positions ``pos (q, d)``, ``in_region
        (q,)``; all shapes in one Newton pass) separate their shape itself, ``(q,)`` bool: those
        inside E from which ``warm_steps`` Newton steps (trust radius one grid cell ``h``) do not
        reach a saddle (Morse index 1) with ``f <= 0`` within two cells. A node that does has the
        two grid components joined through that saddle, between the grid nodes."""
        real = np.asarray(in_region, dtype=bool).copy()
        k = np.nonzero(real)[0]
        if len(k) == 0:
            return real
        x0 = pos[torch.from_numpy(k)].to(self.dtype)
        z = None if Z is None else Z[torch.from_numpy(np.asarray(shape)[k]).to(Z.device)]
        co = self.options.critical
        r = newton_refine(field, x0, z, self.domain, steps=self.options.warm_steps, tol=co.tol, max_step=h,
                          min_step=co.min_step * h, eig_tol=co.eig_tol)
        index = (torch.linalg.eigvalsh(r.hessian) < 0).sum(-1)
        joined = r.converged & (index == 1) & (r.f <= 0) & ((r.x - x0).norm(dim=-1) <= 2 * h)
        real[k[joined.cpu().numpy()]] = False
        return real

    def _hold(self, Z: Tensor | None, rebuild: np.ndarray) -> Tensor | None:
        """The code each shape is judged at this call: the step's ``Z (S, k)`` for the shapes
        built now, the code of its last build for the others (module docstring, "Latents")."""
        if Z is None:
            return None
        if self._latents is None or rebuild.all():
            held = Z.clone()
        else:
            held = self._latents.clone()
            built = torch.from_numpy(rebuild).to(Z.device)
            held[built] = Z[built]
        self._latents = held
        return held

    def __call__(self, field, Z: Tensor | None) -> Tensor:
        t0 = time.perf_counter()
        S = 1 if Z is None else int(Z.shape[0])
        Zd = None if Z is None else Z.detach().to(self.device, self.dtype)
        self._merged = 0
        if (self.points is None or self.network is None or (Zd is None) != (self._latents is None)
                or len(self.last_full) != S or len(self._results) != S
                or (Zd is not None and Zd.shape != self._latents.shape)):
            self.last_full = np.zeros(S, dtype=np.int64)
            self.interval = np.full(S, int(self.config.every), dtype=np.int64)
            rebuild = np.ones(S, dtype=bool)
        else:  # builds only at every `every`-th call: the shapes due then are built in one batch
            on_grid = self.step % int(self.config.every) == 0
            rebuild = (self.step - self.last_full >= self.interval) & on_grid
        held = self._hold(Zd, rebuild)
        warm_failed = self._warm_update(field, held, rebuild) if not rebuild.all() else 0
        if rebuild.any():
            self._build(field, held, None if rebuild.all() else np.nonzero(rebuild)[0])
            self._next_interval(rebuild)
        reason = "full" if rebuild.all() else "partial" if rebuild.any() else "warm"
        loss = self._loss(field, None if held is None else held.to(Z.dtype), S)
        pts = self.points
        counts = pts.counts(S)
        comps = [r.n_components for r in self._results]
        self.last_info = {
            "time": time.perf_counter() - t0,
            "update": reason,
            "rebuilt": int(rebuild.sum()),
            "interval": self.interval.tolist(),
            "warm_failed": warm_failed,
            "n_components": comps,
            "n_disconnected_shapes": int(sum(c > 1 for c in comps)),
            "n_critical": pts.m,
            "n_minima": int(counts["minima"].sum()),
            "n_saddles": int(counts["saddles"].sum()),
            "n_maxima": int(counts["maxima"].sum()),
            "n_edges": int(len(self.network.edges)),
            "n_paths": int(self.network.n_paths),
            "n_penalised": int((self.penalty > 0).sum()) + len(self._extra[2]),
            "n_merged": self._merged,
            "n_fallback": len(self._extra[2]),
            "unreachable_pairs": int(sum(r.unreachable_pairs for r in self._results)),
        }
        self.step += 1
        return loss

    #: a full build that finds nothing to penalise on a shape doubles the interval to that shape's
    #: next one, up to this many times ``config.every``
    MAX_BACKOFF = 4

    def _next_interval(self, built: np.ndarray) -> None:
        """Calls until the next scheduled full build of each shape just built (``built (S,)``).
        Between full builds only the penalised saddles are followed, so a build that finds none on
        a shape (in one piece, the margin met) leaves warm updates nothing to do there, and what it
        would detect (the shape coming apart) is rarer the longer the shape stays whole: its
        interval doubles after each such build, up to ``MAX_BACKOFF * config.every``, and returns to
        ``config.every`` at the first build that penalises anything on it. Each shape keeps its own
        schedule, so one shape with a neck to widen does not hold the others at every build.

        Codes that move (a lattice draw) back off alike: the shape is held at the code of its
        build until the next (:meth:`_hold`). Building every shape every ``config.every`` calls
        instead made the obstacle's training (16 shapes, seed 1, 1 thread beside one other
        training) take 549 s instead of 418 s and left 252 of 256 held-out codes feasible against
        256 of 256 with the backoff (``docs/results.md``, "The latent set")."""
        assert self.points is not None and self.penalty is not None
        S = len(built)
        busy = np.zeros(S, dtype=bool)
        busy[self.points.shape.cpu().numpy()[self.penalty > 0]] = True
        busy[self._extra[1].cpu().numpy()] = True
        every = int(self.config.every)
        grown = np.minimum(2 * self.interval, self.MAX_BACKOFF * every)
        self.interval = np.where(built, np.where(busy, every, grown), self.interval)
        self.last_full = np.where(built, self.step, self.last_full)

    def _warm_update(self, field, Z: Tensor | None, skip: np.ndarray) -> int:
        """Re-converge the penalised saddles of the shapes not in ``skip`` (``(S,)`` bool: those
        about to be rebuilt) on the current field (a few Newton steps).

        The loss depends only on them; the rest of the surface network is kept until the shape's
        next full build. A saddle that fell inside the shape joined its components there: its
        weight becomes 0 (that pair is connected; the other weights stay as they are until the
        next full build). So does one that does not converge, leaves the box or stops being a
        saddle (typically two components merged and the saddle became a minimum): a shape with a
        penalised saddle is built afresh at the next scheduled call (its interval is ``every``),
        which finds what is left to join. Returns how many saddles were lost that way.
        """
        assert self.points is not None and self.penalty is not None
        shape_np = self.points.shape.cpu().numpy()
        ki = np.nonzero((self.penalty > 0) & ~skip[shape_np])[0]
        if len(ki) == 0:
            return 0
        k = torch.from_numpy(ki).to(self.device)
        h = cell_size(self.domain, self.config.grid)
        co = self.options.critical
        r = newton_refine(
            field, self.points.x[k], latents_of(Z, self.points.shape[k]), self.domain,
            steps=self.options.warm_steps, tol=co.tol, max_step=co.max_step * h,
            min_step=co.min_step * h, eig_tol=co.eig_tol,
        )
        lam, V = torch.linalg.eigh(r.hessian)
        good = (r.converged & ((lam < 0).sum(-1) == self.points.index[k])).cpu().numpy()
        self.penalty[ki[~good]] = 0.0
        if good.any():
            j = torch.from_numpy(np.nonzero(good)[0]).to(self.device)
            kk = k[j]
            pts = self.points
            pts.x[kk], pts.f[kk], pts.grad_norm[kk], pts.eigvals[kk], pts.eigvecs[kk] = (
                r.x[j], r.f[j], r.grad_norm[j], lam[j], V[j])
            inside = (r.f[j] <= 0).cpu().numpy()
            self.penalty[ki[good][inside]] = 0.0
            self._merged = int(inside.sum())
        return int((~good).sum())

    def _loss(self, field, Z: Tensor | None, S: int) -> Tensor:
        x, sh, p = self.penalised_points()
        f = field(x.detach(), latents_of(Z, sh))
        return (p.to(device=f.device, dtype=f.dtype) * f).sum() / S

    def penalised_points(self) -> tuple[Tensor, Tensor, Tensor]:
        """The points penalised at the last call (saddles first, then fallback grid nodes):
        positions ``(q, d)``, shapes ``(q,)`` and weights ``(q,)`` (float64; they sum to 1 per
        disconnected shape)."""
        assert self.points is not None and self.penalty is not None
        k = torch.from_numpy(np.nonzero(self.penalty > 0)[0]).to(self.device)
        ex, es, ep = self._extra
        x = torch.cat([self.points.x[k], ex.to(self.points.x.dtype)])
        sh = torch.cat([self.points.shape[k], es])
        p = torch.from_numpy(np.concatenate([self.penalty[k.cpu().numpy()], ep])).to(self.device)
        return x, sh, p
