"""The interface every base (real Kobuki, simulated) offers the supervisor, and its data types.

A `VelocityCommand` is the only thing that moves a robot. `STOP` is the default everywhere.
Time is injected: `now` is seconds on the caller's clock (monotonic on a robot, fake in a sim).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol


@dataclass(frozen=True)
class VelocityCommand:
    """Body-frame velocity: linear m/s (forward +), angular rad/s (left/CCW +)."""

    linear_m_s: float = 0.0
    angular_rad_s: float = 0.0

    @property
    def is_stop(self) -> bool:
        return self.linear_m_s == 0.0 and self.angular_rad_s == 0.0


STOP = VelocityCommand(0.0, 0.0)


@dataclass(frozen=True)
class Pose2D:
    """Planar pose: x, y in metres, theta in radians (CCW from the x axis)."""

    x_m: float = 0.0
    y_m: float = 0.0
    theta_rad: float = 0.0


@dataclass(frozen=True)
class BaseFeedback:
    """The latest state of the base, as the supervisor sees it.

    `received_at_s` is the clock time of the newest valid feedback (None: nothing received yet);
    the supervisor's watchdog turns its age into a link-lost fault. Bit fields follow the Kobuki
    protocol: bumper 1 right / 2 centre / 4 left; wheel_drop 1 right / 2 left; cliff 1 right /
    2 centre / 4 left. `stop_latched`: the base's own safety monitor (the Kobuki's dead-man) has
    latched a stop and refuses motion until the operator resumes: why, one line (None: it has
    not; a base without such a monitor never has).
    """

    received_at_s: float | None = None
    bumper: int = 0
    wheel_drop: int = 0
    cliff: int = 0
    buttons: int = 0
    battery_v: float | None = None
    odometry: Pose2D = Pose2D()
    stop_latched: str | None = None


class Base(Protocol):
    """What the supervisor's control loop drives. Implemented by SimBase and KobukiBase."""

    def send(self, command: VelocityCommand, now: float) -> None:
        """Set the command the base executes from `now` on (held until the next send)."""

    def feedback(self, now: float) -> BaseFeedback:
        """The newest feedback available at `now`."""

    def close(self) -> None:
        """Stop the robot and release the base. Idempotent."""
