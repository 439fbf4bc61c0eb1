"""The supervisor's config section: defaults are consistent, bad combinations are refused by key,
and the settings it shares with other sections agree with them (one line per conflict)."""

from __future__ import annotations

from pathlib import Path

import pytest

from lanewarden.config import load_config
from lanewarden.errors import ConfigError
from lanewarden.supervisor.config import SupervisorConfig


def test_defaults_are_valid_and_match_the_requirements() -> None:
    c = SupervisorConfig()
    assert c.turn_enter_slope_sum == 6.0 and c.turn_exit_slope_sum < 6.0
    assert c.frame_stale_s + c.camera_period_s <= 0.2  # frames stop -> HALT within 200 ms
    assert c.lane_lost_halt_s + c.camera_period_s <= 0.3  # lane leaves view -> HALT within 0.3 s
    assert c.max_linear_accel_m_s2 == 0.3 and c.max_angular_accel_rad_s2 == 3.5
    assert c.auto_resume_after_lane_loss is False


def test_every_timing_and_threshold_has_its_unit_or_kind_in_its_name() -> None:
    suffixes = ("_s", "_m", "_m_s", "_rad_s", "_m_s2", "_rad_s2", "_frames", "_count", "_per_s",
                "_per_s2", "_std", "_sigma", "_fraction", "_slope_sum", "_min", "_below", "_floor",
                "_threshold", "_v", "_deg")  # fmt: skip
    for name, field in SupervisorConfig.model_fields.items():
        if field.annotation is bool:
            continue
        assert name.endswith(suffixes), name


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"turn_exit_slope_sum": 7.0}, "turn_exit_slope_sum"),
        ({"confidence_usable_min": 0.9}, "confidence_usable_min"),
        ({"frame_late_s": 0.3}, "frame_late_s"),
        ({"base_feedback_late_s": 0.5}, "base_feedback_late_s"),
        ({"follow_speed_m_s": 0.5}, "follow_speed_m_s"),
        ({"degraded_max_angular_rad_s": 2.0}, "degraded_max_angular_rad_s"),
        ({"loop_overrun_s": 0.01}, "loop_overrun_s"),
        ({"engage_window_frames": 9}, "supervisor.engage_window_frames = 9: must be 0 or at "
                                      "least engage_confident_frames (10)"),
        ({"recover_window_frames": 4}, "supervisor.recover_window_frames = 4: must be 0 or at "
                                       "least recover_confident_frames (5)"),
    ],
)
def test_inconsistent_values_are_refused_naming_the_keys(
    tmp_path: Path, overrides: dict[str, float], message: str
) -> None:
    path = tmp_path / "bad.yaml"
    lines = "\n".join(f"  {k}: {v}" for k, v in overrides.items())
    path.write_text(f"supervisor:\n{lines}\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert message in str(err.value) and str(path) in str(err.value)


def test_values_of_one_section_that_disagree_are_one_line_each_at_their_key(
        tmp_path: Path) -> None:
    """Three disagreements in `supervisor:` had been one line, `supervisor = a mapping: ...; ...;
    ...`, a new user found."""
    path = tmp_path / "bad.yaml"
    path.write_text("supervisor: {follow_speed_m_s: 0.5, turn_speed_m_s: 0.6, frame_late_s: 0.9}\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(err.value).splitlines() == [
        f"{path}: supervisor.frame_late_s = 0.9: must be below frame_stale_s (0.15)",
        f"{path}: supervisor.follow_speed_m_s = 0.5: must not exceed limiter_max_linear_m_s (0.3)",
        f"{path}: supervisor.turn_speed_m_s = 0.6: must not exceed limiter_max_linear_m_s (0.3)",
    ]


def test_sections_that_disagree_are_refused_one_line_per_conflict(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(
        "supervisor:\n  limiter_max_linear_m_s: 0.3\n  limiter_max_angular_rad_s: 2.0\n"
        "  camera_period_s: 0.05\n"
        "actuation:\n  max_linear_m_s: 0.25\n  max_angular_rad_s: 1.5\n"
        "perception:\n  edges: {max_abs_slope: 2.5}\n"
    )
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(err.value).splitlines() == [
        f"{path}: supervisor.limiter_max_linear_m_s = 0.3: must not exceed "
        "actuation.max_linear_m_s (0.25 m/s), the base's own limit",
        f"{path}: supervisor.limiter_max_angular_rad_s = 2.0: must not exceed "
        "actuation.max_angular_rad_s (1.5 rad/s), the base's own limit",
        f"{path}: supervisor.camera_period_s = 0.05: must be 1 / simulation.camera_rate_hz "
        "(30 Hz, 0.0333333 s): the simulated camera is the robot's",
        f"{path}: supervisor.turn_enter_slope_sum = 6.0: must be below twice "
        "perception.edges.max_abs_slope (2.5): two clamped slopes could never reach it",
    ]


def test_a_lane_the_robot_does_not_fit_in_is_refused(tmp_path: Path) -> None:
    """19 mm tapes 0.3 m apart (the README's survey example once): 0.281 m between the tapes'
    inner edges, where a Kobuki centred in the lane is 0.195 m from each (its footprint and a
    margin, the departure clearance): every frame would halt it. A narrower robot's clearance
    fits it; 0.5 m apart fits a Kobuki."""
    path = tmp_path / "robot.yaml"
    path.write_text("perception:\n  tape: {width_m: 0.019}\n  lane: {width_m: 0.3}\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(err.value) == (
        f"{path}: perception.lane.width_m = 0.3: leaves 0.281 m between the tapes' inner edges, "
        "less than twice supervisor.lane_departure_clearance_m (0.195 m: the robot's half-width "
        "and a margin): centred in this lane the robot would already be leaving it, and every "
        "frame would halt it; expected the lane's true width (a Kobuki needs its tapes' inner "
        "edges 0.39 m apart or more), or a smaller clearance for a narrower robot")
    path.write_text("perception:\n  tape: {width_m: 0.019}\n  lane: {width_m: 0.3}\n"
                    "supervisor: {lane_departure_clearance_m: 0.14}\n")
    assert load_config(path).perception.lane.width_m == 0.3
    path.write_text("perception:\n  tape: {width_m: 0.019}\n  lane: {width_m: 0.5}\n")
    assert load_config(path).perception.lane.width_m == 0.5


def test_agreeing_sections_load_and_the_shared_quantities_have_one_home(tmp_path: Path) -> None:
    path = tmp_path / "ok.yaml"
    path.write_text("supervisor:\n  camera_period_s: 0.05\nsimulation:\n  camera_rate_hz: 20\n")
    assert load_config(path).supervisor.camera_period_s == 0.05
    keys = set(SupervisorConfig.model_fields)
    assert {"turn_enter_slope_sum", "confidence_usable_min", "limiter_max_linear_m_s"} <= keys
    assert not keys & {"lecture_slope_sum_threshold", "max_linear_m_s", "max_angular_rad_s"}


def test_unknown_and_mistyped_keys_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("supervisor:\n  follow_speed: 0.2\n  frame_stale_s: soon\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    text = str(err.value)
    assert "supervisor.follow_speed" in text and "supervisor.frame_stale_s = 'soon'" in text
    assert len(text.splitlines()) == 2


def test_docs_list_every_key_with_its_default() -> None:
    doc = (Path(__file__).resolve().parents[2] / "docs" / "supervisor.md").read_text()
    rows = {
        line.split("|")[1].strip().strip("`"): line.split("|")[2].strip()
        for line in doc.splitlines()
        if line.startswith("| `")
    }
    for name, field in SupervisorConfig.model_fields.items():
        assert name in rows, f"docs/supervisor.md: config key {name} is not documented"
        default = field.default
        shown = str(default).lower() if isinstance(default, bool) else str(round(default, 6))
        assert rows[name] == shown, f"docs/supervisor.md: {name} default {rows[name]} != {shown}"
