"""SimBase: a simulated Kobuki with the same interface as the real one, advancing on injected time.

Differential-drive kinematics with the Kobuki's wheel base, speed limits, acceleration limits
(0.3 m/s², 3.5 rad/s² by default) and a harder braking limit on a commanded stop (the real base
stops hard on a zero command). Odometry is the exact path in the start frame. Bumper, cliff and
wheel-drop bits can be injected and stay until cleared; the feedback link can be cut
(`set_link_alive(False)`: feedback freezes, `received_at_s` stops advancing; commands still reach
the simulated motors).

Never reads a clock and never sleeps: time only moves when a caller passes a later `now`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lanewarden.actuation.base import STOP, BaseFeedback, Pose2D, VelocityCommand
from lanewarden.actuation.config import ActuationConfig
from lanewarden.actuation.errors import ActuationError
from lanewarden.actuation.kobuki_geometry import (
    MAX_ANGULAR_RAD_S,
    MAX_LINEAR_M_S,
    WHEEL_BASE_M,
    integrate_arc,
    limit_command,
    require_finite,
    wrap_angle,
)


@dataclass(frozen=True)
class SimBaseParams:
    """Everything SimBase needs. Defaults are the Kobuki's; `from_config` reads `actuation:`."""

    wheel_base_m: float = WHEEL_BASE_M
    max_linear_m_s: float = MAX_LINEAR_M_S
    max_angular_rad_s: float = MAX_ANGULAR_RAD_S
    accel_linear_m_s2: float = 0.3
    accel_angular_rad_s2: float = 3.5
    brake_linear_m_s2: float = 1.5
    brake_angular_rad_s2: float = 10.0
    battery_v: float = 16.5
    integration_step_s: float = 0.005

    @classmethod
    def from_config(cls, config: ActuationConfig) -> SimBaseParams:
        sim = config.sim
        return cls(max_linear_m_s=config.max_linear_m_s,
                   max_angular_rad_s=config.max_angular_rad_s,
                   accel_linear_m_s2=sim.accel_linear_m_s2,
                   accel_angular_rad_s2=sim.accel_angular_rad_s2,
                   brake_linear_m_s2=sim.brake_linear_m_s2,
                   brake_angular_rad_s2=sim.brake_angular_rad_s2,
                   battery_v=sim.battery_v,
                   integration_step_s=sim.integration_step_s)


ORIGIN = Pose2D()


def _approach(value: float, target: float, max_step: float) -> float:
    if value < target:
        return min(target, value + max_step)
    return max(target, value - max_step)


def _check_bits(name: str, value: int, mask: int) -> int:
    if not isinstance(value, int) or value & ~mask:
        raise ValueError(f"{name} = {value!r}: expected bits within {mask:#x}")
    return value


