"""Actuation's section (`actuation:`) of the one validated config. Every default lives here.

Units are in the names. The Kobuki's own geometry (wheel base, ticks per metre) is a protocol
fact in `kobuki_geometry`, not a setting.
"""

from __future__ import annotations

from pydantic import ConfigDict, Field

from lanewarden.actuation.kobuki_geometry import MAX_ANGULAR_RAD_S, MAX_LINEAR_M_S
from lanewarden.documents import DocumentModel


class SimBaseConfig(DocumentModel):
    """Dynamics of the simulated base (SimBase): acceleration and braking limits, battery, step."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    accel_linear_m_s2: float = Field(
        default=0.3,
        gt=0.0,
        le=10.0,
        description="Linear acceleration limit while following a non-zero command, m/s^2 "
        "(like the reference velocity smoother)",
    )
    accel_angular_rad_s2: float = Field(
        default=3.5,
        gt=0.0,
        le=50.0,
        description="Angular acceleration limit while following a non-zero command, rad/s^2",
    )
    brake_linear_m_s2: float = Field(
        default=1.5,
        gt=0.0,
        le=20.0,
        description="Linear deceleration on a commanded stop, m/s^2 (the real base stops hard)",
    )
    brake_angular_rad_s2: float = Field(
        default=10.0,
        gt=0.0,
        le=100.0,
        description="Angular deceleration on a commanded stop, rad/s^2",
    )
    battery_v: float = Field(
        default=16.5, gt=0.0, le=20.0, description="Battery voltage the simulated base reports, V"
    )
    integration_step_s: float = Field(
        default=0.005,
        ge=0.0001,
        le=0.05,
        description="Longest integration step while a velocity ramps, s (constant velocity is "
        "integrated exactly; at least 0.1 ms: 1e-9 had made a 20 s scenario take a quarter of "
        "an hour, silent)",
    )


class ActuationConfig(DocumentModel):
    """How commands reach the base: the real Kobuki's serial link and dead-man process, the speed
    limits every command is scaled into, and the simulated base's dynamics.

    Dead-man: a separate process owns the serial port, sends base control at `command_rate_hz`,
    stops the base when the control process falls silent or the base reports a hazard, and keeps
    every command inside the speed and acceleration limits below (see docs/actuation.md).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    port: str | None = Field(
        default=None,
        description="Kobuki serial port or pyserial URL; null tries /dev/kobuki, then /dev/ttyUSB0",
    )
    command_rate_hz: float = Field(
        default=50.0,
        ge=20.0,
        le=100.0,
        description="Base-control packets per second the dead-man sends, changed or not, Hz",
    )
    heartbeat_timeout_s: float = Field(
        default=0.2,
        ge=0.02,
        le=1.0,
        description="Silence from the control process after which the dead-man stops the base "
        "and disarms, s",
    )
    orphan_stop_s: float = Field(
        default=0.5,
        ge=0.0,
        le=10.0,
        description="How long the dead-man keeps sending stop after the control process is gone "
        "before it exits, s",
    )
    feedback_timeout_s: float = Field(
        default=0.2,
        ge=0.05,
        le=1.0,
        description="No feedback packet from the base within this while armed: the dead-man "
        "stops the base and holds the stop until the operator resumes, s",
    )
    first_feedback_timeout_s: float = Field(
        default=1.0,
        gt=0.0,
        le=10.0,
        description="A port with no valid feedback packet within this is refused as not a "
        "(working) Kobuki, s",
    )
    link_timeout_s: float = Field(
        default=0.1,
        gt=0.0,
        le=5.0,
        description="Feedback older than this makes link_health().alive false, s (the base "
        "streams at 50 Hz)",
    )
    deadman_start_timeout_s: float = Field(
        default=10.0,
        gt=0.0,
        le=60.0,
        description="How long to wait for the dead-man process to start and open the port, s",
    )
    close_timeout_s: float = Field(
        default=2.0,
        gt=0.0,
        le=30.0,
        description="How long close() waits for the dead-man to send stop and exit before "
        "killing it, s",
    )
    write_timeout_s: float = Field(
        default=0.5,
        gt=0.0,
        le=5.0,
        description="A serial write blocked this long means the link is lost, s",
    )
    max_linear_m_s: float = Field(
        default=MAX_LINEAR_M_S,
        gt=0.0,
        le=MAX_LINEAR_M_S,
        description="Linear speed limit, m/s (at most the Kobuki's 0.7); larger commands are "
        "scaled down, keeping their curvature (by the driver and again by the dead-man)",
    )
    max_angular_rad_s: float = Field(
        default=MAX_ANGULAR_RAD_S,
        gt=0.0,
        le=MAX_ANGULAR_RAD_S,
        description="Angular speed limit, rad/s (at most the Kobuki's pi, 180 deg/s); larger "
        "commands are scaled down, keeping their curvature (by the driver and again by the "
        "dead-man)",
    )
    max_linear_accel_m_s2: float = Field(
        default=1.0,
        gt=0.0,
        le=5.0,
        description="The dead-man ramps increases of linear speed at most this fast, m/s^2 "
        "(decreases pass at once); at least supervisor.max_linear_accel_m_s2",
    )
    max_angular_accel_rad_s2: float = Field(
        default=10.0,
        gt=0.0,
        le=50.0,
        description="The dead-man ramps increases of angular speed at most this fast, rad/s^2 "
        "(decreases pass at once); at least supervisor.max_angular_accel_rad_s2",
    )
    sim: SimBaseConfig = SimBaseConfig()

    @property
    def command_period_s(self) -> float:
        return 1.0 / self.command_rate_hz

