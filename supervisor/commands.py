"""The command each state asks for, before the limiter. Pure functions of (state, estimate, config).

Signs (body frame, angular positive = left/counter-clockwise):
- slope sum > 0 means the lane bends left (lecture: > +6 turn left) -> positive angular rate;
- center_offset > 0 means the lane centre lies LEFT of the robot, `center_preview_m` ahead (metres,
  robot frame, see `supervisor.center_offset`) -> turn left -> positive angular rate.
So the proportional steering is
    w = slope_sum_gain * slope_sum + center_offset_gain * center_offset.

FOLLOW: follow speed, proportional steering. TURN_LEFT/TURN_RIGHT: the lecture's thrust decision
as an arc: turn speed, proportional steering plus/minus `turn_extra_angular_rad_s`. DEGRADED: a
fraction of the follow speed, steering clipped to `degraded_max_angular_rad_s`. HALT: zero, always.
"""

from __future__ import annotations

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.state_machine import SupervisorState


def proportional_steering_rad_s(
    slope_sum: float | None, center_offset: float | None, config: SupervisorConfig
) -> float:
    """w from the filtered slope sum (bend feed-forward) and the centre offset (centring:
    metres, lane centre left of the robot +)."""
    w = 0.0
    if slope_sum is not None:
        w += config.slope_sum_gain_rad_s * slope_sum
    if center_offset is not None:
        w += config.center_offset_gain_rad_s_per_m * center_offset
    return w


def _clip(value: float, bound: float) -> float:
    return max(-bound, min(bound, value))


def command_for(
    state: SupervisorState,
    slope_sum: float | None,
    center_offset: float | None,
    config: SupervisorConfig,
) -> VelocityCommand:
    if state is SupervisorState.HALT:
        return STOP
    w = proportional_steering_rad_s(slope_sum, center_offset, config)
    if state is SupervisorState.FOLLOW:
        return VelocityCommand(config.follow_speed_m_s, w)
    if state is SupervisorState.TURN_LEFT:
        return VelocityCommand(config.turn_speed_m_s, w + config.turn_extra_angular_rad_s)
    if state is SupervisorState.TURN_RIGHT:
        return VelocityCommand(config.turn_speed_m_s, w - config.turn_extra_angular_rad_s)
    if state is SupervisorState.DEGRADED:
        return VelocityCommand(
            config.follow_speed_m_s * config.degraded_speed_fraction,
            _clip(w, config.degraded_max_angular_rad_s),
        )
    raise AssertionError(f"no command for state {state!r}")  # pragma: no cover
