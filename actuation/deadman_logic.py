"""The dead-man's decision logic: what goes on the wire, and when. A pure class driven by `now`.

The dead-man process owns the serial port. Its shell feeds this class what arrives from the
control process (arm, disarm, commands, close, malformed messages, end of stream) and asks
`poll(now)` what to write. The rules:

- It starts DISARMED and sends stop at the steady command rate, whatever it is told.
- ARM (an explicit message, never implied by a command) moves to ARMED with the command stop;
  only ARMED forwards commands. DISARM: stop at once and back to DISARMED (the control process
  is about to be suspended on purpose), until an explicit ARM.
- Every arm, disarm and command is a heartbeat carrying the sender's sequence number and its
  monotonic time at sending; the deadline counts from that stamp, not from when the message was
  read, so a heartbeat that waited in the socket while the sender was frozen is not fresh. A
  stamp from the future or a sequence/stamp going backwards counts as a malformed message.
- ARMED and no heartbeat stamped within the last `heartbeat_timeout_s` (or a malformed message)
  -> TRIPPED: stop goes out at once and is repeated until an explicit ARM; commands meanwhile
  are ignored.
- The control process gone (end of stream) -> STOPPING: stop at once, repeated for
  `orphan_stop_s`, then finished. CLOSE or a signal -> STOPPING for a short burst, then finished.
- A stop (commanded or forced) goes out at once; other commands wait for the next tick.

Never reads a clock, never touches a port or a socket: the shell in `deadman.py` does that.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from lanewarden.actuation.base import STOP, VelocityCommand

#: How many stop packets a requested close puts on the wire before the process exits.
CLOSE_STOP_PACKETS = 3


class DeadmanMode(Enum):
    DISARMED = "disarmed"
    ARMED = "armed"
    TRIPPED = "tripped"
    STOPPING = "stopping"


@dataclass(frozen=True)
class Heartbeat:
    """What makes a control message a heartbeat: the sender's sequence number (counting up) and
    its CLOCK_MONOTONIC time at sending, s."""

    seq: int
    sent_s: float


@dataclass(frozen=True)
class DeadmanSettings:
    heartbeat_timeout_s: float = 0.2
    command_period_s: float = 0.02
    orphan_stop_s: float = 0.5


@dataclass(frozen=True)
class DeadmanEvent:
    """A mode change, reported to the control process (and logged)."""

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
        self._mode = DeadmanMode.DISARMED
        self._command = STOP
        self._last_heartbeat_s = start_s
        self._last_seq = -1
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

    # ---- inputs -------------------------------------------------------------------------------
    def on_arm(self, now: float, heartbeat: Heartbeat) -> None:
        """Explicit arm: ARMED with the command stop (a no-op heartbeat when already armed)."""
        if self._mode is DeadmanMode.STOPPING or not self._accept(heartbeat, now):
            return
        if self._mode is not DeadmanMode.ARMED:
            self._set_command(STOP)
            self._change(DeadmanMode.ARMED, "armed by the control process")

    def on_disarm(self, now: float, heartbeat: Heartbeat) -> None:
        """Stop at once and hold stop without heartbeats until an explicit arm."""
        if self._mode is DeadmanMode.STOPPING or not self._accept(heartbeat, now):
            return
        self._set_command(STOP)
        if self._mode is not DeadmanMode.DISARMED:
            self._change(DeadmanMode.DISARMED, "disarmed by the control process (suspending)")

    def on_command(self, command: VelocityCommand, now: float, heartbeat: Heartbeat) -> None:
        """A command from the control process; also a heartbeat. Ignored unless ARMED."""
        if not self._accept(heartbeat, now) or self._mode is not DeadmanMode.ARMED:
            return
        self._set_command(command)

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

    # ---- outputs ------------------------------------------------------------------------------
    def poll(self, now: float) -> WireAction:
        """What to write at `now`. Call whenever an input arrived or `next_wakeup_s` passed."""
        # compare against the same deadline next_wakeup_s() reports, so waking at it trips
        if self._mode is DeadmanMode.ARMED and now >= self._heartbeat_deadline_s():
            silent_s = now - self._last_heartbeat_s
            self._trip(f"no heartbeat for {silent_s:.3f} s "
                       f"(timeout {self._settings.heartbeat_timeout_s:g} s; the last one was "
                       f"stamped {self._last_heartbeat_s:.6f})")
        finished = self._mode is DeadmanMode.STOPPING and now >= self._stop_until_s
        send: VelocityCommand | None = None
        if self._urgent or now >= self._next_send_s or finished:
            send = self._command
            self._urgent = False
            self._next_send_s = now + self._settings.command_period_s
        events, self._events = tuple(self._events), []
        return WireAction(send, events, finished)

    def next_wakeup_s(self) -> float:
        """The latest time the shell may wait until before calling `poll` again."""
        wakeup = self._next_send_s
        if self._mode is DeadmanMode.ARMED:
            wakeup = min(wakeup, self._heartbeat_deadline_s())
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

    def _heartbeat_deadline_s(self) -> float:
        return self._last_heartbeat_s + self._settings.heartbeat_timeout_s

    def _set_command(self, command: VelocityCommand) -> None:
        if command.is_stop and not self._command.is_stop:
            self._urgent = True
        self._command = command

    def _trip(self, reason: str) -> None:
        self._command = STOP
        self._urgent = True
        self._change(DeadmanMode.TRIPPED, reason)

    def _stop_and_finish(self, now: float, stop_for_s: float, reason: str) -> None:
        if self._mode is DeadmanMode.STOPPING:
            return
        self._command = STOP
        self._urgent = True
        self._stop_until_s = now + stop_for_s
        self._change(DeadmanMode.STOPPING, reason)

    def _change(self, mode: DeadmanMode, reason: str) -> None:
        self._mode = mode
        self._events.append(DeadmanEvent(mode, reason))
