#!/usr/bin/env python
"""Write docs/config.md, the reference of every run-configuration field, from ginn.config.

    python scripts/config_reference.py           # rewrite docs/config.md
    python scripts/config_reference.py --check   # exit 1 if docs/config.md is out of date

The field descriptions of the pydantic models in ``src/ginn/config.py`` are the single source;
the test suite runs ``--check`` so the page cannot drift from the code.
"""

from __future__ import annotations

import argparse
import sys
import typing
from pathlib import Path

from pydantic import BaseModel

from ginn.config import RETIRED, TASK_KINDS, TASK_PARAMS, RunConfig

OUT = Path(__file__).resolve().parents[1] / "docs" / "config.md"

INTRO = """# Run configuration reference

Every run is configured by one `RunConfig` (`ginn.config`), written in full to `RUN/config.yaml`.
A problem spec's `defaults`, then a preset, then the command-line flags, then `--set key=value`
overrides are merged and validated once; an unknown key or a bad value is one line
`config field '<path>': <what is wrong>` and exit status 2. Any field below can be set with
`--set` (dotted path, YAML value), in a spec's `defaults` or in a preset.

This page is generated from the field descriptions in `src/ginn/config.py` by
`python scripts/config_reference.py`; a test keeps it in step with the code.
"""


def _type(annotation) -> str:
    origin = typing.get_origin(annotation)
    if origin is typing.Literal:
        return " \\| ".join(f"`{a}`" for a in typing.get_args(annotation))
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        return " or ".join(_type(a) for a in typing.get_args(annotation))
    if origin is list:
        (arg,) = typing.get_args(annotation) or (typing.Any,)
        return f"list of {_type(arg)}"
    if annotation is type(None):
        return "null"
    return getattr(annotation, "__name__", str(annotation))


def _default(field) -> str:
    if field.default_factory is not None:
        value = field.default_factory()
    else:
        value = field.default
    if isinstance(value, BaseModel):
        return ""
    return "`null`" if value is None else f"`{value}`"


def _bounds(field) -> str:
    out = []
    for m in field.metadata:
        for name, sym in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
            v = getattr(m, name, None)
            if v is not None:
                out.append(f"{sym} {v}")
    return ", ".join(out)


def _row(key: str, field, default: str) -> str:
    if not field.description:
        raise SystemExit(f"config_reference.py: config field {key!r} has no description in src/ginn/config.py")
    meaning = field.description.replace("|", "\\|")
    bounds = _bounds(field)
    if bounds:
        meaning = f"{meaning} ({bounds})"
    return f"| `{key}` | {_type(field.annotation)} | {default} | {meaning} |"


def _is_group(annotation) -> bool:
    return isinstance(annotation, type) and issubclass(annotation, BaseModel)


def _rows(model: type[BaseModel], prefix: str, inst: BaseModel | None, skip=frozenset()) -> list[str]:
    rows = []
    for name, field in model.model_fields.items():
        if name in skip:
            continue
        if _is_group(field.annotation):  # a group in a group (e.g. a loss term): spelled out
            sub = getattr(inst, name) if inst is not None else field.get_default(call_default_factory=True)
            rows += _rows(field.annotation, f"{prefix}{name}.", sub)
            continue
        if inst is not None:
            v = getattr(inst, name)
            default = "`null`" if v is None else f"`{v}`"
        else:
            default = _default(field)
        rows.append(_row(f"{prefix}{name}", field, default))
    return rows


def _table(model: type[BaseModel], prefix: str, skip: set[str] = frozenset()) -> list[str]:
    """The rows of ``model``'s fields, groups within it spelled out with their default instance's values."""
    return ["| key | type | default | meaning |", "|---|---|---|---|", *_rows(model, prefix, None, skip)]


def render() -> str:
    out = [INTRO]
    groups = {n: f.annotation for n, f in RunConfig.model_fields.items()
              if isinstance(f.annotation, type) and issubclass(f.annotation, BaseModel)}
    top = _table(RunConfig, "", skip={"params", *groups})
    out += ["## Top level", "", *top, ""]
    for name, model in groups.items():
        out += [f"## `{name}`", "", (model.__doc__ or "").strip().splitlines()[0], "", *_table(model, f"{name}."), ""]
    out += ["## `params`: the task kind's own group", "",
            "One group per task kind, chosen by `params.kind` (a problem spec sets it from its `kind`): "
            + ", ".join(f"`{k}`" for k in TASK_KINDS) + ".", ""]
    for kind, model in TASK_PARAMS.items():
        doc = (model.__doc__ or "").strip().splitlines()[0]
        out += [f"### `params.kind: {kind}`", "", doc, ""]
        rows = _table(model, "params.", skip={"kind"})
        if len(rows) > 2:
            out += [*rows, ""]
    out += ["## Retired settings", "",
            "Removed settings. A configuration that names one at the value that made it do nothing still "
            "loads (run directories written by earlier versions keep resuming); any other value is refused with the reason.", "",
            "| key | inert value | what replaces it, and why |", "|---|---|---|",
            *(f"| `{k}` | `{v}` | {why.replace('|', chr(92) + '|')} |" for k, (v, why) in RETIRED.items()), ""]
    return "\n".join(out).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--check", action="store_true", help="exit 1 if docs/config.md is out of date")
    a = p.parse_args(argv)
    text = render()
    if a.check:
        if not OUT.is_file() or OUT.read_text() != text:
            print("docs/config.md is out of date: run python scripts/config_reference.py")
            return 1
        print("docs/config.md is up to date")
        return 0
    OUT.write_text(text)
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
