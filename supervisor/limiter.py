"""Command limiter: speed caps and acceleration limits that never delay a stop.

Each axis (linear m/s, angular rad/s) is clipped to its maximum, and only INCREASES of magnitude are
rate-limited (`max_linear_accel_m_s2`, `max_angular_accel_rad_s2`, like the Kobuki velocity
smoother). Anything that brings an axis towards zero passes at once: a stop, a HALT or a slow-down
is never ramped. A reversal goes through zero at once and then ramps up. A non-finite command is
treated as malformed and becomes a stop. `dt` is injected.
"""

from __future__ import annotations

import math

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.supervisor.config import SupervisorConfig


def _limit_axis(current: float, target: float, max_abs: float, max_step: float) -> float:
    target = max(-max_abs, min(max_abs, target))
    base = current if current * target > 0.0 else 0.0
    if abs(target) <= abs(base):
        return target
    step = min(abs(target) - abs(base), max_step)
    return base + math.copysign(step, target)


class CommandLimiter:
    def __init__(self, config: SupervisorConfig) -> None:
        self._config = config
        self._last = STOP

    @property
    def last(self) -> VelocityCommand:
        """The last command that left the limiter."""
        return self._last

    def stop(self) -> VelocityCommand:
        """Zero, at once, and forget the ramp."""
        self._last = STOP
        return STOP

    def limit(self, command: VelocityCommand, dt: float) -> VelocityCommand:
        """The command to send, `dt` seconds after the previous one."""
        if command.is_stop or not (
            math.isfinite(command.linear_m_s) and math.isfinite(command.angular_rad_s)
        ):
            return self.stop()
        cfg = self._config
        dt = max(0.0, dt) if math.isfinite(dt) else 0.0
        linear = _limit_axis(
            self._last.linear_m_s,
            command.linear_m_s,
            cfg.max_linear_m_s,
            cfg.max_linear_accel_m_s2 * dt,
        )
        angular = _limit_axis(
            self._last.angular_rad_s, command.angular_rad_s, cfg.max_angular_rad_s,
            cfg.max_angular_accel_rad_s2 * dt,
        )  # fmt: skip
        self._last = VelocityCommand(linear, angular)
        return self._last
