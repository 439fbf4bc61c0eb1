"""The `actuation:` config section: defaults, units, and one-line errors for bad values."""

from __future__ import annotations

from pathlib import Path

import pytest

from lanewarden.config import LanewardenConfig, load_config
from lanewarden.errors import ConfigError


def test_defaults() -> None:
    actuation = LanewardenConfig().actuation
    assert actuation.port is None
    assert actuation.command_rate_hz == 50.0 and actuation.command_period_s == 0.02
    assert actuation.heartbeat_timeout_s == 0.2
    assert actuation.first_feedback_timeout_s == 1.0
    assert (actuation.max_linear_m_s, round(actuation.max_angular_rad_s, 4)) == (0.7, 3.1416)
    assert (actuation.sim.accel_linear_m_s2, actuation.sim.brake_linear_m_s2) == (0.3, 1.5)


def test_values_load_from_yaml(tmp_path: Path) -> None:
    path = tmp_path / "robot.yaml"
    path.write_text("actuation:\n  port: /dev/ttyUSB1\n  heartbeat_timeout_s: 0.1\n"
                    "  sim:\n    brake_linear_m_s2: 2.0\n")
    actuation = load_config(path).actuation
    assert (actuation.port, actuation.heartbeat_timeout_s, actuation.sim.brake_linear_m_s2) == (
        "/dev/ttyUSB1", 0.1, 2.0)


@pytest.mark.parametrize(("text", "key"), [
    ("actuation:\n  command_rate_hz: 5\n", "actuation.command_rate_hz"),
    ("actuation:\n  max_linear_m_s: 2.0\n", "actuation.max_linear_m_s"),
    ("actuation:\n  heartbeat_timeout_s: 0\n", "actuation.heartbeat_timeout_s"),
    ("actuation:\n  sim:\n    brake_linear_m_s2: -1\n", "actuation.sim.brake_linear_m_s2"),
    ("actuation:\n  heartbeat_timeout: 0.2\n", "actuation.heartbeat_timeout"),
])
def test_bad_values_name_the_key(tmp_path: Path, text: str, key: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert key in str(info.value) and len(str(info.value).splitlines()) == 1


def test_the_deadmans_envelope_defaults_and_holds_the_gates_ramps(tmp_path: Path) -> None:
    actuation = LanewardenConfig().actuation
    assert (actuation.feedback_timeout_s, actuation.max_linear_accel_m_s2,
            actuation.max_angular_accel_rad_s2) == (0.2, 1.0, 10.0)
    path = tmp_path / "bad.yaml"
    path.write_text("supervisor:\n  max_linear_accel_m_s2: 0.5\n  max_angular_accel_rad_s2: 4.0\n"
                    "actuation:\n  max_linear_accel_m_s2: 0.4\n  max_angular_accel_rad_s2: 3.0\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(err.value).splitlines() == [
        f"{path}: supervisor.max_linear_accel_m_s2 = 0.5: must not exceed "
        "actuation.max_linear_accel_m_s2 (0.4 m/s^2), the dead-man's envelope",
        f"{path}: supervisor.max_angular_accel_rad_s2 = 4.0: must not exceed "
        "actuation.max_angular_accel_rad_s2 (3 rad/s^2), the dead-man's envelope",
    ]
