"""Scenario files: the library validates; bad files fail with one line per key, naming the file."""

from __future__ import annotations

from pathlib import Path

import pytest

from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.library import library_names, library_path, resolve_scenario
from lanewarden.scenarios.spec import load_scenario_file, parse_scenario

REQUIRED = {
    "lecture", "wide-bends", "straight", "s-curve", "dashed", "one-edge-gap", "lane-ends", "glare",
    "dark-tape-on-light", "light-tape-on-dark",
}


def test_library_has_every_named_scenario_and_each_validates() -> None:
    names = library_names()
    assert REQUIRED <= set(names)
    assert any(n.startswith("fault-") for n in names)
    for name in names:
        spec = resolve_scenario(name)
        assert spec.name == name
        assert spec.expect.supervised is not None, f"{name} has no expected outcome"


def test_every_fault_kind_has_a_library_scenario() -> None:
    from typing import get_args

    from lanewarden.scenarios.spec import FaultKind

    kinds = {f.kind for n in library_names() for f in resolve_scenario(n).faults}
    assert kinds == set(get_args(FaultKind))


def test_unknown_scenario_name_lists_the_available_ones() -> None:
    with pytest.raises(ScenarioError) as info:
        resolve_scenario("no-such-scenario")
    message = str(info.value)
    assert "\n" not in message
    assert "no-such-scenario" in message and "lecture" in message and "straight" in message


def test_bad_keys_are_one_line_each_naming_file_and_key(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(
        "name: bad\nlane:\n  segments:\n    - straight_m: -1\n    - arc_radius_m: 1.0\n"
        "  widht_m: 0.6\nfaults:\n  - kind: meteor\n    at_s: 1\n", encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario_file(path)
    lines = str(info.value).splitlines()
    assert all(line.startswith(str(path)) for line in lines)
    joined = "\n".join(lines)
    assert "lane.segments.0.straight_m = -1" in joined
    assert "lane.segments.1" in joined and "turn_deg" in joined
    assert "unknown key 'lane.widht_m'" in joined
    assert "faults.0.kind = 'meteor'" in joined


def test_missing_file_and_bad_yaml(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="scenario file not found"):
        load_scenario_file(tmp_path / "nope.yaml")
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: [unclosed\n", encoding="utf-8")
    with pytest.raises(ScenarioError, match=r"broken.yaml: not valid YAML at line"):
        load_scenario_file(broken)


def test_gap_must_be_ordered_and_library_path_is_packaged() -> None:
    with pytest.raises(ScenarioError, match="to_m .* must be greater than from_m"):
        parse_scenario({"name": "g", "lane": {"segments": [{"straight_m": 2}],
                        "gaps": [{"tape": "left", "from_m": 1.0, "to_m": 0.5}]}}, "g.yaml")
    assert library_path("lecture").is_file()


def test_config_overrides_are_validated_with_the_scenario_named() -> None:
    from lanewarden.config import LanewardenConfig
    from lanewarden.scenarios.spec import with_overrides

    base = LanewardenConfig()
    tuned = with_overrides(base, {"simulation": {"width_px": 320, "height_px": 240}}, "x.yaml")
    assert tuned.simulation.width_px == 320 and tuned.perception == base.perception
    with pytest.raises(ScenarioError, match=r"x.yaml: unknown key 'config.simulation.nope'"):
        with_overrides(base, {"simulation": {"nope": 1}}, "x.yaml")


def test_misspelt_events_and_states_in_an_expectation_are_refused_when_read(
        tmp_path: Path) -> None:
    """A misspelt halt reason, event or state in `expect:` ran the whole simulation and then
    failed the check on it; now the file is refused, one line each, naming the closest name.
    A halt reason's own words (`not engaged`, single-line.yaml) are still accepted."""
    path = tmp_path / "typos.yaml"
    path.write_text(
        "name: typos\nlane:\n  segments:\n    - straight_m: 2\nexpect:\n  supervised:\n"
        "    halt_reason_any_of: [LANE_LOTS, not engaged]\n    events_include: [BUMPR]\n"
        "    states_visited_include: [DEGRADE]\n", encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario_file(path)
    lines = str(info.value).splitlines()
    assert [line.split(" expected one of")[0] for line in lines] == [
        f"{path}: expect.supervised.halt_reason_any_of = ['LANE_LOTS', 'not engaged']: "
        "'LANE_LOTS' is no supervisor event: did you mean LANE_LOST?",
        f"{path}: expect.supervised.states_visited_include = ['DEGRADE']: 'DEGRADE' is no "
        "supervisor state: did you mean DEGRADED?",
        f"{path}: expect.supervised.events_include = ['BUMPR']: 'BUMPR' is no supervisor "
        "event: did you mean BUMPER?",
    ]
    assert lines[1].endswith("expected one of FOLLOW, TURN_LEFT, TURN_RIGHT, DEGRADED, HALT")
