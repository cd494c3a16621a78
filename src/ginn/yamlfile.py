"""Reading YAML strictly: a key repeated in one mapping is an error, not a silent overwrite.

Used for problem specs, run configurations (``config.yaml``) and sweep search spaces. Imports
only :mod:`ginn.errors`.
"""

from __future__ import annotations

from typing import Any

import yaml

from .errors import ConfigError

__all__ = ["load_yaml"]


class _StrictLoader(yaml.SafeLoader):
    """yaml's safe loader, refusing duplicate keys."""


class _DuplicateKey(yaml.YAMLError):
    pass


def _mapping(loader: _StrictLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen: dict = {}
    for key_node, _ in node.value:  # the mapping's own keys (a `<<` merge may be overridden)
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            raise _DuplicateKey(f"duplicate key {key!r} at line {key_node.start_mark.line + 1} "
                                f"(first at line {seen[key] + 1})")
        seen[key] = key_node.start_mark.line
    loader.flatten_mapping(node)
    return loader.construct_mapping(node, deep=deep)


_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping)


def load_yaml(text: str, source: str = "<string>") -> Any:
    """Parse YAML ``text`` (from ``source``, for messages).

    Raises:
        ConfigError: one line, ``<source>: YAML syntax error at line L, column C: <problem>``,
            ``<source>: duplicate key 'k' at line L (first at line M)`` or ``<source>: nested more
            than 64 levels deep``.
    """
    try:
        data = yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - a SafeLoader subclass
    except RecursionError:
        raise ConfigError(f"{source}: nested more than {MAX_DEPTH} levels deep") from None
    except _DuplicateKey as e:
        raise ConfigError(f"{source}: {e}") from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or type(e).__name__
        raise ConfigError(f"{source}: YAML syntax error{where}: {problem}") from None
    if _depth(data) > MAX_DEPTH:
        raise ConfigError(f"{source}: nested more than {MAX_DEPTH} levels deep")
    return data


#: the deepest nesting of mappings and lists accepted (a spec or config needs a handful; CSG trees
#: a few dozen)
MAX_DEPTH = 64


def _depth(data: Any) -> int:
    """The nesting depth of mappings and lists in ``data`` (iterative: no recursion limit)."""
    deepest, stack = 0, [(data, 0)]
    while stack:
        node, d = stack.pop()
        if isinstance(node, dict):
            stack.extend((v, d + 1) for v in node.values())
        elif isinstance(node, list):
            stack.extend((v, d + 1) for v in node)
        else:
            continue
        deepest = max(deepest, d + 1)
        if deepest > MAX_DEPTH:
            break
    return deepest
