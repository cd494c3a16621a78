"""Run configuration: the retired settings."""

import pytest

from ginn.config import build_config, nested
from ginn.errors import ConfigError


def test_retired_settings_load_at_their_inert_value_and_fail_otherwise():
    """An old run's config.yaml names the retired settings at the values that made them do nothing:
    it still loads (and resumes); any other value fails with one line saying what replaced it."""
    from ginn.config import RETIRED

    old = {"losses": {"containment_margin": 0.0}, "sampling": {"band_containment": False, "n_domain": 100},
           "diversity": {"interface_clearance": 0.0, "p": 0.25}}
    cfg = build_config(old)
    assert cfg.sampling.n_domain == 100 and cfg.diversity.p == 0.25
    for key, (inert, _) in RETIRED.items():
        value = 0.05 if inert is not False else True
        with pytest.raises(ConfigError, match=f"^config field '{key}' was retired: ") as e:
            build_config(nested({key: value}))
        assert "\n" not in str(e.value)
