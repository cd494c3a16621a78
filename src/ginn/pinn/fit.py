"""A minimal trainer for :class:`ginn.pinn.gray_scott.GrayScottTask` (used by the slow test and the
experiments until the generic trainer takes over): Adam over the weighted active loss terms with the
schedule and gradient clipping of ``cfg.training``.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import torch
from torch import nn

from ..train.task import Task


def fit(task: Task, iterations: int | None = None, log: Callable[[int, dict], None] | None = None,
        log_every: int = 100) -> tuple[nn.Module, list[dict]]:
    """Train ``task`` from a fresh model (seeded with ``cfg.seed``).

    Returns:
        ``(model, history)``; history holds one dict of floats per logged step.
    """
    cfg = task.cfg
    tr = cfg.training
    n_it = tr.iterations if iterations is None else iterations
    torch.manual_seed(cfg.seed)
    model = task.build_model()
    opt = torch.optim.Adam(model.parameters(), lr=tr.lr)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda t: tr.lr_decay ** (t / tr.lr_decay_every))
    gen = torch.Generator().manual_seed(cfg.seed)
    terms = task.terms()
    history: list[dict] = []
    t0 = time.perf_counter()
    for step in range(n_it):
        active = {k for k, t in terms.items() if t.weight > 0 and step >= t.start}
        losses = task.loss_terms(model, step, active, gen)
        total = sum(terms[k].weight * losses[k] for k in active if k in losses)
        opt.zero_grad(set_to_none=True)
        total.backward()
        if tr.grad_clip > 0:
            nn.utils.clip_grad_norm_(model.parameters(), tr.grad_clip)
        opt.step()
        sched.step()
        if step % log_every == 0 or step == n_it - 1:
            rec = {"step": step, "time": time.perf_counter() - t0, "total": float(total.detach())}
            rec.update({k: float(v) for k, v in losses.items()})
            history.append(rec)
            if log is not None:
                log(step, rec)
    return model, history
