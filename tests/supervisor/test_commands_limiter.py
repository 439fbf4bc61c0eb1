"""Commands per state (with their signs) and the limiter that never delays a stop."""

from __future__ import annotations

import math

import pytest

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.supervisor.commands import command_for, proportional_steering_rad_s
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.limiter import CommandLimiter, CommandLimits
from lanewarden.supervisor.state_machine import SupervisorState as S

CONFIG = SupervisorConfig()
LIMITS = CommandLimits.for_driving(CONFIG)
DT = 1.0 / 30.0


def test_signs_bend_left_turns_left_and_lane_centre_left_turns_left() -> None:
    assert proportional_steering_rad_s(3.0, 0.0, CONFIG) > 0.0  # lane bends left -> turn left
    assert proportional_steering_rad_s(-3.0, 0.0, CONFIG) < 0.0
    # Lane centre 5 cm left of the robot (metres, robot frame) -> turn left at 3.6 rad/s per m.
    assert proportional_steering_rad_s(0.0, 0.05, CONFIG) == pytest.approx(0.18)
    assert proportional_steering_rad_s(0.0, -0.05, CONFIG) == pytest.approx(-0.18)
    assert proportional_steering_rad_s(None, None, CONFIG) == 0.0


def test_command_per_state() -> None:
    assert command_for(S.HALT, 5.0, 0.3, CONFIG) == STOP
    follow = command_for(S.FOLLOW, 2.0, 0.1, CONFIG)
    assert follow.linear_m_s == CONFIG.follow_speed_m_s
    assert follow.angular_rad_s == pytest.approx(
        CONFIG.slope_sum_gain_rad_s * 2.0 + CONFIG.center_offset_gain_rad_s_per_m * 0.1
    )
    left = command_for(S.TURN_LEFT, 7.0, 0.0, CONFIG)
    right = command_for(S.TURN_RIGHT, -7.0, 0.0, CONFIG)
    assert left.linear_m_s == right.linear_m_s == CONFIG.turn_speed_m_s
    assert left.angular_rad_s > command_for(S.FOLLOW, 7.0, 0.0, CONFIG).angular_rad_s > 0.0
    assert right.angular_rad_s == pytest.approx(-left.angular_rad_s)
    degraded = command_for(S.DEGRADED, 50.0, 3.0, CONFIG)
    assert degraded.linear_m_s == CONFIG.follow_speed_m_s * CONFIG.degraded_speed_fraction
    assert degraded.angular_rad_s == CONFIG.degraded_max_angular_rad_s  # bounded


def test_limiter_ramps_up_at_the_accel_limits() -> None:
    limiter = CommandLimiter(LIMITS)
    out = limiter.limit(VelocityCommand(0.2, 1.0), DT)
    assert out.linear_m_s == pytest.approx(CONFIG.max_linear_accel_m_s2 * DT)
    assert out.angular_rad_s == pytest.approx(CONFIG.max_angular_accel_rad_s2 * DT)
    for _ in range(40):
        out = limiter.limit(VelocityCommand(0.2, 1.0), DT)
    assert out == VelocityCommand(0.2, 1.0)


def test_limiter_caps_speeds() -> None:
    limiter = CommandLimiter(LIMITS)
    for _ in range(200):
        out = limiter.limit(VelocityCommand(5.0, -9.0), DT)
    assert out == VelocityCommand(CONFIG.limiter_max_linear_m_s, -CONFIG.limiter_max_angular_rad_s)


@pytest.mark.parametrize("how", ["stop", "zero command", "nan command"])
def test_a_stop_is_never_ramped(how: str) -> None:
    limiter = CommandLimiter(LIMITS)
    for _ in range(60):
        limiter.limit(VelocityCommand(0.2, 0.5), DT)
    if how == "stop":
        out = limiter.stop()
    elif how == "zero command":
        out = limiter.limit(STOP, DT)
    else:
        out = limiter.limit(VelocityCommand(math.nan, 0.0), DT)
    assert out == STOP and limiter.last == STOP
    again = limiter.limit(VelocityCommand(0.2, 0.0), DT)  # and it ramps again from zero
    assert again.linear_m_s == pytest.approx(CONFIG.max_linear_accel_m_s2 * DT)


def test_slowing_down_is_immediate_and_reversal_goes_through_zero() -> None:
    limiter = CommandLimiter(LIMITS)
    for _ in range(60):
        limiter.limit(VelocityCommand(0.2, 0.8), DT)
    slow = limiter.limit(VelocityCommand(0.1, 0.2), DT)
    assert slow == VelocityCommand(0.1, 0.2)
    reverse = limiter.limit(VelocityCommand(0.1, -0.8), DT)
    assert reverse.angular_rad_s == pytest.approx(-CONFIG.max_angular_accel_rad_s2 * DT)
