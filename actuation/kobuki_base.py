"""KobukiBase: the real base, driven through the dead-man process that owns its serial port.

`KobukiBase.open(port)` starts the dead-man (`actuation.deadman_link.DeadmanLink`: its own
session, its own watch on it), checks its HELLO (the same protocol and package version as this
process, else one line and nothing moves), waits (bounded) for the port to open and for the first
valid feedback packet, and from then on:
`send()` forwards each command (which is also the dead-man's heartbeat), the feedback the
dead-man forwards is decoded here and stamped with the injected clock, and `close()` stops the
base and reaps the process. The first `send()` arms the dead-man; after the dead-man trips
(this process went quiet for `heartbeat_timeout_s`) the base stays stopped, motion commands are
ignored by it and `send()` raises DeadmanTrippedError, until `rearm()` is called explicitly.
When the dead-man latches a stop of its own (bumper, cliff, wheel drop, stale feedback) the
feedback says so (`BaseFeedback.stop_latched`, the gate's DEADMAN_LATCHED); motion is ignored by
it until `resume()`, the operator's explicit start or resume, finds the hazard cleared.
`hold_stopped()` stops and disarms it on purpose (before this process suspends itself); motion
then raises too until `rearm()`.

Call `send()` at least every `heartbeat_timeout_s` while the robot should move. Never write to
the serial port from here, and never block on the dead-man: a link or process failure (the
dead-man dead or unresponsive included) becomes a one-line KobukiLinkError naming the port.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType

from lanewarden.actuation.base import STOP, BaseFeedback, Pose2D, VelocityCommand
from lanewarden.actuation.config import ActuationConfig
from lanewarden.actuation.deadman_link import DeadmanLink
from lanewarden.actuation.deadman_logic import DeadmanMode
from lanewarden.actuation.deadman_messages import (
    FeedbackReceived,
    Hello,
    check_non_motion,
    version_mismatch,
)
from lanewarden.actuation.errors import ActuationError, DeadmanTrippedError, KobukiLinkError
from lanewarden.actuation.kobuki_commands import (
    ExtraRequest,
    SoundSequence,
    encode_request_extra,
    encode_sound_sequence,
)
from lanewarden.actuation.kobuki_feedback import (
    UDID,
    BasicSensorData,
    ControllerInfo,
    FeedbackPacket,
    Version,
    decode_feedback,
)
from lanewarden.actuation.kobuki_geometry import limit_command, require_finite
from lanewarden.actuation.kobuki_port import NO_FEEDBACK_HINT, resolve_port
from lanewarden.actuation.odometry import EncoderOdometry


@dataclass(frozen=True)
class LinkHealth:
    """The serial link and dead-man as the control process sees them at `now`."""

    port: str
    last_packet_age_s: float | None
    packets: int
    checksum_errors: int
    malformed_subpayloads: int
    deadman_mode: DeadmanMode
    deadman_reason: str
    lost_reason: str | None
    low_latency: bool
    alive: bool
    deadman_priority: str = "unknown"
    deadman_priority_raised: bool = False


class KobukiBase:
    """The real Kobuki behind its dead-man process. Create with `KobukiBase.open(...)`."""

    def __init__(self, port: str, clock: Callable[[], float], config: ActuationConfig) -> None:
        """Starts the dead-man process (use `open`, which also waits until the base streams)."""
        self._port = port
        self._clock = clock
        self._config = config
        self._closed = False
        self._armed = False
        self._held = False
        # everything below is written by the relay thread, under self._cond
        self._packets = 0
        self._checksum_errors = 0
        self._malformed = 0
        self._received_at_s: float | None = None
        self._stamp_ms: int | None = None  # the newest basic packet's own time stamp
        self._latest = FeedbackPacket()
        self._sensors: BasicSensorData | None = None
        self._hardware_version: Version | None = None
        self._firmware_version: Version | None = None
        self._udid: UDID | None = None
        self._controller_info: ControllerInfo | None = None
        self._odometry = EncoderOdometry()
        self._link = DeadmanLink.start(port, config, clock, self._apply_feedback)
        self._cond = self._link.cond

    # ---- opening ------------------------------------------------------------------------------
    @classmethod
    def open(cls, port: str | None = None, *, clock: Callable[[], float] = time.monotonic,
             config: ActuationConfig | None = None, request_versions: bool = True) -> KobukiBase:
        """Start the dead-man on `port` (None: config.port, then /dev/kobuki, /dev/ttyUSB0).

        Returns once the first valid feedback packet arrived. Raises KobukiLinkError (one line
        naming the port and the likely fix) when the port is missing, refused, busy, or silent.
        """
        config = config or ActuationConfig()
        try:
            port = resolve_port(port or config.port)
        except LookupError as exc:
            raise KobukiLinkError(str(exc)) from None
        base = cls(port, clock, config)
        try:
            base._wait_until_streaming(request_versions)
        except BaseException:
            base.close()
            raise
        return base

    def _wait_until_streaming(self, request_versions: bool) -> None:
        config, link = self._config, self._link
        if not link.wait_for(lambda: link.opened or link.open_error is not None or link.gone,
                             config.deadman_start_timeout_s):
            raise KobukiLinkError(f"{self._port}: the dead-man process did not open the port "
                                  f"within {config.deadman_start_timeout_s:g} s")
        with self._cond:  # its HELLO came before anything else it said
            hello, opened = link.hello, link.opened
        if hello is not None and (mismatch := version_mismatch(Hello.ours(), hello)) is not None:
            raise KobukiLinkError(f"{self._port}: the dead-man process is {mismatch}: start "
                                  "both from one installation (reinstall lanewarden, or run the "
                                  "`lanewarden` command of the installation you mean)")
        if hello is None and opened:
            raise KobukiLinkError(f"{self._port}: the dead-man process did not say which version "
                                  "it runs (an older lanewarden?): reinstall lanewarden")
        with self._cond:
            if link.open_error is not None:
                raise KobukiLinkError(link.open_error)
            if not link.opened:
                raise KobukiLinkError(f"{self._port}: the dead-man process exited at start-up "
                                      f"({link.lost or 'no reason given'})")
        if not link.wait_for(lambda: self._packets > 0 or link.lost is not None,
                             config.first_feedback_timeout_s):
            raise KobukiLinkError(
                f"{self._port}: no Kobuki sensor data (valid feedback packet) within "
                f"{config.first_feedback_timeout_s:g} s: {NO_FEEDBACK_HINT}")
        self._raise_if_lost()
        if request_versions:
            self.request_extra(ExtraRequest.HARDWARE_VERSION | ExtraRequest.FIRMWARE_VERSION
                               | ExtraRequest.UDID)

    # ---- the Base interface -------------------------------------------------------------------
    def send(self, command: VelocityCommand, now: float) -> None:
        """Forward `command` (scaled into the limits) to the dead-man; it is also a heartbeat.

        Non-finite components: stop is sent, then ActuationError. A lost link or dead dead-man:
        KobukiLinkError. A motion command while the dead-man is tripped: forwarded (and ignored
        by it), then DeadmanTrippedError. A motion command while the dead-man holds its own
        hazard latch: forwarded and ignored by it, no error (the latch is in the feedback, where
        the gate halts on it). A motion command after `hold_stopped()`: stop is sent instead, then
        DeadmanTrippedError. After close(): ActuationError.
        """
        self._raise_if_unusable()
        if not self._armed:
            self._link.arm()
            self._armed = True
        try:
            require_finite(command)
        except ActuationError:
            self._link.command(STOP)
            raise
        limited = limit_command(command, self._config.max_linear_m_s,
                                self._config.max_angular_rad_s)
        if self._held and not limited.is_stop:
            self._link.command(STOP)
            raise DeadmanTrippedError(
                f"{self._port}: the base is held stopped (hold_stopped()); motion commands are "
                "ignored until rearm()")
        self._link.command(limited)
        with self._cond:
            tripped, reason = self._link.mode is DeadmanMode.TRIPPED, self._link.mode_reason
        if tripped and not limited.is_stop:
            raise DeadmanTrippedError(
                f"{self._port}: the dead-man stopped the base ({reason}); motion commands are "
                "ignored until rearm()")

    def feedback(self, now: float) -> BaseFeedback:
        """The newest decoded feedback; `received_at_s` is the injected clock at its arrival."""
        with self._cond:
            sensors = self._sensors
            return BaseFeedback(
                received_at_s=self._received_at_s,
                bumper=sensors.bumper if sensors else 0,
                wheel_drop=sensors.wheel_drop if sensors else 0,
                cliff=sensors.cliff if sensors else 0,
                buttons=sensors.buttons if sensors else 0,
                battery_v=sensors.battery_v if sensors else None,
                odometry=self._odometry.pose,
                stop_latched=(self._link.mode_reason
                              if self._link.mode is DeadmanMode.LATCHED else None),
            )

    def close(self) -> None:
        """Stop the base (the dead-man sends stop, flushes, exits), reap it. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._link.close()

    def __enter__(self) -> KobukiBase:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    # ---- beyond the Base interface ------------------------------------------------------------
    def rearm(self, now: float) -> None:
        """Explicitly re-arm a tripped, disarmed or held dead-man (not out of its own hazard
        latch: that takes `resume()`). The command is stop until the next send()."""
        self._raise_if_unusable()
        self._link.arm()
        self._armed = True
        self._held = False

    def resume(self, now: float) -> bool:
        """The operator's explicit start or resume: arm the dead-man, and release its own hazard
        latch once the hazard has cleared (the only way out of it). The command is stop until the
        next send(). Unless it was armed already (then RESUME is only a heartbeat), waits (at
        most twice the heartbeat timeout; the base is stopped meanwhile) for the dead-man's
        answer. Returns whether it is armed. Call only from an operator's start or resume, never
        automatically."""
        self._raise_if_unusable()
        link = self._link
        with self._cond:
            armed = link.mode is DeadmanMode.ARMED
        seq = link.resume()
        self._armed = True
        self._held = False
        if armed:
            return True
        link.wait_for(lambda: (link.wire is not None and link.wire.heartbeat_seq >= seq)
                      or link.gone, 2 * self._config.heartbeat_timeout_s)
        with self._cond:
            return link.mode is DeadmanMode.ARMED

    def hold_stopped(self, now: float) -> bool:
        """Stop now and disarm the dead-man (it holds stop without needing heartbeats), e.g.
        before this process suspends itself; motion is refused until `rearm()`.

        Waits (at most twice the heartbeat timeout) until the dead-man reports a stop written
        after this request, or the link is lost (the relay has then written the stop itself if
        it could). Returns whether the dead-man confirmed the stop. Never raises."""
        self._held = True
        link = self._link
        try:
            seq = link.disarm()
        except KobukiLinkError:
            return False
        return link.wait_for(
            lambda: (link.wire is not None and link.wire.heartbeat_seq >= seq
                     and link.wire.command.is_stop) or link.gone,
            2 * self._config.heartbeat_timeout_s,
        ) and not link.gone

    def request_extra(self, flags: int) -> None:
        """Ask the base for versions / UDID (ExtraRequest bits); they arrive as feedback."""
        self.send_extra(encode_request_extra(flags))

    def play_sound_sequence(self, sequence: SoundSequence) -> None:
        self.send_extra(encode_sound_sequence(sequence))

    def send_extra(self, sub_payloads: bytes) -> None:
        """Write non-motion command sub-payloads once (ValueError for base control)."""
        check_non_motion(sub_payloads)
        self._raise_if_unusable()
        self._link.raw(sub_payloads)

    def wait_for(self, predicate: Callable[[KobukiBase], bool], timeout_s: float) -> bool:
        """Block until `predicate(self)` holds (re-checked on every relayed message) or timeout."""
        return self._link.wait_for(lambda: predicate(self), timeout_s)

    def link_health(self, now: float) -> LinkHealth:
        with self._cond:
            link = self._link
            age = None if self._received_at_s is None else now - self._received_at_s
            return LinkHealth(
                port=self._port, last_packet_age_s=age, packets=self._packets,
                checksum_errors=self._checksum_errors, malformed_subpayloads=self._malformed,
                deadman_mode=link.mode, deadman_reason=link.mode_reason,
                lost_reason=link.lost, low_latency=link.low_latency,
                alive=(link.lost is None and age is not None
                       and age <= self._config.link_timeout_s),
                deadman_priority=link.priority, deadman_priority_raised=link.priority_raised,
            )

    def priority_warning(self) -> str | None:
        """One line for the operator when the dead-man could not raise its priority, else None."""
        with self._cond:
            if self._link.priority_raised:
                return None
            return (f"{self._port}: the dead-man runs at {self._link.priority}: under load it "
                    "may stop the robot later than documented (run as root or grant "
                    "CAP_SYS_NICE)")

    @property
    def port(self) -> str:
        return self._port

    @property
    def deadman_pid(self) -> int:
        return self._link.process.pid

    @property
    def deadman_hello(self) -> Hello | None:
        """The dead-man's HELLO: its protocol, package version and the folder it imported
        lanewarden from."""
        with self._cond:
            return self._link.hello

    @property
    def deadman_mode(self) -> DeadmanMode:
        with self._cond:
            return self._link.mode

    @property
    def motion_stopped_s(self) -> float | None:
        """When the dead-man wrote the stop that ended the latest motion (CLOCK_MONOTONIC, the
        dead-man's reading once the write returned), or None."""
        with self._cond:
            return self._link.motion_stopped_s

    @property
    def deadman_reason(self) -> str:
        """Why the dead-man is in its mode (one line)."""
        with self._cond:
            return self._link.mode_reason

    @property
    def link_lost(self) -> str | None:
        """Why the link was lost (one line), or None while it is up."""
        with self._cond:
            return self._link.lost

    @property
    def stop_failed(self) -> str | None:
        """One line when a stop the control side had to write itself (the dead-man gone, killed,
        or its port failed) could not be written: the base may still be driving its last
        command. None otherwise. Final once `close()` has returned."""
        with self._cond:
            return self._link.stop_failed

    @property
    def packets_received(self) -> int:
        with self._cond:
            return self._packets

    @property
    def sensors(self) -> BasicSensorData | None:
        with self._cond:
            return self._sensors

    @property
    def latest_packet(self) -> FeedbackPacket:
        """The newest 50 Hz stream packet (the one with basic sensor data, inertial, cliff ADC,
        current, gyro, GPIO); versions/UDID/controller info have their own properties."""
        with self._cond:
            return self._latest

    @property
    def battery_v(self) -> float | None:
        with self._cond:
            return self._sensors.battery_v if self._sensors else None

    @property
    def odometry(self) -> Pose2D:
        with self._cond:
            return self._odometry.pose

    @property
    def hardware_version(self) -> Version | None:
        with self._cond:
            return self._hardware_version

    @property
    def firmware_version(self) -> Version | None:
        with self._cond:
            return self._firmware_version

    @property
    def udid(self) -> UDID | None:
        with self._cond:
            return self._udid

    @property
    def controller_info(self) -> ControllerInfo | None:
        with self._cond:
            return self._controller_info

    # ---- internals ----------------------------------------------------------------------------
    def _raise_if_unusable(self) -> None:
        if self._closed:
            raise ActuationError(f"{self._port}: the Kobuki base is closed")
        self._raise_if_lost()

    def _raise_if_lost(self) -> None:
        with self._cond:
            if self._link.lost is not None:
                raise KobukiLinkError(self._link.lost)

    def _apply_feedback(self, message: FeedbackReceived, arrived_s: float) -> None:
        """Called by the relay thread, under self._cond."""
        packet = decode_feedback(message.payload)
        self._checksum_errors = message.checksum_errors
        self._malformed += len(packet.malformed_ids) + int(packet.truncated)
        if packet.basic is not None:
            # Only the base's sensor stream proves a live Kobuki: a port that echoes our own
            # command frames back (loop://, a terminal with echo on) carries valid frames too.
            # And only a packet the base stamped anew (50 a second, its u16 millisecond
            # counter): one repeating the last one's stamp is the same packet replayed, no news
            # of the base, and leaves the feedback as old as it was (the dead-man's rule too,
            # `DeadmanLogic.on_feedback`: each layer holds it without the other).
            stamp = packet.basic.timestamp_ms
            if stamp != self._stamp_ms:
                self._received_at_s = arrived_s
            self._stamp_ms = stamp
            self._packets += 1
            self._latest = packet
            self._sensors = packet.basic
            self._odometry.update(packet.basic.left_encoder, packet.basic.right_encoder)
        self._hardware_version = packet.hardware_version or self._hardware_version
        self._firmware_version = packet.firmware_version or self._firmware_version
        self._udid = packet.udid or self._udid
        self._controller_info = packet.controller_info or self._controller_info
