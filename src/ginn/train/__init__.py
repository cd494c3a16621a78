"""The training engine, independent of any problem: the :class:`Task` and :class:`Results`
interfaces, the :class:`Trainer` (Adam, schedule, clipping, loss balancing, non-finite guard,
signals, checkpoints) and its plug-ins (:mod:`ginn.train.callbacks`), atomic checkpoints, run
directories and torchrun data parallelism."""

from .balancing import AugmentedLagrangian, Balance, WeightedSum, make_balancer
from .callbacks import Callback, StopRun
from .checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from .task import Evaluation, Metrics, Results, Task
from .trainer import Trainer, TrainingDiverged, TrainResult

__all__ = [
    "Task", "Results", "Evaluation", "Metrics", "Trainer", "TrainResult", "TrainingDiverged", "StopRun", "Callback",
    "WeightedSum", "AugmentedLagrangian", "Balance", "make_balancer",
    "CheckpointError", "load_checkpoint", "save_checkpoint",
]
