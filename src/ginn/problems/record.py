"""A run's own copy of its problem: the spec, and every file it reads (meshes), so that a run
directory rebuilds its problem from what it holds and from nothing else.

Without files the copy is the spec file itself, comments and all. With files each one is copied
to ``inputs/`` beside the copy, and the copy is the validated spec as YAML with those paths made
relative (``inputs/part.stl``): a relative path in a spec resolves against the spec's own folder,
which for the copy is the run directory.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import yaml

from ..errors import GinnError
from .loader import load_spec
from .spec import ProblemSpec

__all__ = ["INPUTS", "SpecRecord", "record_spec"]

#: the folder of a run directory that holds the files its problem reads
INPUTS = "inputs"


@dataclass
class SpecRecord:
    """What a run keeps of its problem: ``text`` (the YAML of ``problem.yaml``) or, for a spec
    that reads no files and is what its file says, ``source`` (that file, copied as it is); and
    ``inputs``, ``{name in inputs/: the file it copies}``."""

    source: Path | None = None
    text: str | None = None
    inputs: dict[str, Path] = field(default_factory=dict)


def _mesh_paths(node, found: list[str]) -> None:
    """Every ``path`` of a mesh node (a region or an interface) in a dumped spec, in order."""
    if isinstance(node, dict):
        if node.get("type") == "mesh" and isinstance(node.get("path"), str):
            found.append(node["path"])
        for v in node.values():
            _mesh_paths(v, found)
    elif isinstance(node, list):
        for v in node:
            _mesh_paths(v, found)


def _relocate(node, names: dict[str, str]):
    if isinstance(node, dict):
        out = {k: _relocate(v, names) for k, v in node.items()}
        if node.get("type") == "mesh" and node.get("path") in names:
            out["path"] = f"{INPUTS}/{names[node['path']]}"
        return out
    if isinstance(node, list):
        return [_relocate(v, names) for v in node]
    return node


def record_spec(spec: ProblemSpec) -> SpecRecord:
    """The :class:`SpecRecord` of ``spec`` (its mesh paths are absolute once validated)."""
    data = spec.model_dump(mode="json", exclude_none=True, by_alias=True)
    paths: list[str] = []
    _mesh_paths(data, paths)
    if not paths:
        src = Path(spec.source)
        if src.is_file():
            try:
                if load_spec(src).model_dump(mode="json") == spec.model_dump(mode="json"):
                    return SpecRecord(source=src)
            except GinnError:  # a source that no longer loads: recorded as YAML
                pass
        return SpecRecord(text=yaml.safe_dump(data, sort_keys=False))
    names: dict[str, str] = {}
    inputs: dict[str, Path] = {}
    for p in dict.fromkeys(paths):
        name, stem, suffix, i = Path(p).name, Path(p).stem, Path(p).suffix, 1
        while name in inputs:
            name, i = f"{stem}-{i}{suffix}", i + 1
        names[p], inputs[name] = name, Path(p)
    return SpecRecord(text=yaml.safe_dump(_relocate(data, names), sort_keys=False), inputs=inputs)
