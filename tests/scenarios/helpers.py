"""Small scenario specs built in code for the simulator's tests."""

from __future__ import annotations

from typing import Any

from lanewarden.scenarios.spec import ScenarioSpec, parse_scenario


def spec_from(data: dict[str, Any]) -> ScenarioSpec:
    data = {"name": "test", **data}
    return parse_scenario(data, "test.yaml")


def straight_spec(length_m: float = 4.0, **extra: Any) -> ScenarioSpec:
    return spec_from({"lane": {"segments": [{"straight_m": length_m}], **extra}})
