"""The package structure: imports follow the layers docs/architecture.md lists, every module
imports on its own, the packages form no import cycle, ginn modules are imported at the top of a
module (no hidden function-local imports), and no module reaches into another module's private
names."""

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import ginn

SRC = Path(ginn.__file__).resolve().parent
ARCHITECTURE = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"
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


def _package_imports(modules: dict[str, Path]) -> list[tuple[str, str, str]]:
    """``(package, imported package, where)`` of every import between two packages."""
    out = []
    for name, path in modules.items():
        if name in FACADES:
            continue
        src = _package(name, modules)
        for target, line, _, _ in _imports(name, path):
            owner = _owner(target, modules)
            if owner is None or owner in FACADES:
                assert owner not in FACADES, f"{name} imports the façade {owner}"
                continue
            dst = _package(owner, modules)
            if dst != src:
                out.append((src, dst, f"{name}:{line} imports {target}"))
    return out


def _layers() -> dict[str, int]:
    """Each package's layer, from the list under "## Layers" in docs/architecture.md (0 at the
    bottom); ``ginn/__init__`` is the façade."""
    block = ARCHITECTURE.read_text().split("## Layers", 1)[1].split("```", 2)[1]
    rank = {}
    for i, line in enumerate(ln for ln in block.splitlines() if ln.strip()):
        for name in line.split("  ")[0].split(","):
            rank[name.strip()] = i
    return rank


def layer_violations(imports: list[tuple[str, str, str]], rank: dict[str, int]) -> list[str]:
    """The imports of a package from a higher layer, and the packages the list leaves out."""
    bad = [f"{where}: {src} (layer {rank[src]}) imports {dst} (layer {rank[dst]})"
           for src, dst, where in imports if src in rank and dst in rank and rank[dst] > rank[src]]
    bad += sorted({f"package {p} is in no layer of docs/architecture.md" for s, d, _ in imports for p in (s, d)
                   if p not in rank})
    return bad


def test_imports_follow_the_documented_layers():
    assert not layer_violations(_package_imports(_modules()), _layers())


def test_an_upward_import_fails_the_layer_check(tmp_path):
    """The check catches an import against the order: geometry importing the evaluation."""
    modules = _modules()
    bent = tmp_path / "base.py"
    bent.write_text(modules["ginn.geometry.base"].read_text() + "\nfrom ..eval import metrics  # noqa\n")
    bad = layer_violations(_package_imports({**modules, "ginn.geometry.base": bent}), _layers())
    assert len(bad) == 1 and "geometry (layer 2) imports eval (layer 6)" in bad[0]
    assert "package nowhere is in no layer" in layer_violations([("nowhere", "errors", "x")], _layers())[0]


def test_package_graph_is_acyclic():
    modules = _modules()
    edges: dict[str, set[str]] = {}
    for src, dst, _ in _package_imports(modules):
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
    # what the layers' notes say: config depends on nothing of ginn but errors, train on no task
    # and no evaluation
    assert edges.get("config", set()) <= {"errors"}
    assert not edges.get("train", set()) & {"tasks", "runs", "eval", "constraints"}
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


def _closures(modules: dict[str, Path]) -> dict[str, list[str]]:
    """Every module's ginn dependencies, transitively: the modules it imports and the packages
    above it (whose ``__init__`` runs first), without the façade ``ginn``."""
    direct: dict[str, set[str]] = {}
    for name, path in modules.items():
        deps = {o for t, *_ in _imports(name, path) if (o := _owner(t, modules)) not in (None, "ginn")}
        parts = name.split(".")
        deps |= {".".join(parts[:i]) for i in range(2, len(parts))} & set(modules)
        direct[name] = deps - {name}
    out = {}
    for name in modules:
        seen, todo = set(), list(direct[name])
        while todo:
            m = todo.pop()
            if m not in seen:
                seen.add(m)
                todo += direct.get(m, ())
        out[name] = sorted(seen)
    return out


@pytest.mark.long
def test_every_module_imports_on_its_own():
    """Each module imported with nothing of ginn loaded but what it imports itself (directly or
    through the modules it imports, and the packages above it; the package ``ginn`` a bare
    namespace, its ``__init__``, which imports everything, not run), so that no module relies on
    another having been imported before it; then the façade itself, in a clean ``sys.modules``."""
    modules = _modules()
    closures = _closures({n: p for n, p in modules.items() if n not in FACADES})
    code = (
        "import importlib, json, sys, types\n"
        f"src = {str(SRC)!r}\n"
        "closures = json.loads(sys.stdin.read())\n"
        "bad = []\n"
        "for n, keep in closures.items():\n"
        "    keep = set(keep) | {'ginn'}\n"
        "    for k in [k for k in sys.modules if (k == 'ginn' or k.startswith('ginn.')) and k not in keep]:\n"
        "        del sys.modules[k]\n"
        "    for k, m in list(sys.modules.items()):  # a package keeps no attribute for a module gone\n"
        "        if k.startswith('ginn') and hasattr(m, '__path__'):\n"
        "            for a, v in list(vars(m).items()):\n"
        "                if isinstance(v, types.ModuleType) and v.__name__.startswith('ginn.') and v.__name__ not in sys.modules:\n"
        "                    delattr(m, a)\n"
        "    if 'ginn' not in sys.modules:\n"
        "        bare = types.ModuleType('ginn')\n"
        "        bare.__path__ = [src]\n"
        "        sys.modules['ginn'] = bare\n"
        "    try:\n"
        "        importlib.import_module(n)\n"
        "    except Exception as e:\n"
        "        bad.append(f'{n}: {type(e).__name__}: {e}')\n"
        "for k in [k for k in sys.modules if k == 'ginn' or k.startswith('ginn.')]:\n"
        "    del sys.modules[k]\n"
        "importlib.import_module('ginn')\n"
        "print('\\n'.join(bad))\n"
        "sys.exit(1 if bad else 0)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], input=json.dumps(closures), capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert len(closures) > 60


def test_the_import_check_catches_a_module_relying_on_another(tmp_path):
    """A module that uses a package it never imports (here ``ginn.errors`` through the bare
    ``ginn`` namespace) fails when loaded with only its own closure."""
    pkg = tmp_path / "ginn"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "errors.py").write_text("X = 1\n")
    (pkg / "user.py").write_text("import ginn\nY = ginn.errors.X\n")
    code = ("import importlib, sys, types\n"
            f"bare = types.ModuleType('ginn'); bare.__path__ = [{str(pkg)!r}]; sys.modules['ginn'] = bare\n"
            "importlib.import_module('ginn.errors')\n"
            "del sys.modules['ginn.errors']; del bare.errors\n"
            "importlib.import_module('ginn.user')\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "has no attribute 'errors'" in r.stderr


def test_public_api_names_resolve():
    for name in ginn.__all__:
        assert hasattr(ginn, name), name
    for mod in (ginn.train, ginn.tasks, ginn.extract, ginn.eval, ginn.viz, ginn.models, ginn.losses, ginn.topology,
                ginn.constraints):
        for name in mod.__all__:
            assert hasattr(mod, name), f"{mod.__name__}.{name}"
