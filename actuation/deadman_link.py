"""The control process's end of the dead-man: starting it, talking to it, watching that it lives.

`DeadmanLink.start(...)` runs `python -P -m lanewarden.actuation.deadman` in a session of its own
(so the terminal's Ctrl-Z, Ctrl-\\ and Ctrl-C reach only the control process, never the process
that must stop the robot) with one end of a SOCK_SEQPACKET socketpair. `-P` keeps the current
folder off its module path: run from a folder holding another checkout, it still imports the
lanewarden this interpreter has installed (a venv, an editable install, PYTHONPATH and the user's
site-packages all still count). Our HELLO goes out at once; the dead-man's (`hello`, checked by
the caller) says which version it runs and where it imported it from. Heartbeats (`arm`,
`resume`, `disarm`, `command`) are numbered and stamped with time.monotonic here, whatever clock
the caller injects elsewhere: the dead-man compares the stamp with its own CLOCK_MONOTONIC.

A relay thread decodes what the dead-man says: feedback payloads go to `on_feedback` (stamped with
the caller's clock on arrival); port, priority, mode, `WIRE` reports and link loss are kept here.
It also watches the dead-man: it reports every write to the port (at the command rate), so no
report received for `heartbeat_timeout_s`, with nothing waiting in the socket, means it is
frozen, starved or wedged (the silence is timed from when the relay last received a report, so a
relay that was itself frozen or starved first drains its backlog and then waits the full time).
Then it is killed and, once it is confirmed dead, the port is reopened and the stop written from
here (`write_stop_directly`); the same when it dies from a signal it could not handle. That work
runs in a thread that is not a daemon, so it completes even if this process is exiting. Either
way the link is then lost with one line saying what happened and whether the stop went out (a
send that finds the dead-man gone waits, bounded, for that line).

The only code outside the dead-man process that writes to the serial port is
`write_stop_directly`, and only after the dead-man is confirmed dead: two writers never race.
"""

from __future__ import annotations

import select
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable

from lanewarden.actuation.base import VelocityCommand
from lanewarden.actuation.config import ActuationConfig
from lanewarden.actuation.deadman import EXIT_LINK_LOST
from lanewarden.actuation.deadman_logic import CLOSE_STOP_PACKETS, DeadmanMode, Heartbeat
from lanewarden.actuation.deadman_messages import (
    MAX_MESSAGE_BYTES,
    Arm,
    Close,
    Command,
    ControlMessage,
    DeadmanMessage,
    Disarm,
    FeedbackReceived,
    Hello,
    LinkLost,
    ModeChanged,
    OnTheWire,
    OpenFailed,
    PortOpened,
    RawCommand,
    Resume,
    decode_deadman,
    encode_control,
)
from lanewarden.actuation.errors import KobukiLinkError
from lanewarden.actuation.kobuki_commands import STOP_PACKET
from lanewarden.actuation.kobuki_port import STOP_RETRY_S, StopOutcome, stop_through_port
from lanewarden.actuation.realtime import raise_priority


def write_stop_directly(port: str, write_timeout_s: float) -> StopOutcome:
    """Reopen `port` and write the stop packet a few times (`kobuki_port.stop_through_port`:
    what is queued for the device dropped first, the port tried again for a while when it is
    gone). Call ONLY once the dead-man process is confirmed dead. Returns whether the stop went
    out, and one line saying so. Never raises."""
    return stop_through_port(port, STOP_PACKET, CLOSE_STOP_PACKETS, write_timeout_s)


