"""Data-parallel training across processes (``torchrun``): one slice of the shapes per rank.

``torchrun --nproc_per_node=K -m ginn train ...`` starts K copies of ``ginn train``; each finds
``RANK``/``WORLD_SIZE``/``LOCAL_RANK`` in its environment, joins the process group (gloo on CPU,
NCCL on CUDA with device ``cuda:LOCAL_RANK``) and trains the contiguous slice
``[rank * S/K, (rank + 1) * S/K)`` of the S latent codes of a generative model.

Why the sharded run equals the single-process run (up to floating-point summation order):

* Sampling: every rank draws the points of *all* shapes from the same seeded generator in the
  same order and keeps its slice, so the samples (and the generator state) are those of one process.
* Local terms (interface, eikonal, obstacle, ...) are means over equal-sized per-shape sample
  sets, so the global mean is the average of the per-rank means. Each rank replaces its term
  ``L_r`` by ``L_r - sg(L_r) + mean_r sg(L_r)`` (``sg``: stop-gradient): the value is the global
  value (logged, and seen by a non-linear balancer such as the augmented Lagrangian), and the
  gradient is ``phi'(L) dL_r``; averaging the gradients over ranks gives ``phi'(L) dL``, the
  single-process gradient.
* Diversity couples all shapes: with ``V[i, j] = f_j(x_i)`` (``x_i`` boundary samples of shape i),
  rank r computes the columns ``j`` of its own shapes at the boundary points of *every* shape
  (the points are gathered without gradient: gradients flow through field values, not sample
  locations) and the autograd-aware ``all_gather`` assembles the full ``V`` on every rank. Every
  rank then evaluates the same ``delta(V)``; the backward of ``all_gather`` sums the K identical
  gradients of each rank's columns, and the gradient average divides by K: exact.
* Gradients are averaged by one ``all_reduce`` of the flattened gradient after ``backward``
  (not DDP's hooks): the loss needs several forward passes and ``autograd.grad(create_graph=True)``
  before one backward, and the backward itself contains the ``all_gather`` collective; DDP's
  bucketed asynchronous all-reduces on the same process group would interleave with it. One
  explicit all-reduce per step is also what DDP would send (a single bucket for these models).

Only rank 0 writes the run directory; checkpoints hold every rank's task state (e.g. its
connectedness critical points) and RNG state, so ``ginn resume`` under the same world size
continues exactly.
"""

from __future__ import annotations

import datetime as _dt
import os
from dataclasses import dataclass
from typing import Any

import torch
import torch.distributed as tdist
from torch import Tensor

from ..config import RunConfig, with_overrides
from ..errors import ConfigError, GinnError


def in_torchrun() -> bool:
    """Whether this process was started by torchrun (or another launcher setting the variables)."""
    return "RANK" in os.environ and "WORLD_SIZE" in os.environ


@dataclass
class DistContext:
    """The process group of a distributed run, as the trainer and tasks see it.

    Attributes:
        rank, world: this process's rank and the number of processes.
        local_rank: rank on this node (selects the GPU).
        device: this rank's device string (``cpu`` or ``cuda:LOCAL_RANK``).
        backend: ``gloo`` or ``nccl``.
    """

    rank: int
    world: int
    local_rank: int
    device: str
    backend: str

    @property
    def is_main(self) -> bool:
        return self.rank == 0

    # --- sharding ------------------------------------------------------------------------------

    def shard(self, n: int) -> tuple[int, int]:
        """This rank's contiguous slice ``[lo, hi)`` of ``n`` items (n must divide evenly)."""
        if n % self.world != 0:
            raise ConfigError(
                f"latents.n_shapes={n} is not divisible by the number of processes ({self.world}); "
                "distributed training needs equal shards"
            )
        k = n // self.world
        return self.rank * k, (self.rank + 1) * k

    def localize(self, cfg: RunConfig) -> RunConfig:
        """``cfg`` with this rank's device (``cuda`` -> ``cuda:LOCAL_RANK``)."""
        if cfg.device == self.device:
            return cfg
        return with_overrides(cfg, {"device": self.device})

    # --- collectives ---------------------------------------------------------------------------

    def _dev(self) -> torch.device:
        return torch.device(self.device)

    def globalize(self, losses: dict[str, Tensor]) -> dict[str, Tensor]:
        """Per-rank means -> terms whose value is the average over ranks (one all-reduce).

        Returns ``{k: L_k - sg(L_k) + mean_r sg(L_k)}``: the value is the global mean, the
        gradient this rank's own ``dL_k`` (averaged over ranks later by :meth:`average_gradients`).
        Non-finite values propagate to every rank, so every rank skips the same steps.
        """
        names = sorted(losses)
        if not names:
            return losses
        vals = torch.stack([losses[k].detach().reshape(()).to(torch.float64) for k in names]).to(self._dev())
        tdist.all_reduce(vals, op=tdist.ReduceOp.SUM)
        vals = vals / self.world
        out = {}
        for i, k in enumerate(names):
            L = losses[k]
            g = vals[i].to(device=L.device, dtype=L.dtype)
            out[k] = L - L.detach() + g if L.requires_grad else g
        return out

    def average_gradients(self, params) -> None:
        """Average ``p.grad`` over ranks in place (one all-reduce of the flattened gradient).

        A parameter without a gradient on some rank counts as zero there.
        """
        params = [p for p in params if p.requires_grad]
        if not params:
            return
        flat = torch.cat([(p.grad if p.grad is not None else torch.zeros_like(p)).reshape(-1) for p in params])
        tdist.all_reduce(flat, op=tdist.ReduceOp.SUM)
        flat /= self.world
        i = 0
        for p in params:
            n = p.numel()
            p.grad = flat[i:i + n].view_as(p).clone()
            i += n

    def broadcast_parameters(self, module: torch.nn.Module) -> None:
        """Copy rank 0's parameters and buffers to every rank."""
        with torch.no_grad():
            for t in list(module.parameters()) + list(module.buffers()):
                tdist.broadcast(t.data, src=0)

    def any(self, flag: bool) -> bool:
        """True on every rank if ``flag`` is true on any rank."""
        t = torch.tensor([1.0 if flag else 0.0], device=self._dev())
        tdist.all_reduce(t, op=tdist.ReduceOp.MAX)
        return bool(t.item() > 0)

    def gather_objects(self, obj: Any) -> list[Any]:
        """Every rank's ``obj`` (picklable), in rank order, on every rank."""
        out: list[Any] = [None] * self.world
        tdist.all_gather_object(out, obj)
        return out

    def broadcast_object(self, obj: Any) -> Any:
        """Rank 0's ``obj`` on every rank."""
        box = [obj]
        tdist.broadcast_object_list(box, src=0)
        return box[0]

    def all_gather_cat(self, t: Tensor, dim: int = 0) -> Tensor:
        """Concatenate every rank's ``t`` (same shape everywhere) along ``dim``; no gradient."""
        parts = [torch.empty_like(t) for _ in range(self.world)]
        tdist.all_gather(parts, t.contiguous())
        return torch.cat(parts, dim=dim)

    def all_gather_cat_autograd(self, t: Tensor, dim: int = 0) -> Tensor:
        """As :meth:`all_gather_cat`, differentiable: the backward sums every rank's gradient of
        this rank's part (``torch.distributed.nn.functional.all_gather``)."""
        import warnings

        from torch.distributed.nn.functional import all_gather

        with warnings.catch_warnings():  # deprecated in favour of a private API; still the public one
            warnings.simplefilter("ignore", FutureWarning)
            parts = all_gather(t.contiguous())
        return torch.cat(parts, dim=dim)

    def barrier(self) -> None:
        if self.backend == "nccl":
            tdist.barrier(device_ids=[self.local_rank])
        else:
            tdist.barrier()


