"""Run configuration: the vocabulary every layer of ginn speaks, validated (pydantic) and frozen.

Every field is settable by ``--set a.b=v``. A problem spec's ``defaults`` and a preset's overrides
are partial dicts of :class:`RunConfig`, merged in that order, then ``--set`` overrides; the result
is validated once (:func:`build_config`). Task-specific parameters are the typed group ``params``,
one model per task kind, selected by its ``kind`` (a discriminated union): :class:`ShapeParams`,
:class:`MirrorParams`, :class:`GrayScottParams`.

One module per family of groups: :mod:`~ginn.config.base` (strict models, loss terms, dtypes,
default resolutions), :mod:`~ginn.config.engine` (model, latents, balancing, training, output),
one module per task kind's parameters (:mod:`~ginn.config.shape`, :mod:`~ginn.config.mirror`,
:mod:`~ginn.config.gray_scott`), and :mod:`~ginn.config.run` (the run configuration, merging,
``--set``). The kinds' parameter schemas live here, beside the engine's, so that a configuration
is validated whole, once, before any task exists (a spec's defaults, a preset, ``--set``, a
sweep's trial); everything else of a kind lives in its task package.

This package imports only :mod:`ginn.errors`; ``docs/config.md`` is generated from the field
descriptions here (``python scripts/config_reference.py``) and a test keeps it in step.
"""

from .base import (
    CELLS_PER_LENGTH,
    DTYPES,
    HELDOUT_LATENTS,
    HELDOUT_PER_SHAPE,
    MIN_STEP_CODES,
    RESOLUTION,
    STRAIN_CLIP,
    LossTerm,
    Strict,
    default_resolution,
)
from .engine import BalancingConfig, LatentConfig, ModelConfig, OutputConfig, TrainingConfig
from .gray_scott import GrayScottLosses, GrayScottParams, GSParams
from .mirror import MirrorParams
from .run import (
    RETIRED,
    TASK_KINDS,
    TASK_PARAMS,
    RunConfig,
    TaskParams,
    build_config,
    config_to_dict,
    deep_merge,
    drop_retired,
    flattened,
    nested,
    one_line,
    parse_set,
    parse_task_params,
    with_overrides,
)
from .shape import ConnectednessConfig, DiversityConfig, LossesConfig, SamplingConfig, ShapeParams, StructuralConfig, TopologyConfig

__all__ = [
    "CELLS_PER_LENGTH", "DTYPES", "HELDOUT_LATENTS", "HELDOUT_PER_SHAPE", "MIN_STEP_CODES", "RESOLUTION", "STRAIN_CLIP", "LossTerm",
    "Strict", "default_resolution",
    "ModelConfig", "LatentConfig", "BalancingConfig", "TrainingConfig", "OutputConfig",
    "LossesConfig", "SamplingConfig", "DiversityConfig", "ConnectednessConfig", "TopologyConfig", "StructuralConfig", "ShapeParams",
    "MirrorParams", "GSParams", "GrayScottLosses", "GrayScottParams",
    "TASK_PARAMS", "TASK_KINDS", "TaskParams", "RunConfig", "RETIRED",
    "deep_merge", "flattened", "nested", "parse_set", "one_line", "drop_retired", "build_config", "with_overrides",
    "parse_task_params", "config_to_dict",
]
