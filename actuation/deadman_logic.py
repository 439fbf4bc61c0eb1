"""The dead-man's decision logic: what goes on the wire, and when. A pure class driven by `now`.

The dead-man process owns the serial port: it is the base's safety monitor, and these rules hold
whatever the control process says (it may be wrong, frozen or gone). Its shell feeds this class
what arrives from the control process (arm, resume, disarm, commands, close, malformed messages,
end of stream) and from the base (the hazard bits of every feedback packet), and asks
`poll(now)` what to write. The rules:

- It starts DISARMED and sends stop at the steady command rate, whatever it is told.
- ARM (an explicit message, never implied by a command) moves DISARMED or TRIPPED to ARMED with
  the command stop; only ARMED forwards commands. DISARM: stop at once and back to DISARMED (the
  control process is about to be suspended on purpose), until an explicit ARM.
- Every arm, resume, disarm and command is a heartbeat carrying the sender's sequence number and
  its monotonic time at sending; the deadline counts from that stamp, not from when the message
  was read, so a heartbeat that waited in the socket while the sender was frozen is not fresh. A
  stamp from the future or a sequence/stamp going backwards counts as a malformed message.
- ARMED and no heartbeat stamped within the last `heartbeat_timeout_s` (or a malformed message)
  -> TRIPPED: stop goes out at once and is repeated until an explicit ARM; commands meanwhile
  are ignored.
- Its own hazard latch (LATCHED): a feedback packet with a bumper, cliff or wheel-drop bit set,
  seen while DISARMED or ARMED, or (ARMED) no feedback packet read within `feedback_timeout_s`
  -> stop at once, repeated; commands are ignored. ARM and DISARM do not leave LATCHED: only
  RESUME (the operator's explicit start or resume, relayed by the control process) does, and only
  once the hazard has cleared (the newest packet has no hazard bit and is fresh); a RESUME before
  that is refused (an event says why) and the latch holds. Arming out of DISARMED or TRIPPED
  while a hazard is present latches instead of arming.
- The envelope: every command it forwards is scaled into `max_linear_m_s` / `max_angular_rad_s`
  (keeping its curvature) and each axis's increases are ramped at most `max_*_accel` per command
  period; a decrease or a stop passes at once. Clamped, never refused: what went out is reported.
- The control process gone (end of stream) -> STOPPING: stop at once, repeated for
  `orphan_stop_s`, then finished. CLOSE or a signal -> STOPPING for a short burst, then finished.
- A stop (commanded or forced) goes out at once; other commands wait for the next tick.

Never reads a clock, never touches a port or a socket: the shell in `deadman.py` does that.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.actuation.kobuki_feedback import (
    BUMPER_SIDES,
    CLIFF_SIDES,
    WHEEL_DROP_SIDES,
    side_names,
)
from lanewarden.actuation.kobuki_geometry import (
    MAX_ANGULAR_RAD_S,
    MAX_LINEAR_M_S,
    limit_command,
    ramp_axis,
)

#: How many stop packets a requested close puts on the wire before the process exits.
CLOSE_STOP_PACKETS = 3


class DeadmanMode(Enum):
    DISARMED = "disarmed"
    ARMED = "armed"
    TRIPPED = "tripped"
    LATCHED = "latched"
    STOPPING = "stopping"


@dataclass(frozen=True)
class Heartbeat:
    """What makes a control message a heartbeat: the sender's sequence number (counting up) and
    its CLOCK_MONOTONIC time at sending, s."""

    seq: int
    sent_s: float


@dataclass(frozen=True)
class SafetySensors:
    """The hazard bits of one feedback packet's basic sensor data (Kobuki layout: bumper 1 right /
    2 centre / 4 left, wheel drop 1 right / 2 left, cliff 1 right / 2 centre / 4 left) and when
    the dead-man read it (its CLOCK_MONOTONIC), s."""

    read_s: float
    bumper: int = 0
    cliff: int = 0
    wheel_drop: int = 0
    #: The base's own time stamp of the packet (its u16 millisecond counter; None: not known).
    timestamp_ms: int | None = None

    def hazard(self) -> str | None:
        """What is wrong, one line ("bumper pressed (left)"), or None when no bit is set."""
        found = [f"{what} ({', '.join(side_names(bits, sides)) or f'bits {bits:#x}'})"
                 for what, bits, sides in (("bumper pressed", self.bumper, BUMPER_SIDES),
                                           ("cliff sensor triggered", self.cliff, CLIFF_SIDES),
                                           ("wheel dropped", self.wheel_drop, WHEEL_DROP_SIDES))
                 if bits]
        return "; ".join(found) or None


@dataclass(frozen=True)
class Envelope:
    """The base's envelope, enforced on every command the dead-man forwards (see the module
    docstring): speed limits, m/s and rad/s, and ramps for increases, m/s^2 and rad/s^2."""

    max_linear_m_s: float = MAX_LINEAR_M_S
    max_angular_rad_s: float = MAX_ANGULAR_RAD_S
    max_linear_accel_m_s2: float = 1.0
    max_angular_accel_rad_s2: float = 10.0


@dataclass(frozen=True)
class DeadmanSettings:
    heartbeat_timeout_s: float = 0.2
    command_period_s: float = 0.02
    orphan_stop_s: float = 0.5
    feedback_timeout_s: float = 0.2
    envelope: Envelope = Envelope()


@dataclass(frozen=True)
class DeadmanEvent:
    """A mode change (or a refused resume), reported to the control process (and logged)."""

    mode: DeadmanMode
    reason: str


@dataclass(frozen=True)
class WireAction:
    """What `poll` decided: a base-control command to write now (or None), events, and whether
    the process should flush and exit after writing it."""

    send: VelocityCommand | None
    events: tuple[DeadmanEvent, ...] = ()
    finished: bool = False


class DeadmanLogic:
    def __init__(self, settings: DeadmanSettings, start_s: float) -> None:
        self._settings = settings
        envelope = settings.envelope
        self._ramp_linear_m_s = envelope.max_linear_accel_m_s2 * settings.command_period_s
        self._ramp_angular_rad_s = envelope.max_angular_accel_rad_s2 * settings.command_period_s
        self._mode = DeadmanMode.DISARMED
        self._target = STOP  # what the control process asked for (within the speed limits)
        self._command = STOP  # what goes on the wire
        self._last_heartbeat_s = start_s
        self._last_seq = -1
        self._feedback_s: float | None = None  # when the newest feedback packet was read
        #: the newest packet's own time stamp, and that stamp when packets repeat it (None: the
        #: newest packet was a new one)
        self._timestamp_ms: int | None = None
        self._repeated_ms: int | None = None
        #: packets read without readable basic sensor data since the last packet with it
        self._without_sensors = 0
        self._sensor_hazard: str | None = None  # what the newest feedback packet says is wrong
        self._next_send_s = start_s  # the first stop goes out at once
        self._urgent = True
        self._stop_until_s = 0.0
        self._events: list[DeadmanEvent] = []

    @property
    def mode(self) -> DeadmanMode:
        return self._mode

    @property
    def command(self) -> VelocityCommand:
        """The command currently being put on the wire."""
        return self._command

    @property
    def heartbeat_seq(self) -> int:
        """Sequence number of the newest accepted heartbeat (-1: none yet)."""
        return self._last_seq

    # ---- inputs from the control process ------------------------------------------------------
    def on_arm(self, now: float, heartbeat: Heartbeat) -> None:
        """Explicit arm: DISARMED or TRIPPED -> ARMED with the command stop (LATCHED instead while
        a hazard is present). A heartbeat only when ARMED or LATCHED."""
        if self._mode is DeadmanMode.STOPPING or not self._accept(heartbeat, now):
            return
        if self._mode in (DeadmanMode.DISARMED, DeadmanMode.TRIPPED):
            self._arm(now, "armed by the control process")

    def on_resume(self, now: float, heartbeat: Heartbeat) -> None:
        """The operator's explicit start or resume: like ARM, and the only way out of LATCHED,
        once the hazard has cleared (else the latch holds and an event says why)."""
        if self._mode is DeadmanMode.STOPPING or not self._accept(heartbeat, now):
            return
        if self._mode is DeadmanMode.LATCHED:
            hazard = self._hazard(now)
            if hazard is not None:
                self._change(DeadmanMode.LATCHED, f"resume refused: {hazard}")
                return
            self._set_target(STOP)
            self._change(DeadmanMode.ARMED, "re-armed by the operator (the hazard has cleared)")
        elif self._mode is not DeadmanMode.ARMED:
            self._arm(now, "armed by the operator")

    def on_disarm(self, now: float, heartbeat: Heartbeat) -> None:
        """Stop at once and hold stop without heartbeats until an explicit arm (a heartbeat only
        when LATCHED: the latch holds)."""
        if self._mode in (DeadmanMode.STOPPING, DeadmanMode.LATCHED) \
                or not self._accept(heartbeat, now):
            return
        self._set_target(STOP)
        if self._mode is not DeadmanMode.DISARMED:
            self._change(DeadmanMode.DISARMED, "disarmed by the control process (suspending)")

    def on_command(self, command: VelocityCommand, now: float, heartbeat: Heartbeat) -> None:
        """A command from the control process; also a heartbeat. Ignored unless ARMED."""
        if not self._accept(heartbeat, now) or self._mode is not DeadmanMode.ARMED:
            return
        envelope = self._settings.envelope
        self._set_target(limit_command(command, envelope.max_linear_m_s,
                                       envelope.max_angular_rad_s))

    def on_malformed(self, now: float, what: str) -> None:
        """A message that could not be decoded: stop and disarm, like a missed heartbeat."""
        if self._mode is DeadmanMode.ARMED:
            self._trip(f"malformed message from the control process ({what})")

    def on_control_gone(self, now: float) -> None:
        """The control process closed its end (exited, crashed or was killed)."""
        self._stop_and_finish(now, self._settings.orphan_stop_s,
                              "control process gone: stopping the base and exiting")

    def on_close(self, now: float, reason: str = "closed by the control process") -> None:
        """An orderly close (CLOSE message or SIGTERM/SIGINT): a short burst of stops, exit."""
        self._stop_and_finish(now, (CLOSE_STOP_PACKETS - 1) * self._settings.command_period_s,
                              reason)

    # ---- inputs from the base -----------------------------------------------------------------
    def on_feedback(self, now: float, sensors: SafetySensors) -> None:
        """One feedback packet's hazard bits: a hazard latches (DISARMED or ARMED) at once. A
        packet carrying the same time stamp as the one before is no news of the base (the base
        stamps each packet anew, 50 a second): it never makes the feedback fresh (an attacker's
        review: a device replaying one packet 10 times a second kept the link 'ok' while the
        robot moved nowhere, and would have hidden a bumper), while its hazard bits still
        count."""
        self._without_sensors = 0
        stamp = sensors.timestamp_ms
        repeated = stamp is not None and stamp == self._timestamp_ms
        self._timestamp_ms = stamp
        self._repeated_ms = stamp if repeated else None
        if not repeated and (self._feedback_s is None or sensors.read_s > self._feedback_s):
            self._feedback_s = sensors.read_s
        self._sensor_hazard = sensors.hazard()
        if self._sensor_hazard is not None and self._mode in (DeadmanMode.DISARMED,
                                                              DeadmanMode.ARMED):
            self._latch(self._sensor_hazard)

    def on_packet_without_sensors(self) -> None:
        """A packet read whose basic sensor data is missing or unreadable: no news of the base's
        hazards, so no fresh feedback; counted, so that a latch for stale feedback says packets
        do arrive (it had said only 'no feedback' while 50 a second came)."""
        self._without_sensors += 1

    # ---- outputs ------------------------------------------------------------------------------
    def poll(self, now: float) -> WireAction:
        """What to write at `now`. Call whenever an input arrived or `next_wakeup_s` passed."""
        # compare against the same deadlines next_wakeup_s() reports, so waking at one acts
        if self._mode is DeadmanMode.ARMED and now >= self._heartbeat_deadline_s():
            silent_s = now - self._last_heartbeat_s
            self._trip(f"no heartbeat for {silent_s:.3f} s "
                       f"(timeout {self._settings.heartbeat_timeout_s:g} s; the last one was "
                       f"stamped {self._last_heartbeat_s:.6f})")
        if self._mode is DeadmanMode.ARMED and (hazard := self._hazard(now)) is not None:
            self._latch(hazard)
        finished = self._mode is DeadmanMode.STOPPING and now >= self._stop_until_s
        send: VelocityCommand | None = None
        if self._urgent or now >= self._next_send_s or finished:
            send = self._command = self._shaped(self._target)
            self._urgent = False
            self._next_send_s = now + self._settings.command_period_s
        events, self._events = tuple(self._events), []
        return WireAction(send, events, finished)

    def next_wakeup_s(self) -> float:
        """The latest time the shell may wait until before calling `poll` again."""
        wakeup = self._next_send_s
        if self._mode is DeadmanMode.ARMED:
            wakeup = min(wakeup, self._heartbeat_deadline_s(), self._feedback_deadline_s())
        if self._mode is DeadmanMode.STOPPING:
            wakeup = min(wakeup, self._stop_until_s)
        if self._urgent:
            wakeup = float("-inf")
        return wakeup

    # ---- internals ----------------------------------------------------------------------------
    def _accept(self, heartbeat: Heartbeat, now: float) -> bool:
        """Take `heartbeat` as the newest one, or treat it as malformed (False)."""
        if heartbeat.sent_s > now:
            problem = f"heartbeat stamped in the future ({heartbeat.sent_s - now:.6f} s ahead)"
        elif heartbeat.seq <= self._last_seq:
            problem = f"heartbeat sequence went backwards ({heartbeat.seq} after {self._last_seq})"
        elif self._last_seq >= 0 and heartbeat.sent_s < self._last_heartbeat_s:
            problem = "heartbeat stamp went backwards"
        else:
            self._last_seq = heartbeat.seq
            self._last_heartbeat_s = heartbeat.sent_s
            return True
        self.on_malformed(now, problem)
        return False

    def _hazard(self, now: float) -> str | None:
        """Why the base must not move now (the newest packet's hazard, or feedback missing or
        stale), or None."""
        if self._sensor_hazard is not None:
            return self._sensor_hazard
        if self._feedback_s is None:
            return "no feedback from the base yet"
        if now >= self._feedback_deadline_s():
            repeated = ("" if self._repeated_ms is None else
                        f"; its packets repeat the time stamp {self._repeated_ms} ms: the same "
                        "packet replayed")
            if self._without_sensors:
                repeated += (f"; {self._without_sensors} packets since carry no readable basic "
                             "sensor data")
            return (f"no feedback from the base for {now - self._feedback_s:.3f} s (timeout "
                    f"{self._settings.feedback_timeout_s:g} s{repeated})")
        return None

    def _heartbeat_deadline_s(self) -> float:
        return self._last_heartbeat_s + self._settings.heartbeat_timeout_s

    def _feedback_deadline_s(self) -> float:
        if self._feedback_s is None:
            return float("-inf")
        return self._feedback_s + self._settings.feedback_timeout_s

    def _shaped(self, target: VelocityCommand) -> VelocityCommand:
        """The next command on the wire towards `target`: stop unless ARMED, increases ramped."""
        if self._mode is not DeadmanMode.ARMED or target.is_stop:
            return STOP
        envelope, wire = self._settings.envelope, self._command
        return VelocityCommand(
            ramp_axis(wire.linear_m_s, target.linear_m_s, envelope.max_linear_m_s,
                      self._ramp_linear_m_s),
            ramp_axis(wire.angular_rad_s, target.angular_rad_s, envelope.max_angular_rad_s,
                      self._ramp_angular_rad_s))

    def _arm(self, now: float, reason: str) -> None:
        hazard = self._hazard(now)
        if hazard is not None:
            self._latch(hazard)
            return
        self._set_target(STOP)
        self._change(DeadmanMode.ARMED, reason)

    def _set_target(self, command: VelocityCommand) -> None:
        if command.is_stop and not self._command.is_stop:
            self._urgent = True
        self._target = command

    def _force_stop(self) -> None:
        self._target = STOP
        self._urgent = True

    def _trip(self, reason: str) -> None:
        self._force_stop()
        self._change(DeadmanMode.TRIPPED, reason)

    def _latch(self, reason: str) -> None:
        self._force_stop()
        self._change(DeadmanMode.LATCHED, reason)

    def _stop_and_finish(self, now: float, stop_for_s: float, reason: str) -> None:
        if self._mode is DeadmanMode.STOPPING:
            return
        self._force_stop()
        self._stop_until_s = now + stop_for_s
        self._change(DeadmanMode.STOPPING, reason)

    def _change(self, mode: DeadmanMode, reason: str) -> None:
        self._mode = mode
        self._events.append(DeadmanEvent(mode, reason))
