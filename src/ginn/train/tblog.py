"""TensorBoard event files of a run (``training.log: [jsonl, tensorboard]``), beside ``metrics.jsonl``.

Every record the trainer writes to ``metrics.jsonl`` is mirrored here, at the number of completed
iterations (an event's ``step``; ``step + 1`` for the record of iteration ``step``):

==============================  ==========================================================
tag                             from
==============================  ==========================================================
``loss/<term>``                 each loss term's value (its weight not applied)
``loss/total``, ``grad_norm``   the combined loss and the gradient norm before clipping
``diagnostics/<name>``          values whose name starts with ``_`` (e.g. the share of
                                boundary points that converged)
``lr``, ``time``                the learning rate and the seconds of training
``multiplier/<term>``           the multipliers of a balancing method other than weighted
``feasibility/feasible``        shapes feasible at a feasibility check (and ``/shapes``)
``feasibility/worst/<metric>``  the worst value of each checked metric
``feasibility/violated/<c>``    how many shapes violate constraint ``c``
``feasibility/ratio/<c>``       the worst value of constraint ``c`` over its bound
``events``                      (text) every other event: rollback, restored, stopped, ...
``figures/<file>``              (image) the PNGs a completed run writes
==============================  ==========================================================

Resume: the writer is opened with ``purge_step`` one past the checkpoint's completed iterations,
so TensorBoard discards what the interrupted run logged after the checkpoint, as
``metrics.jsonl`` is cut back.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import ConfigError

__all__ = ["TensorBoardLog", "tensorboard_available"]


def tensorboard_available() -> bool:
    """Whether the ``tensorboard`` package (the ``track`` extra) is importable."""
    try:
        import tensorboard  # noqa: F401
    except ImportError:
        return False
    return True


class TensorBoardLog:
    """Writes the trainer's records as TensorBoard scalars, text and images under ``run_dir/tensorboard``.

    Arguments:
        run_dir: the run directory.
        purge_step: events at or after this TensorBoard step from an earlier process are
            discarded when TensorBoard reads the directory (0: none).
    """

    def __init__(self, run_dir: str | Path, purge_step: int = 0):
        if not tensorboard_available():
            raise ConfigError("training.log: tensorboard needs the tensorboard package (pip install 'ginn[track]')")
        from torch.utils.tensorboard import SummaryWriter

        self.path = Path(run_dir) / "tensorboard"
        self.writer = SummaryWriter(str(self.path), purge_step=purge_step if purge_step > 0 else None)

    def write(self, record: dict) -> None:
        """One record of ``metrics.jsonl``."""
        event = record.get("event")
        step = int(record.get("step", 0)) + (0 if event is not None else 1)
        add = self.writer.add_scalar
        if event is None:
            for k, v in record.items():
                if k in ("step", "multipliers") or not isinstance(v, (int, float)):
                    continue
                if k in ("lr", "time", "grad_norm"):
                    add(k, v, step)
                elif k == "total":
                    add("loss/total", v, step)
                elif k.startswith("_"):
                    add(f"diagnostics/{k[1:]}", v, step)
                else:
                    add(f"loss/{k}", v, step)
            for k, v in (record.get("multipliers") or {}).items():
                add(f"multiplier/{k}", v, step)
        elif event == "feasibility":
            add("feasibility/feasible", record["feasible"], step)
            add("feasibility/shapes", record["shapes"], step)
            for k, v in (record.get("worst") or {}).items():
                if isinstance(v, (int, float)):
                    add(f"feasibility/worst/{k}", v, step)
            for k, v in (record.get("violated") or {}).items():
                add(f"feasibility/violated/{k}", v, step)
            for k, v in (record.get("ratios") or {}).items():
                if isinstance(v, (int, float)):
                    add(f"feasibility/ratio/{k}", v, step)
        else:
            self.writer.add_text("events", json.dumps(record), step)

    def figures(self, paths: list[Path], step: int) -> int:
        """Add the PNG files among ``paths`` as images (tag ``figures/<file name>``); returns how many."""
        import matplotlib.image as mpimg

        n = 0
        for p in paths:
            if Path(p).suffix.lower() != ".png":
                continue
            img = np.asarray(mpimg.imread(str(p)))  # (H, W, 3 | 4) floats in [0, 1]
            if img.ndim == 2:
                img = img[..., None]
            self.writer.add_image(f"figures/{Path(p).stem}", img[..., :3], step, dataformats="HWC")
            n += 1
        return n

    def close(self) -> None:
        self.writer.flush()
        self.writer.close()
