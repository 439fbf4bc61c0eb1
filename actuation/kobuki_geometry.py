"""The Kobuki's physical constants and the velocity limits every base applies to a command.

Numbers are protocol facts (../shared/docs/kobuki-protocol.md). This module never touches a port
or a clock: it is shared by the codec, the odometry, the real driver and the simulated base.
"""

from __future__ import annotations

import math

from lanewarden.actuation.base import VelocityCommand
from lanewarden.actuation.errors import ActuationError

#: Distance between the two wheels' contact points (the reference driver's "bias").
WHEEL_BASE_M = 0.230
WHEEL_RADIUS_M = 0.035
TICKS_PER_REVOLUTION = 2578.33
#: Encoder ticks per metre of wheel travel: 2578.33 / (2π · 0.035) ≈ 11724.4.
TICKS_PER_METRE = TICKS_PER_REVOLUTION / (2.0 * math.pi * WHEEL_RADIUS_M)
MAX_LINEAR_M_S = 0.7
MAX_ANGULAR_RAD_S = math.radians(180.0)


def require_finite(command: VelocityCommand) -> VelocityCommand:
    """Return `command` unchanged, or raise ActuationError naming the non-finite component."""
    for name, value in (("linear_m_s", command.linear_m_s),
                        ("angular_rad_s", command.angular_rad_s)):
        if not math.isfinite(value):
            raise ActuationError(
                f"velocity command {name} = {value!r}: expected a finite number (sent stop instead)"
            )
    return command


def limit_command(command: VelocityCommand, max_linear_m_s: float,
                  max_angular_rad_s: float) -> VelocityCommand:
    """Scale a finite command down so both components are within the limits.

    Both components are scaled by the same factor, so the commanded curvature (the path) is kept;
    only the speed along it drops. A command already within the limits is returned unchanged.
    """
    scale = 1.0
    if abs(command.linear_m_s) > max_linear_m_s:
        scale = min(scale, max_linear_m_s / abs(command.linear_m_s))
    if abs(command.angular_rad_s) > max_angular_rad_s:
        scale = min(scale, max_angular_rad_s / abs(command.angular_rad_s))
    if scale == 1.0:
        return command
    return VelocityCommand(command.linear_m_s * scale, command.angular_rad_s * scale)


def ramp_axis(current: float, target: float, max_abs: float, max_step: float) -> float:
    """One axis of a velocity moved from `current` towards `target`: clipped to +-`max_abs`, an
    increase of magnitude limited to `max_step`, anything towards zero (a stop, a slow-down)
    passed at once; a reversal goes through zero at once and then ramps up."""
    target = max(-max_abs, min(max_abs, target))
    base = current if current * target > 0.0 else 0.0
    if abs(target) - abs(base) <= max_step:  # a decrease, or the last step up: exactly there
        return target
    return base + math.copysign(max_step, target)


def wrap_angle(theta_rad: float) -> float:
    """The same angle in (-π, π]."""
    wrapped = math.remainder(theta_rad, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def integrate_arc(x_m: float, y_m: float, theta_rad: float, linear_m_s: float,
                  angular_rad_s: float, dt_s: float) -> tuple[float, float, float]:
    """Exact pose after driving a constant (v, ω) for dt: a straight line or a circular arc.

    Returns (x, y, theta) with theta NOT wrapped (callers wrap when they publish a pose).
    """
    dtheta = angular_rad_s * dt_s
    if abs(dtheta) < 1e-9:
        # straight (or nearly): the midpoint heading is exact to second order
        mid = theta_rad + 0.5 * dtheta
        distance = linear_m_s * dt_s
        return x_m + distance * math.cos(mid), y_m + distance * math.sin(mid), theta_rad + dtheta
    radius = linear_m_s / angular_rad_s
    new_theta = theta_rad + dtheta
    return (x_m + radius * (math.sin(new_theta) - math.sin(theta_rad)),
            y_m - radius * (math.cos(new_theta) - math.cos(theta_rad)),
            new_theta)
