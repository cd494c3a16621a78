"""The one table of task kinds: a spec's ``kind`` (and the run's ``params.kind``) to its Task class.

A new kind of problem adds its parameter group to :data:`ginn.config.TaskParams` and one row here.
"""

from __future__ import annotations

from ..config import TASK_KINDS, RunConfig
from ..errors import SpecError
from ..problems.spec import ProblemSpec
from ..train.task import Task
from .gray_scott import GrayScottTask
from .mirror import MirrorTask
from .shape import ShapeTask

#: kind -> Task class (each builds itself from the spec and the config: ``Task.from_spec``).
TASKS: dict[str, type[Task]] = {
    "shape": ShapeTask,
    "mirror": MirrorTask,
    "gray-scott": GrayScottTask,
}

assert set(TASKS) == set(TASK_KINDS), "every task kind of ginn.config.TaskParams needs a row in TASKS"


def make_task(spec: ProblemSpec, cfg: RunConfig) -> Task:
    """Build the task of ``spec`` (a loaded problem spec) under ``cfg``."""
    cls = TASKS.get(spec.kind)
    if cls is None:  # pragma: no cover - the spec schema admits TASK_KINDS only
        raise SpecError(f"spec field 'kind': unknown problem kind {spec.kind!r}")
    return cls.from_spec(spec, cfg)
