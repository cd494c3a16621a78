"""The docs are a reference that cannot drift: the generated pages match the code, every flag, node
type and preset is documented, every figure link resolves, and no page, comment, preset, test or
script reads like a lab notebook (development chapters, run ids)."""

import importlib.util
import re
import sys
from pathlib import Path

import pytest

from ginn.cli.parser import build_parser
from ginn.problems import list_problems, load_spec
from ginn.problems.interfaces import INTERFACE_TYPES
from ginn.problems.regions import REGION_TYPES

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_config_reference_is_generated_from_the_code():
    assert _script("config_reference").main(["--check"]) == 0


def test_results_tables_are_generated_from_results_yaml():
    assert _script("reproduce").main(["--check"]) == 0


def test_results_summary_of_a_shape_run():
    """The values a results table shows, from a metrics.json of two shapes."""
    rp = _script("reproduce")
    m = {"n_shapes": 2, "diversity_mean": 0.12,
         "shapes": [{"b0": 1, "b0_in_design_region": 1, "connected_interfaces_share": 1.0, "interface_cd1": 3e-3,
                     "volume_outside": 1e-3},
                    {"b0": 2, "b0_in_design_region": 1, "connected_interfaces_share": 0.5, "interface_cd1": 7e-3,
                     "volume_outside": 4e-3}],
         "mean": {"b0": 1.5, "b0_in_design_region": 1.0, "connected_interfaces_share": 0.75, "interface_cd1": 5e-3,
                  "volume_outside": 2.5e-3, "surface_strain": 12.0}}
    s = rp.summarize("shape", m)
    assert s["conn"] == [1, 2] and s["cd1_max"] == 7e-3 and s["vol_out_max"] == 4e-3 and s["delta"] == 0.12
    assert rp.fmt(s["conn"], "frac") == "1/2" and rp.fmt(s["cd1"], ".1e") == "5.0e-03" and rp.fmt(None, ".3f") == "–"
    row = {"id": "x", "problem": "obstacle", "preset": "quick", "seed": 1, "set": ["model.w0_first=2"]}
    assert rp.command(row) == "ginn train obstacle --preset quick --seed 1 --set model.w0_first=2"


def test_every_cli_flag_is_documented():
    text = (DOCS / "cli.md").read_text() + (DOCS / "scaling.md").read_text()
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    missing = []
    for name, p in sub.choices.items():
        assert f"ginn {name}" in text, name
        for action in p._actions:
            for flag in action.option_strings:
                if flag.startswith("--") and flag != "--help" and flag not in text:
                    missing.append(f"ginn {name} {flag}")
    assert not missing, missing


def test_every_node_type_and_preset_is_in_the_spec_reference():
    text = (DOCS / "problem-spec.md").read_text()
    for t in (*REGION_TYPES, *INTERFACE_TYPES):
        assert f"| `{t}` |" in text, t
    for name in list_problems():
        assert f"`{name}`" in text, name
        for preset in load_spec(name).presets:
            assert f"`{preset}`" in text, (name, preset)


def test_figure_links_resolve_and_every_figure_is_used():
    pages = {p: p.read_text() for p in [*DOCS.glob("*.md"), ROOT / "README.md"]}
    linked = set()
    for page, text in pages.items():
        for link in re.findall(r"\]\((img/[^)]+)\)", text):
            assert (DOCS / link).is_file(), f"{page.name}: {link}"
            linked.add(link)
    on_disk = {f"img/{p.name}" for p in (DOCS / "img").glob("*")}
    assert on_disk <= linked, sorted(on_disk - linked)


_CHAPTERS = re.compile(r"\bsessions?\b", re.IGNORECASE)  # development chapters ("the fourth session")
_RUN_IDS = re.compile(
    r"(?<![\w.])o_[A-Z][A-Za-z0-9]*\b"        # obstacle run ids (o_Z, o_B2)
    r"|\bb(1[0-9]|[2-9][0-9])\b"             # bracket run ids (b0, b1 are Betti numbers)
    r"|\bg\d+s\d\b|\bg1[0-9]\b"              # generative bracket / gray-scott run ids
    r"|\b[Rr]uns? [a-z]\d+\b"
)


@pytest.mark.parametrize("where", ["docs", "src", "tests", "scripts", "benchmarks", "README.md", "Makefile"])
def test_no_lab_notebook(where):
    root = ROOT / where
    files = [root] if root.is_file() else [p for p in root.rglob("*") if p.suffix in (".md", ".py", ".yaml", ".sh", ".toml")]
    bad = []
    for f in files:
        if f.resolve() == Path(__file__).resolve():
            continue
        for i, line in enumerate(f.read_text().splitlines(), 1):
            m = _CHAPTERS.search(line) or _RUN_IDS.search(line)
            if m:
                bad.append(f"{f.relative_to(ROOT)}:{i}: {m.group(0)!r} in {line.strip()[:100]}")
    assert not bad, "\n".join(bad)


#: what a reference page must not hold: commits (hex words of 7 to 40 digits and letters), the
#: project's issues by number, and the changes of a diary ("no longer", "fell from ... to ..."); a
#: page says what the code does, the git log what changed
_HISTORY = re.compile(r"(?<![\w.#-])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![\w.-])"
                      r"|\bissues? ?(?:#|no\. ?)?-?\d+|\bissue-\d+|#\d{1,4}\b|\bno longer\b|\bfell from\b")


@pytest.mark.parametrize("page", sorted(p.name for p in DOCS.glob("*.md")) + ["README.md"])
def test_reference_pages_cite_no_commit_or_issue(page):
    path = ROOT / page if page == "README.md" else DOCS / page
    bad = [f"{page}:{i}: {m.group(0)!r} in {line.strip()[:100]}"
           for i, line in enumerate(path.read_text().splitlines(), 1) if (m := _HISTORY.search(line))]
    assert not bad, "\n".join(bad)


def test_the_history_pattern_catches_commits_and_issues():
    for text in ("measured against aa29841", "issue 7's bounds", "the issue-9 bounds", "see #31", "(issue #12)",
                 "the loss no longer saw it", "the step fell from 0.1 to 0.08 s"):
        assert _HISTORY.search(text), text
    for text in ("a 2-core CPU", "0.7071067811865476e-01", "16x16 grid", "seed 1234567", "float32", "deadbeef-like"):
        assert not _HISTORY.search(text), text


def test_the_guide_to_your_own_problem_shows_a_valid_spec():
    """The spec in docs/your-own-problem.md loads, builds and has the suite's geometry."""
    from ginn.problems import load_spec
    from ginn.problems.loader import parse_spec

    text = (ROOT / "docs" / "your-own-problem.md").read_text()
    block = text.split("```yaml\n", 1)[1].split("```", 1)[0]
    spec = parse_spec(block)
    p, ref = spec.build(), load_spec(ROOT / "benchmarks" / "suite" / "l-bracket-2d.yaml").build()
    assert p.n_interface_components == ref.n_interface_components == 3 and p.unit_scale == ref.unit_scale == 10.0
    assert spec.config().latents.n_shapes == 4 and p.tolerances.interface * p.unit_scale == 0.05
