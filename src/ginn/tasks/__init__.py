"""The built-in tasks (shape problems, the parabolic mirror, the Gray-Scott PINN) and the registry
that maps a problem kind to its Task class."""

from .gray_scott import GrayScottTask
from .mirror import MirrorTask
from .registry import TASKS, make_task
from .shape import ShapeTask

__all__ = ["TASKS", "make_task", "ShapeTask", "MirrorTask", "GrayScottTask"]
