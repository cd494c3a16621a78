"""Errors that the CLI turns into one clear line and exit status 2, and the one formatter of
pydantic validation errors into such a line.

This module imports nothing of ginn (and nothing of pydantic: it reads the plain dicts of
``ValidationError.errors()``), so every layer may use it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any


class GinnError(Exception):
    """Base class of user-facing errors."""


class ConfigError(GinnError, ValueError):
    """A bad configuration value, flag or key."""


class SpecError(GinnError, ValueError):
    """A malformed problem spec; the message names the field path."""


def field_message(err: Mapping[str, Any]) -> str:
    """What is wrong, in a few words, from one entry of ``ValidationError.errors()``."""
    t = err.get("type", "")
    ctx = err.get("ctx") or {}
    msg = str(err.get("msg", "invalid value"))
    if t == "missing":
        return "required field is missing"
    if t == "extra_forbidden":
        return "unknown key"
    if t == "greater_than":
        return f"must be > {ctx.get('gt')}"
    if t == "greater_than_equal":
        return f"must be >= {ctx.get('ge')}"
    if t == "less_than":
        return f"must be < {ctx.get('lt')}"
    if t == "less_than_equal":
        return f"must be <= {ctx.get('le')}"
    if t == "finite_number":
        return "must be a finite number (not nan or inf)"
    if t == "too_short":
        return f"needs at least {ctx.get('min_length')} item(s), got {ctx.get('actual_length')}"
    if t == "union_tag_invalid":
        return f"unknown type '{ctx.get('tag')}' (expected one of: {str(ctx.get('expected_tags', '')).replace(chr(39), '')})"
    if t == "union_tag_not_found":
        return f"missing key '{ctx.get('discriminator', 'type').strip(chr(39))}'"
    if t == "value_error":
        return msg.removeprefix("Value error, ")
    if t in ("float_parsing", "float_type"):
        return "must be a number"
    if t == "literal_error":
        return "must be " + msg.removeprefix("Input should be ")
    return msg[:1].lower() + msg[1:]


def field_path(loc: Iterable[Any], data: Any = None, tags: Iterable[str] = ()) -> str:
    """A readable path from a pydantic ``loc``, e.g. ``geometry.interfaces[1].radius``.

    Discriminated unions put their tag into ``loc`` (``interfaces.1.circle.radius``); a tag is
    dropped where ``data`` shows that the element at that place is tagged with it, or, without
    ``data``, where it is one of ``tags``. Validator wrappers (``function-after[...]``) are dropped.
    """
    tags = set(tags)
    out = ""
    cur = data
    for el in loc:
        if isinstance(el, int):
            out += f"[{el}]"
            cur = cur[el] if isinstance(cur, list) and -len(cur) <= el < len(cur) else None
            continue
        el = str(el)
        if isinstance(cur, dict) and el in cur:
            out += ("." if out else "") + el
            cur = cur[el]
        elif el in tags and (cur is None or isinstance(cur, dict)):
            continue  # the discriminator tag of the element at this place
        elif "[" in el or "-" in el and el not in tags:
            continue  # a validator wrapper such as function-after[...]
        else:
            out += ("." if out else "") + el
            cur = None
    return out or "<root>"
