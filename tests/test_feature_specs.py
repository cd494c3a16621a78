"""The specs of the feature benchmarks (``benchmarks/feature``) are valid, and the manufacturing
bracket is the built-in bracket's geometry with the tolerances it adds."""

from pathlib import Path

import pytest

from ginn.problems import get_spec, load_spec

FEATURE = Path(__file__).resolve().parents[1] / "benchmarks" / "feature"


@pytest.mark.parametrize("path", sorted(FEATURE.glob("*.yaml")), ids=lambda p: p.stem)
def test_feature_spec_builds(path):
    problem = load_spec(path).build()
    assert problem.tolerances != type(problem.tolerances)()  # each states a tolerance beyond the defaults


def test_bracket_make_is_the_bracket_with_manufacturing_tolerances():
    make, plain = load_spec(FEATURE / "bracket-make.yaml"), get_spec("bracket")
    assert make.geometry == plain.geometry
    assert make.defaults["latents"] == plain.defaults["latents"]
    t = make.build().tolerances
    assert t.min_thickness.size == 0.02 and t.overhang.angle == 45 and t.volume_fraction.max == 0.3
    assert t.interface == plain.tolerances.interface and t.volume_outside == plain.tolerances.volume_outside
