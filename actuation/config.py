"""Actuation's section (`actuation:`) of the one validated config. Every default lives here.

Units are in the names. The Kobuki's own geometry (wheel base, ticks per metre) is a protocol
fact in `kobuki_geometry`, not a setting.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from actuation.kobuki_geometry import MAX_ANGULAR_RAD_S, MAX_LINEAR_M_S


class SimBaseConfig(BaseModel):
    """`actuation.sim`: the simulated base's dynamics (SimBase)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    #: acceleration limit while following a non-zero command (reference velocity smoother)
    accel_linear_m_s2: float = Field(default=0.3, gt=0.0, le=10.0)
    accel_angular_rad_s2: float = Field(default=3.5, gt=0.0, le=50.0)
    #: deceleration limit on a commanded stop: the real base stops hard on a zero command
    brake_linear_m_s2: float = Field(default=1.5, gt=0.0, le=20.0)
    brake_angular_rad_s2: float = Field(default=10.0, gt=0.0, le=100.0)
    #: the battery voltage the simulated base reports
    battery_v: float = Field(default=16.5, gt=0.0, le=20.0)
    #: longest integration step while a velocity ramps (constant velocity is integrated exactly)
    integration_step_s: float = Field(default=0.005, gt=0.0, le=0.05)


class ActuationConfig(BaseModel):
    """`actuation:` the real base's link and dead-man, the velocity limits, the simulated base."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    #: serial port or pyserial URL; null: /dev/kobuki, then /dev/ttyUSB0
    port: str | None = None
    #: base-control packets per second the dead-man puts on the wire, changed or not
    command_rate_hz: float = Field(default=50.0, ge=20.0, le=100.0)
    #: silence from the control process after which the dead-man stops the base and disarms
    heartbeat_timeout_s: float = Field(default=0.2, ge=0.02, le=1.0)
    #: how long the dead-man keeps sending stop after the control process is gone, then exits
    orphan_stop_s: float = Field(default=0.5, ge=0.0, le=10.0)
    #: a port that gives no valid feedback packet within this is not a (working) Kobuki
    first_feedback_timeout_s: float = Field(default=1.0, gt=0.0, le=10.0)
    #: feedback older than this makes `link_health().alive` false (the base streams at 50 Hz)
    link_timeout_s: float = Field(default=0.1, gt=0.0, le=5.0)
    #: how long to wait for the dead-man process to start and open the port
    deadman_start_timeout_s: float = Field(default=10.0, gt=0.0, le=60.0)
    #: how long close() waits for the dead-man to send stop and exit before killing it
    close_timeout_s: float = Field(default=2.0, gt=0.0, le=30.0)
    #: a serial write blocked this long means the link is gone
    write_timeout_s: float = Field(default=0.5, gt=0.0, le=5.0)
    #: command limits (the Kobuki's: 0.7 m/s, 180 °/s); larger commands are scaled down
    max_linear_m_s: float = Field(default=MAX_LINEAR_M_S, gt=0.0, le=MAX_LINEAR_M_S)
    max_angular_rad_s: float = Field(default=MAX_ANGULAR_RAD_S, gt=0.0, le=MAX_ANGULAR_RAD_S)
    sim: SimBaseConfig = SimBaseConfig()

    @property
    def command_period_s(self) -> float:
        return 1.0 / self.command_rate_hz