def init_distributed(device: str = "cpu", timeout_s: float = 1800.0) -> DistContext | None:
    """Join the process group described by the torchrun environment; None outside torchrun.

    Arguments:
        device: the configured device (``cpu`` -> gloo; ``cuda[:N]`` -> NCCL on ``cuda:LOCAL_RANK``).
        timeout_s: collective timeout.

    Returns:
        the :class:`DistContext`, or None when ``WORLD_SIZE`` is unset (a plain single process).
    """
    if not in_torchrun():
        return None
    world = int(os.environ["WORLD_SIZE"])
    rank = int(os.environ["RANK"])
    local = int(os.environ.get("LOCAL_RANK", rank))
    if device.startswith("cuda"):
        if not torch.cuda.is_available():
            raise ConfigError(f"--device {device}: CUDA is not available on this machine")
        torch.cuda.set_device(local)
        dev, backend = f"cuda:{local}", "nccl"
    else:
        dev, backend = "cpu", "gloo"
    if not tdist.is_initialized():
        kw: dict[str, Any] = {"backend": backend, "timeout": _dt.timedelta(seconds=timeout_s)}
        if backend == "nccl":
            kw["device_id"] = torch.device(dev)
        tdist.init_process_group(**kw)
    return DistContext(rank=rank, world=world, local_rank=local, device=dev, backend=backend)


def shutdown(ctx: DistContext | None) -> None:
    """Leave the process group (no barrier: a rank that failed must not hang the others)."""
    if ctx is not None and tdist.is_initialized():
        tdist.destroy_process_group()


def on_main(ctx: DistContext | None, fn):
    """``fn()`` run on rank 0 only, its result (e.g. a new run directory) broadcast to every rank.

    A :class:`ginn.errors.GinnError` raised on rank 0 is raised on every rank, so all stop together.
    """
    if ctx is None:
        return fn()
    result, err = None, None
    if ctx.is_main:
        try:
            result = fn()
        except GinnError as e:
            err = e
    result, err = ctx.broadcast_object((result, err))
    if err is not None:
        raise err
    return result


def cross_values_sharded(field, xb_local: Tensor, Z_local: Tensor, mask_local: Tensor | None,
                         ctx: DistContext) -> tuple[Tensor, Tensor | None]:
    """The full cross-value tensor of the diversity loss from sharded shapes, with exact gradients.

    Arguments:
        field: callable ``(x, z) -> (n,)``.
        xb_local: this rank's boundary samples ``(s, m, d)``; Z_local: its latents ``(s, k)``;
        mask_local: validity ``(s, m)`` or None.

    Returns:
        ``V (S, S, m)`` with ``V[i, j] = f_j(x_i)`` over all ``S = s * world`` shapes, and the
        gathered mask ``(S, m)``. Rank r evaluates only the columns of its own shapes; the
        autograd all-gather assembles the rest.
    """
    s, m, d = xb_local.shape
    k = Z_local.shape[-1]
    xb = ctx.all_gather_cat(xb_local.detach(), dim=0)  # (S, m, d)
    mask = None
    if mask_local is not None:
        mask = ctx.all_gather_cat(mask_local.to(torch.uint8), dim=0).bool()
    S = xb.shape[0]
    X = xb[:, None, :, :].expand(S, s, m, d).reshape(-1, d)
    ZZ = Z_local[None, :, None, :].expand(S, s, m, k).reshape(-1, k)
    V_cols = field(X, ZZ).reshape(S, s, m)
    return ctx.all_gather_cat_autograd(V_cols, dim=1), mask
