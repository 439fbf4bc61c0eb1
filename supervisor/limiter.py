"""Command limiter: speed caps and acceleration limits that never delay a stop.

Each axis (linear m/s, angular rad/s) is clipped to its maximum, and only INCREASES of magnitude are
rate-limited (like the Kobuki velocity smoother). Anything that brings an axis towards zero passes
at once: a stop, a HALT or a slow-down is never ramped. A reversal goes through zero at once and
then ramps up. A non-finite command is treated as malformed and becomes a stop. `dt` is injected,
and a late step (longer than `CommandLimits.max_step_s`) does not buy a bigger jump.

Used by the SafetyGate only (supervisor/gate.py): controllers never limit their own commands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.actuation.kobuki_geometry import ramp_axis
from lanewarden.supervisor.config import SupervisorConfig


@dataclass(frozen=True)
class CommandLimits:
    """Caps (m/s, rad/s), ramps for increases (m/s^2, rad/s^2) and the longest step credited (s)."""

    max_linear_m_s: float
    max_angular_rad_s: float
    linear_accel_m_s2: float
    angular_accel_rad_s2: float
    max_step_s: float

    @classmethod
    def for_driving(cls, config: SupervisorConfig) -> CommandLimits:
        """What a controller's commands may reach: the supervisor's limiter settings."""
        return cls(
            max_linear_m_s=config.limiter_max_linear_m_s,
            max_angular_rad_s=config.limiter_max_angular_rad_s,
            linear_accel_m_s2=config.max_linear_accel_m_s2,
            angular_accel_rad_s2=config.max_angular_accel_rad_s2,
            max_step_s=config.loop_overrun_s,
        )

    @classmethod
    def for_bring_up(
        cls, config: SupervisorConfig, max_linear_m_s: float, max_angular_rad_s: float
    ) -> CommandLimits:
        """`base drive`: the base's own speed limits (its flags are checked against them), with
        the supervisor's ramps."""
        return cls(
            max_linear_m_s=max_linear_m_s,
            max_angular_rad_s=max_angular_rad_s,
            linear_accel_m_s2=config.max_linear_accel_m_s2,
            angular_accel_rad_s2=config.max_angular_accel_rad_s2,
            max_step_s=config.loop_overrun_s,
        )


class CommandLimiter:
    def __init__(self, limits: CommandLimits) -> None:
        self.limits = limits
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
        lim = self.limits
        dt = min(max(0.0, dt), lim.max_step_s) if math.isfinite(dt) else 0.0
        linear = ramp_axis(
            self._last.linear_m_s, command.linear_m_s, lim.max_linear_m_s,
            lim.linear_accel_m_s2 * dt,
        )  # fmt: skip
        angular = ramp_axis(
            self._last.angular_rad_s, command.angular_rad_s, lim.max_angular_rad_s,
            lim.angular_accel_rad_s2 * dt,
        )  # fmt: skip
        self._last = VelocityCommand(linear, angular)
        return self._last
