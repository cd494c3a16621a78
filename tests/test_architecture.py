"""The package structure: every module imports on its own, the packages form no import cycle,
ginn modules are imported at the top of a module (no hidden function-local imports), and no
module reaches into another module's private names."""

import ast
import subprocess
import sys
from pathlib import Path

import ginn

SRC = Path(ginn.__file__).resolve().parent
#: the façade and the entry point may import from every package
FACADES = {"ginn", "ginn.__main__"}


def _module_name(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(SRC.rglob("*.py"))}


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> list[str]:
    """Absolute names a ``from ... import ...`` statement refers to (module or module.name)."""
    if node.level == 0:
        base = node.module or ""
    else:
        parts = module.split(".")
        if not is_package:
            parts = parts[:-1]
        parts = parts[: len(parts) - (node.level - 1)]
        base = ".".join(parts + ([node.module] if node.module else []))
    return [f"{base}.{a.name}" if a.name != "*" else base for a in node.names]


def _imports(module: str, path: Path) -> list[tuple[str, int, bool, str]]:
    """``(target, line, at_top_level, source line)`` of every ginn import in ``path``."""
    tree = ast.parse(path.read_text())
    lines = path.read_text().splitlines()
    top = set(id(n) for n in tree.body)
    for n in tree.body:  # imports under a top-level `if`/`try` count as top level
        if isinstance(n, (ast.If, ast.Try)):
            top |= {id(c) for c in ast.walk(n)}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            targets = _resolve(module, path.name == "__init__.py", node)
        else:
            continue
        for t in targets:
            if t == "ginn" or t.startswith("ginn."):
                out.append((t, node.lineno, id(node) in top, lines[node.lineno - 1]))
    return out


def _package(name: str, modules: dict[str, Path]) -> str:
    """The first-level unit a module belongs to: ``ginn.train.trainer`` -> ``train``; ``ginn.config`` -> ``config``."""
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else ""


def _owner(target: str, modules: dict[str, Path]) -> str | None:
    """The module a dotted import target lives in (``ginn.config.RunConfig`` -> ``ginn.config``)."""
    while target and target not in modules:
        target = target.rpartition(".")[0]
    return target or None


def test_package_graph_is_acyclic():
    modules = _modules()
    edges: dict[str, set[str]] = {}
    for name, path in modules.items():
        if name in FACADES:
            continue
        src = _package(name, modules)
        for target, _, _, _ in _imports(name, path):
            owner = _owner(target, modules)
            if owner is None or owner in FACADES:
                assert owner not in FACADES, f"{name} imports the façade {owner}"
                continue
            dst = _package(owner, modules)
            if dst != src:
                edges.setdefault(src, set()).add(dst)
    # depth-first search for a cycle
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(u: str) -> None:
        state[u] = 1
        stack.append(u)
        for v in sorted(edges.get(u, ())):
            if state.get(v) == 1:
                cycle = stack[stack.index(v):] + [v]
                raise AssertionError("package import cycle: " + " -> ".join(cycle))
            if state.get(v) is None:
                visit(v)
        stack.pop()
        state[u] = 2

    for u in sorted(edges):
        if state.get(u) is None:
            visit(u)
    # the layering the docs describe: config depends on nothing of ginn but errors, train on no task
    assert edges.get("config", set()) <= {"errors"}
    assert "tasks" not in edges.get("train", set()) and "runs" not in edges.get("train", set())
    assert not edges.get("errors")


def test_ginn_imports_are_at_module_level_and_public():
    """A function-local import of a ginn module hides a dependency; one is allowed only where it
    defers a heavy optional dependency, and its line says so (``# deferred: ...``). Names with a
    leading underscore belong to their module."""
    modules = _modules()
    bad = []
    for name, path in modules.items():
        for target, line, at_top, text in _imports(name, path):
            if not at_top and "deferred:" not in text:
                bad.append(f"{path.relative_to(SRC.parent)}:{line}: function-local import of {target}")
            owner = _owner(target, modules)
            leaf = target[len(owner) + 1:] if owner and len(target) > len(owner) else ""
            if leaf.startswith("_") and not leaf.startswith("__") and owner is not None and _package(owner, modules) != _package(name, modules):
                bad.append(f"{path.relative_to(SRC.parent)}:{line}: imports the private {target}")
    assert not bad, "\n".join(bad)


def test_every_module_imports_on_its_own():
    """Each module imported first in a clean ``sys.modules`` (one interpreter; ginn's modules are
    dropped between imports), so no module relies on another having been imported before it."""
    names = sorted(n for n in _modules() if n != "ginn.__main__")
    code = (
        "import importlib, sys, traceback\n"
        f"names = {names!r}\n"
        "bad = []\n"
        "for n in names:\n"
        "    for k in [k for k in sys.modules if k == 'ginn' or k.startswith('ginn.')]:\n"
        "        del sys.modules[k]\n"
        "    try:\n"
        "        importlib.import_module(n)\n"
        "    except Exception as e:\n"
        "        bad.append(f'{n}: {type(e).__name__}: {e}')\n"
        "print('\\n'.join(bad))\n"
        "sys.exit(1 if bad else 0)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert len(names) > 60


def test_public_api_names_resolve():
    for name in ginn.__all__:
        assert hasattr(ginn, name), name
    for mod in (ginn.train, ginn.tasks, ginn.extract, ginn.eval, ginn.viz, ginn.models, ginn.losses, ginn.topology):
        for name in mod.__all__:
            assert hasattr(mod, name), f"{mod.__name__}.{name}"
