"""The command each state asks for, before the limiter. Pure functions of (state, estimate, config).

Signs (body frame, angular positive = left/counter-clockwise):
- slope sum > 0 means the lane bends left (lecture: > +6 turn left) -> positive angular rate;
- center_offset > 0 means the lane centre lies LEFT of the robot, `center_preview_m` ahead (metres,
  robot frame, see `supervisor.center_offset`) -> turn left -> positive angular rate.
So the proportional steering is
    w = slope_sum_gain * slope_sum + center_offset_gain * center_offset.

FOLLOW: follow speed, proportional steering. TURN_LEFT/TURN_RIGHT: the lecture's thrust decision
as an arc: turn speed, proportional steering plus/minus `turn_extra_angular_rad_s`, withheld in
proportion as the lane centre lies on the outer side of the turn (`turn_extra_fade_m`): a robot
off-centre towards a tape sees that tape steep in the image, which the slope sum reads as a bend
towards it, and the extra would then drive it onto the tape. DEGRADED: a
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


def turn_extra_rad_s(direction: float, center_offset: float | None,
                     config: SupervisorConfig) -> float:
    """The extra turn rate of a turn towards `direction` (+1 left, -1 right): all of
    `turn_extra_angular_rad_s` while the lane centre ahead lies on the turn's side of the robot
    (or straight ahead, or is unknown), none once it lies `turn_extra_fade_m` or more on the
    other side, in proportion between."""
    outside = 0.0 if center_offset is None else max(0.0, -direction * center_offset)
    share = max(0.0, 1.0 - outside / config.turn_extra_fade_m)
    return direction * config.turn_extra_angular_rad_s * share


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
        return VelocityCommand(config.turn_speed_m_s, w + turn_extra_rad_s(1.0, center_offset,
                                                                           config))
    if state is SupervisorState.TURN_RIGHT:
        return VelocityCommand(config.turn_speed_m_s, w + turn_extra_rad_s(-1.0, center_offset,
                                                                           config))
    if state is SupervisorState.DEGRADED:
        return VelocityCommand(
            config.follow_speed_m_s * config.degraded_speed_fraction,
            _clip(w, config.degraded_max_angular_rad_s),
        )
    raise AssertionError(f"no command for state {state!r}")  # pragma: no cover