def receive_or_silence(recv: Callable[[], bytes], deadline_s: float | None,
                       clock: Callable[[], float],
                       wait_readable: Callable[[float | None], object]) -> bytes | None:
    """The next message (b"" at end of stream), or None for silence: the queue seen empty at a
    time after `deadline_s` (None: wait as long as it takes).

    `recv` must not block (BlockingIOError when nothing is queued); `wait_readable(timeout)`
    waits until something is (or the timeout passes). What is already queued always counts, so
    a caller that was itself starved or frozen first drains its backlog; and only an empty queue
    seen after the deadline is silence, because the caller may have been frozen (SIGSTOP,
    Ctrl-Z) between a look at the queue and its clock reading."""
    while True:
        try:
            return recv()
        except BlockingIOError:
            pass
        except OSError:
            return b""
        wait_s = None if deadline_s is None else deadline_s - clock()
        if wait_s is not None and wait_s <= 0.0:
            try:
                return recv()  # a look after the deadline
            except BlockingIOError:
                return None
            except OSError:
                return b""
        wait_readable(wait_s)


def _signal_name(returncode: int) -> str:
    try:
        return signal.Signals(-returncode).name
    except ValueError:
        return f"signal {-returncode}"


class DeadmanLink:
    """One running dead-man process and the socket to it. Create with `DeadmanLink.start`.

    Everything the relay thread learns is read under `cond` (a Condition notified on every
    message): `opened`, `low_latency`, `priority_raised`, `priority`, `open_error`, `lost`,
    `gone`, `hello` (the dead-man's HELLO), `mode`, `mode_reason`, `wire` (the newest WIRE
    report), `motion_stopped_s` (when the dead-man wrote the stop that ended the latest motion,
    on its CLOCK_MONOTONIC)."""

    def __init__(self, port: str, process: subprocess.Popen[bytes], control: socket.socket,
                 config: ActuationConfig, clock: Callable[[], float],
                 on_feedback: Callable[[FeedbackReceived, float], None]) -> None:
        self.port = port
        self.process = process
        self._control = control
        self._config = config
        self._clock = clock
        self._on_feedback = on_feedback
        self._send_lock = threading.Lock()  # one sequence, in order, whichever thread sends
        self._seq = -1
        self.cond = threading.Condition()
        self.closing = False
        self.opened = False
        self.low_latency = False
        self.priority_raised = False
        self.priority = "unknown"
        self.open_error: str | None = None
        self.lost: str | None = None
        #: Set when a stop this side had to write could not be (one line saying so): the base
        #: may still be driving its last command (`KobukiBase.stop_failed`).
        self.stop_failed: str | None = None
        self.gone = False
        self.hello: Hello | None = None
        self.mode = DeadmanMode.DISARMED
        self.mode_reason = "started"
        self.wire: OnTheWire | None = None
        self.motion_stopped_s: float | None = None
        self._emergency: threading.Thread | None = None
        self._relay = threading.Thread(target=self._relay_messages, name="kobuki-relay",
                                       daemon=True)

    @classmethod
    def start(cls, port: str, config: ActuationConfig, clock: Callable[[], float],
              on_feedback: Callable[[FeedbackReceived, float], None]) -> DeadmanLink:
        """Start the dead-man on `port`; KobukiLinkError when the process cannot be started."""
        parent_end, child_end = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        # -P: the current folder must not shadow the installed package (see the docstring)
        argv = [sys.executable, "-P", "-m", "lanewarden.actuation.deadman", "--port", port,
                "--control-fd", str(child_end.fileno()),
                "--command-rate-hz", repr(config.command_rate_hz),
                "--heartbeat-timeout-s", repr(config.heartbeat_timeout_s),
                "--orphan-stop-s", repr(config.orphan_stop_s),
                "--write-timeout-s", repr(config.write_timeout_s),
                "--feedback-timeout-s", repr(config.feedback_timeout_s),
                "--max-linear-m-s", repr(config.max_linear_m_s),
                "--max-angular-rad-s", repr(config.max_angular_rad_s),
                "--max-linear-accel-m-s2", repr(config.max_linear_accel_m_s2),
                "--max-angular-accel-rad-s2", repr(config.max_angular_accel_rad_s2)]
        try:
            # its own session: no terminal signal (SIGTSTP, SIGQUIT, SIGINT) reaches it
            process = subprocess.Popen(argv, pass_fds=(child_end.fileno(),),
                                       stdin=subprocess.DEVNULL, start_new_session=True)
        except OSError as exc:
            parent_end.close()
            raise KobukiLinkError(f"{port}: cannot start the dead-man process ({exc})") from exc
        finally:
            child_end.close()
        try:  # first of all: the dead-man checks our HELLO before it touches the port
            parent_end.send(encode_control(Hello.ours()), socket.MSG_DONTWAIT)
        except OSError:
            pass  # it died at once: the relay sees the end of the stream and says so
        link = cls(port, process, parent_end, config, clock, on_feedback)
        link._relay.start()
        return link

    # ---- talking to the dead-man ----------------------------------------------------------------
    def arm(self) -> int:
        """Post ARM; returns its heartbeat sequence number."""
        return self._post_heartbeat(Arm)

    def resume(self) -> int:
        """Post RESUME (the operator's explicit start or resume: also clears the dead-man's own
        hazard latch once the hazard has cleared); returns its sequence number."""
        return self._post_heartbeat(Resume)

    def disarm(self) -> int:
        """Post DISARM (stop at once, hold stop without heartbeats); returns its sequence number."""
        return self._post_heartbeat(Disarm)

    def command(self, command: VelocityCommand) -> int:
        """Post CMD (also a heartbeat); returns its sequence number."""
        return self._post_heartbeat(lambda beat: Command(command, beat))

    def raw(self, sub_payloads: bytes) -> None:
        self._post(RawCommand(sub_payloads))

    def _post_heartbeat(self, make: Callable[[Heartbeat], ControlMessage]) -> int:
        with self._send_lock:
            self._seq += 1
            self._post(make(Heartbeat(self._seq, time.monotonic())))
            return self._seq

    def _post(self, message: ControlMessage) -> None:
        try:
            self._control.send(encode_control(message), socket.MSG_DONTWAIT)
        except BlockingIOError:
            raise KobukiLinkError(
                f"{self.port}: the dead-man process is not reading commands") from None
        except OSError as exc:
            # gone: the relay says how once it has seen to the stop (a moment, bounded)
            self.wait_for(lambda: self.gone, self._config.close_timeout_s)
            raise KobukiLinkError(self.lost or f"{self.port}: the dead-man process is gone "
                                  f"({exc.strerror or exc})") from None

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        with self.cond:
            return self.cond.wait_for(predicate, timeout_s)

    def close(self) -> None:
        """Ask the dead-man to stop and exit, reap it (kill it, and write the stop ourselves, if
        it does not exit within close_timeout_s), stop the relay. Call once."""
        with self.cond:
            self.closing = True
        try:
            self._post(Close())
        except KobukiLinkError:
            pass  # already gone: it stopped the base on its way out (or the relay did)
        try:
            self.process.wait(timeout=self._config.close_timeout_s)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            with self.cond:
                opened = self.opened
            if opened:
                outcome = write_stop_directly(self.port, self._config.write_timeout_s)
                if not outcome.written:
                    with self.cond:
                        self.stop_failed = (f"{self.port}: the dead-man process did not exit "
                                            f"when closed: killed it; {outcome.line}")
        try:
            self._control.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._relay.join(timeout=self._config.close_timeout_s)
        with self.cond:
            emergency = self._emergency
        if emergency is not None:
            emergency.join(timeout=self._config.close_timeout_s + STOP_RETRY_S
                           + 2 * self._config.write_timeout_s)
        self._control.close()

    # ---- the relay thread -----------------------------------------------------------------------
    def _relay_messages(self) -> None:
        raise_priority()  # best effort: the watch and the emergency stop it starts must be on time
        silence_s = self._config.heartbeat_timeout_s
        last_report_s: float | None = None  # when the relay last received a WIRE report
        while True:
            data = self._receive(None if last_report_s is None else last_report_s + silence_s)
            if data is None:
                self._start_emergency_stop(f"stopped answering (no report for {silence_s:g} s)",
                                           kill=True)
                return
            if not data:
                self._on_end_of_stream()
                return
            try:
                message = decode_deadman(data)
            except (ValueError, UnicodeDecodeError):
                continue
            if isinstance(message, OnTheWire | PortOpened):
                last_report_s = time.monotonic()  # from the port's opening on, every write
            arrived_s = self._clock()
            with self.cond:
                self._apply(message, arrived_s)
                self.cond.notify_all()

    def _receive(self, deadline_s: float | None) -> bytes | None:
        control = self._control
        return receive_or_silence(
            lambda: control.recv(MAX_MESSAGE_BYTES, socket.MSG_DONTWAIT), deadline_s,
            time.monotonic, lambda wait_s: select.select([control], [], [], wait_s))

    def _apply(self, message: DeadmanMessage, arrived_s: float) -> None:
        if isinstance(message, FeedbackReceived):
            self._on_feedback(message, arrived_s)
        elif isinstance(message, OnTheWire):
            if message.command.is_stop and self.wire is not None and not self.wire.command.is_stop:
                self.motion_stopped_s = message.written_s
            self.wire = message
        elif isinstance(message, ModeChanged):
            self.mode, self.mode_reason = message.mode, message.reason
        elif isinstance(message, Hello):
            self.hello = message
        elif isinstance(message, PortOpened):
            self.opened, self.low_latency = True, message.low_latency
            self.priority_raised, self.priority = message.priority_raised, message.priority
        elif isinstance(message, OpenFailed):
            self.open_error = message.message
        elif isinstance(message, LinkLost):
            self.lost = message.message

    def _on_end_of_stream(self) -> None:
        """The dead-man closed its end: exited on its own (it stopped the base on its way out) or
        was killed by a signal it could not handle (then nobody did: write the stop ourselves)."""
        try:
            returncode = self.process.wait(timeout=self._config.close_timeout_s)
        except subprocess.TimeoutExpired:
            self.process.kill()
            returncode = self.process.wait()
        with self.cond:
            closing, opened = self.closing, self.opened
        if returncode == EXIT_LINK_LOST and opened:
            # The port failed under it (a device gone, a write that would not end): its own stop
            # went nowhere, also on its way out when asked to close. A device that comes back (a
            # USB glitch) gets the stop from here; the firmware would drive the last command
            # forever (an attacker's review).
            self._start_emergency_stop("lost the serial link", kill=False)
        elif closing:
            self._lose(None)
        elif returncode < 0 and opened:
            self._start_emergency_stop(f"was killed ({_signal_name(returncode)})", kill=False)
        else:
            self._lose(f"{self.port}: the dead-man process exited")

    def _start_emergency_stop(self, what: str, *, kill: bool) -> None:
        """Run `_emergency_stop` in a thread that is NOT a daemon: it finishes even when this
        process is on its way out (an exception in the main thread, a plain return)."""
        thread = threading.Thread(target=self._emergency_stop, args=(what, kill),
                                  name="kobuki-emergency-stop")
        with self.cond:
            self._emergency = thread
        thread.start()

    def _emergency_stop(self, what: str, kill: bool) -> None:
        """Kill the dead-man if asked (also while closing: a frozen dead-man would not act on
        CLOSE either), and once it is confirmed dead write the stop ourselves; then the link is
        lost, saying what happened."""
        if kill:
            self.process.kill()
            what += ": killed it"
        try:
            self.process.wait(timeout=self._config.close_timeout_s)
        except subprocess.TimeoutExpired:
            outcome = StopOutcome(False, "could not confirm it dead, so no stop was written: the "
                                  "base may still be driving its last command: switch it off")
        else:
            outcome = write_stop_directly(self.port, self._config.write_timeout_s)
        with self.cond:
            said = self.lost  # (the dead-man's own line, when it said why it ended)
        line = (f"{said}; {outcome.line}" if said else
                f"{self.port}: the dead-man process {what}; {outcome.line}")
        if not outcome.written:
            with self.cond:
                self.stop_failed = line
        self._lose(line, replace=True)

    def _lose(self, reason: str | None, *, replace: bool = False) -> None:
        with self.cond:
            self.gone = True
            if (self.lost is None or replace) and reason is not None:
                self.lost = reason
            self.cond.notify_all()
