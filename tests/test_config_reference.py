"""docs/configuration.md is generated from the config models and every key is documented."""

from __future__ import annotations

from lanewarden.config import LanewardenConfig
from lanewarden.config_reference import config_keys, render_reference
from tests.conftest import PROJECT_ROOT

REFERENCE = PROJECT_ROOT / "docs" / "configuration.md"


def test_every_config_key_has_a_description() -> None:
    missing = [key for key, _, text in config_keys(LanewardenConfig()) if not text]
    assert missing == [], f"config keys without Field(description=...): {missing}"


def test_configuration_reference_is_current() -> None:
    expected = render_reference()
    assert REFERENCE.exists(), "run: python -m lanewarden.config_reference > docs/configuration.md"
    assert REFERENCE.read_text(encoding="utf-8") == expected, (
        "docs/configuration.md is stale; regenerate it with "
        "`python -m lanewarden.config_reference > docs/configuration.md`"
    )
