"""Reading problem specs: YAML files and the built-in presets (``problems/presets/*.yaml``)."""

from __future__ import annotations

from pathlib import Path

from ..errors import ConfigError, SpecError
from ..yamlfile import load_yaml
from .spec import ProblemSpec, validate_spec

PRESET_DIR = Path(__file__).resolve().parent / "presets"


def list_problems() -> list[str]:
    """Names of the built-in problems (sorted)."""
    return sorted(p.stem for p in PRESET_DIR.glob("*.yaml"))


def problem_summaries() -> list[tuple[str, str, str]]:
    """``(name, kind, one-line description)`` of every built-in problem (for ``ginn problems``)."""
    out = []
    for name in list_problems():
        spec = load_spec(builtin_path(name))
        out.append((name, spec.kind, " ".join(spec.description.split())))
    return out


def builtin_path(name: str) -> Path:
    """The YAML file of a built-in problem. Raises SpecError for an unknown name."""
    p = PRESET_DIR / f"{name}.yaml"
    if not p.is_file():
        raise SpecError(f"unknown problem '{name}' (built-in: {', '.join(list_problems())}; or give a .yaml path)")
    return p


def spec_text(path_or_name: str | Path) -> str:
    """The YAML text of a spec file or a built-in problem (what ``ginn problems show`` prints)."""
    return _locate(path_or_name).read_text()


def _locate(path_or_name: str | Path) -> Path:
    """The spec file: a path to a YAML file, or a built-in problem's by name. A directory is never
    a spec, so a bare built-in name that also names a directory here (e.g. a run directory written
    with ``--out obstacle``) is the built-in problem."""
    p = Path(path_or_name).expanduser()
    if p.is_dir():
        if len(Path(path_or_name).parts) == 1 and str(path_or_name) in list_problems():
            return builtin_path(str(path_or_name))
        raise SpecError(f"spec {p}: is a directory, not a YAML spec file")
    if p.suffix.lower() in (".yaml", ".yml") or p.is_file() or len(p.parts) > 1:
        if not p.is_file():
            raise SpecError(f"spec file not found: {p}")
        return p
    return builtin_path(str(path_or_name))


def parse_spec(text: str, base_dir: Path | None = None, source: str = "<string>") -> ProblemSpec:
    """Validate a spec given as YAML text (relative mesh paths resolve against ``base_dir``)."""
    try:
        data = load_yaml(text, f"spec {source}")
    except ConfigError as e:
        raise SpecError(str(e)) from None
    return validate_spec(data, base_dir=base_dir, source=source)


def load_spec(path_or_name: str | Path) -> ProblemSpec:
    """Load and validate a spec: a path to a YAML file, or the name of a built-in problem.

    Relative mesh paths in a file resolve against the file's directory.

    Raises:
        SpecError: one line naming the file or field and what is wrong.
    """
    p = _locate(path_or_name)
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise SpecError(f"spec {p}: cannot read ({type(e).__name__})") from None
    return parse_spec(text, base_dir=p.resolve().parent, source=str(p))


def get_spec(name: str) -> ProblemSpec:
    """The spec of a built-in problem by name."""
    return load_spec(builtin_path(name))