class SimBase:
    """A simulated Kobuki. The first call with a `now` sets the time origin."""

    def __init__(self, pose: Pose2D = ORIGIN, params: SimBaseParams | None = None) -> None:
        self._params = params or SimBaseParams()
        self._start = pose
        self._x, self._y, self._theta = pose.x_m, pose.y_m, pose.theta_rad
        self._linear = 0.0
        self._angular = 0.0
        self._commanded = STOP
        self._time_s: float | None = None
        self._bumper = 0
        self._cliff = 0
        self._wheel_drop = 0
        self._link_alive = True
        self._last_feedback = BaseFeedback(battery_v=self._params.battery_v)
        self._closed = False

    # ---- the Base interface -------------------------------------------------------------------
    def send(self, command: VelocityCommand, now: float) -> None:
        """Integrate up to `now` under the old command, then execute `command` (within limits)."""
        if self._closed:
            raise ActuationError("simulated base: closed")
        self.advance_to(now)
        try:
            require_finite(command)
        except ActuationError:
            self._commanded = STOP
            raise
        self._commanded = limit_command(command, self._params.max_linear_m_s,
                                        self._params.max_angular_rad_s)

    def feedback(self, now: float) -> BaseFeedback:
        self.advance_to(now)
        if self._link_alive:
            self._last_feedback = BaseFeedback(
                received_at_s=now, bumper=self._bumper, wheel_drop=self._wheel_drop,
                cliff=self._cliff, buttons=0, battery_v=self._params.battery_v,
                odometry=self.odometry)
        return self._last_feedback

    def close(self) -> None:
        """Command stop (the base brakes as time advances). Idempotent."""
        self._commanded = STOP
        self._closed = True

    # ---- simulation API -----------------------------------------------------------------------
    def advance_to(self, now: float) -> None:
        """Integrate the motion from the last advance time to `now` (no-op the first time)."""
        if self._time_s is None:
            self._time_s = now
            return
        if now < self._time_s:
            raise ActuationError(
                f"simulated base: time went backwards ({now!r} s < {self._time_s!r} s)")
        remaining = now - self._time_s
        while remaining > 0.0:
            remaining -= self._step(remaining)
        self._time_s = now

    def inject(self, bumper: int = 0, cliff: int = 0, wheel_drop: int = 0) -> None:
        """Set the bumper/cliff/wheel-drop bits (BaseFeedback layout); sticky until changed."""
        self._bumper = _check_bits("bumper", bumper, 0b111)
        self._cliff = _check_bits("cliff", cliff, 0b111)
        self._wheel_drop = _check_bits("wheel_drop", wheel_drop, 0b11)

    def set_link_alive(self, alive: bool) -> None:
        self._link_alive = alive

    @property
    def pose(self) -> Pose2D:
        """Ground truth in the world frame (theta in (-π, π])."""
        return Pose2D(self._x, self._y, wrap_angle(self._theta))

    @property
    def velocity(self) -> VelocityCommand:
        """The actual body velocity (after speed and acceleration limits)."""
        return VelocityCommand(self._linear, self._angular)

    @property
    def commanded(self) -> VelocityCommand:
        """The command being executed (after the speed limits), STOP after close()."""
        return self._commanded

    @property
    def odometry(self) -> Pose2D:
        """The path since the start pose, in the start frame (what the encoders would say)."""
        dx, dy = self._x - self._start.x_m, self._y - self._start.y_m
        cos0, sin0 = math.cos(self._start.theta_rad), math.sin(self._start.theta_rad)
        return Pose2D(cos0 * dx + sin0 * dy, -sin0 * dx + cos0 * dy,
                      wrap_angle(self._theta - self._start.theta_rad))

    # ---- integration --------------------------------------------------------------------------
    def _step(self, remaining_s: float) -> float:
        """Advance by at most `remaining_s`; return the time actually integrated."""
        target = self._commanded
        if self._linear == target.linear_m_s and self._angular == target.angular_rad_s:
            self._x, self._y, self._theta = integrate_arc(
                self._x, self._y, self._theta, self._linear, self._angular, remaining_s)
            return remaining_s
        params = self._params
        braking = target.is_stop
        linear_rate = params.brake_linear_m_s2 if braking else params.accel_linear_m_s2
        angular_rate = params.brake_angular_rad_s2 if braking else params.accel_angular_rad_s2
        # end the step where a ramp reaches its target, so the mean velocity is exact
        dt = min(remaining_s, params.integration_step_s)
        for value, goal, rate in ((self._linear, target.linear_m_s, linear_rate),
                                  (self._angular, target.angular_rad_s, angular_rate)):
            if value != goal:
                dt = min(dt, abs(goal - value) / rate)
        linear = _approach(self._linear, target.linear_m_s, linear_rate * dt)
        angular = _approach(self._angular, target.angular_rad_s, angular_rate * dt)
        self._x, self._y, self._theta = integrate_arc(
            self._x, self._y, self._theta, 0.5 * (self._linear + linear),
            0.5 * (self._angular + angular), dt)
        self._linear, self._angular = linear, angular
        return dt
