"""The training engine, independent of any problem: the :class:`Task` interface, the
:class:`Trainer` (Adam, schedule, clipping, loss balancing, non-finite guard, signals), atomic
checkpoints, run directories and torchrun data parallelism."""

from .balancing import AugmentedLagrangian, WeightedSum, make_balancer
from .checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from .task import Task
from .trainer import StopRun, Trainer, TrainingDiverged, TrainResult

__all__ = [
    "Task", "Trainer", "TrainResult", "TrainingDiverged", "StopRun",
    "WeightedSum", "AugmentedLagrangian", "make_balancer",
    "CheckpointError", "load_checkpoint", "save_checkpoint",
]
