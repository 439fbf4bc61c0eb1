"""The dead-man process (`python -P -m lanewarden.actuation.deadman`): the only owner of the
Kobuki's port, and the base's safety monitor.

Started by KobukiBase (in a session of its own, so the terminal's job-control and quit signals
never reach it; with `-P`, so a `lanewarden/` folder in the current directory cannot stand in for
the installed code) with one end of a SOCK_SEQPACKET socketpair. It first trades HELLOs with the
control process and exits (EXIT_VERSION_MISMATCH) without touching the port unless both speak the
same protocol and package version. It raises its own scheduling priority where the OS permits
(SCHED_FIFO, else a negative nice value) so a loaded machine cannot starve its send loop, opens
the serial port, writes base control at the steady command rate (changed or not), reports every
write to the control process (`WIRE`, its own heartbeat), relays every valid feedback payload and
its link health, and follows `DeadmanLogic`: when the control process goes silent or away, or a
feedback packet shows a bumper, cliff or wheel drop, or feedback goes stale, the base is stopped
at once and kept stopped; every command it forwards is kept inside the base's envelope.
On SIGTERM, SIGINT, SIGHUP, SIGQUIT, an internal error or a CLOSE message: stop, flush, exit.
Even SIGTSTP sent to it directly does not stop it (its process group is orphaned, and the kernel
discards job-control stops there); only SIGSTOP can freeze it, and then the control process
notices its silence, kills it and writes the stop itself.

This is the thin shell around `DeadmanLogic`: the only code here that reads time.monotonic.
It must never exit without trying to put a stop on the wire, and never block on the control
process (messages to it are dropped when it does not read).
"""

from __future__ import annotations

import argparse
import os
import select
import signal
import socket
import sys
import threading
import time
from collections import deque
from collections.abc import Sequence
from types import FrameType

import serial

from lanewarden.actuation.deadman_logic import (
    DeadmanLogic,
    DeadmanSettings,
    Envelope,
    SafetySensors,
)
from lanewarden.actuation.deadman_messages import (
    MAX_MESSAGE_BYTES,
    Arm,
    Close,
    Command,
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
    decode_control,
    decode_hello,
    encode_deadman,
    version_mismatch,
)
from lanewarden.actuation.kobuki_commands import STOP_PACKET, command_packet, encode_velocity
from lanewarden.actuation.kobuki_feedback import decode_feedback
from lanewarden.actuation.kobuki_framing import PacketReader
from lanewarden.actuation.kobuki_port import (
    PORT_ERRORS,
    describe_open_error,
    open_kobuki_serial,
    put_stop,
)
from lanewarden.actuation.realtime import raise_priority, spare_from_oom

EXIT_OK = 0
EXIT_OPEN_FAILED = 3
EXIT_LINK_LOST = 4
EXIT_INTERNAL_ERROR = 5
EXIT_VERSION_MISMATCH = 6

#: How long to wait for the control process's HELLO (it sends it right after starting us).
HELLO_TIMEOUT_S = 10.0

#: Serial read timeout of the feedback thread (bounds how long stopping it takes).
READ_TIMEOUT_S = 0.05
#: Control messages handled per wake-up before the send loop polls again.
MAX_MESSAGES_PER_WAKE = 64


def _lost_message(port: str, exc: BaseException) -> str:
    detail = " ".join(str(exc).split()) or type(exc).__name__
    return (f"{port}: serial link lost ({detail}): check the USB cable and that the base is "
            "switched on")


class DeadmanProcess:
    def __init__(self, port: str, control: socket.socket, settings: DeadmanSettings,
                 write_timeout_s: float, priority: tuple[bool, str] = (False, "normal")) -> None:
        self._port = port
        self._priority = priority
        self._control: socket.socket | None = control
        self._settings = settings
        self._write_timeout_s = write_timeout_s
        self._link: serial.SerialBase | None = None
        self._packets = PacketReader()
        # feedback thread -> main loop, in order: each packet's hazard bits (None: no basic
        # sensor data in it) and the message relaying it to the control process
        self._from_base: deque[tuple[SafetySensors | None, FeedbackReceived]] = deque()
        self._mode: ModeChanged | None = None  # the newest MODE told
        self._dropped = False  # a message could not be sent: tell the MODE again first
        self._reading = threading.Event()
        self._lost: str | None = None
        self._signal: int | None = None
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)

    # ---- talking to the control process (never blocks) ----------------------------------------
    def _tell(self, message: DeadmanMessage) -> None:
        """Send `message` if the socket takes it now. When a message had to be dropped (the
        control process frozen, its socket full), the current MODE goes again first once the
        socket takes messages again, so a control process that was frozen through a latch still
        learns of it. Called from the main loop only."""
        control = self._control
        if control is None:
            return
        if isinstance(message, ModeChanged):
            self._mode = message
        if self._dropped and self._mode is not None and message is not self._mode:
            if not self._send(control, self._mode):
                return
        self._dropped = not self._send(control, message)

    @staticmethod
    def _send(control: socket.socket, message: DeadmanMessage) -> bool:
        try:
            control.send(encode_deadman(message), socket.MSG_DONTWAIT)
        except OSError:
            return False  # full (control process frozen) or gone: feedback is stale either way
        return True

    def _wake(self) -> None:
        try:
            os.write(self._wake_w, b"!")
        except OSError:
            pass

    # ---- the feedback thread ------------------------------------------------------------------
    def _read_feedback(self) -> None:
        link = self._link
        assert link is not None
        try:
            while self._reading.is_set():
                data = link.read(max(1, link.in_waiting))
                for payload in self._packets.feed(data):
                    basic = decode_feedback(payload).basic
                    sensors = None if basic is None else SafetySensors(
                        time.monotonic(), basic.bumper, basic.cliff, basic.wheel_drop,
                        basic.timestamp_ms)
                    # the main loop judges the hazard bits at once, then relays the packet
                    self._from_base.append(
                        (sensors, FeedbackReceived(self._packets.checksum_errors, payload)))
                    self._wake()
        except PORT_ERRORS as exc:
            if self._reading.is_set():
                self._lost = _lost_message(self._port, exc)
                self._wake()

    # ---- the main loop ------------------------------------------------------------------------
    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self._signal = signum

    def handshake(self) -> str | None:
        """Send our HELLO, read the control process's: None when both speak the same protocol
        and package version, else why not (then the port must not be touched)."""
        ours = Hello.ours()
        self._tell(ours)
        control = self._control
        assert control is not None
        ready, _, _ = select.select([control.fileno(), self._wake_r], [], [], HELLO_TIMEOUT_S)
        if control.fileno() not in ready:
            return "no HELLO from the control process"
        try:
            data = control.recv(MAX_MESSAGE_BYTES)
            theirs = decode_hello(data)
        except (OSError, ValueError, UnicodeDecodeError) as exc:
            return f"the control process did not say HELLO ({exc})"
        return version_mismatch(ours, theirs)

    def run(self) -> int:
        if self.handshake() is not None:
            return EXIT_VERSION_MISMATCH  # the control side names the mismatch; nothing moved
        try:
            self._link, low_latency = open_kobuki_serial(
                self._port, read_timeout_s=READ_TIMEOUT_S, write_timeout_s=self._write_timeout_s)
        except PORT_ERRORS as exc:
            self._tell(OpenFailed(describe_open_error(self._port, exc)))
            return EXIT_OPEN_FAILED
        self._tell(PortOpened(low_latency, *self._priority))
        self._reading.set()
        reader = threading.Thread(target=self._read_feedback, name="kobuki-feedback",
                                  daemon=True)
        reader.start()
        try:
            return self._loop()
        except PORT_ERRORS as exc:
            self._tell(LinkLost(_lost_message(self._port, exc)))
            return EXIT_LINK_LOST
        except BaseException as exc:  # noqa: BLE001 - the stop below must happen whatever failed
            self._tell(LinkLost(f"{self._port}: dead-man process failed ({exc!r})"))
            return EXIT_INTERNAL_ERROR
        finally:
            self._shutdown(reader)

    def _loop(self) -> int:
        logic = DeadmanLogic(self._settings, time.monotonic())
        link = self._link
        assert link is not None
        relay: list[FeedbackReceived] = []
        while True:
            action = logic.poll(time.monotonic())
            if action.send is not None:
                link.write(command_packet(encode_velocity(action.send)))
                written_s = time.monotonic()
            for event in action.events:
                self._tell(ModeChanged(event.mode, event.reason))
            # after the MODE a packet caused: the control process never sees a hazard bit
            # before the latch it caused
            for message in relay:
                self._tell(message)
            relay.clear()
            if action.send is not None:
                self._tell(OnTheWire(logic.heartbeat_seq, written_s, action.send))
            if action.finished:
                return EXIT_OK
            if self._lost is not None:
                self._tell(LinkLost(self._lost))
                return EXIT_LINK_LOST
            waiting_on = [self._wake_r] + ([self._control] if self._control else [])
            timeout_s = max(0.0, logic.next_wakeup_s() - time.monotonic())
            ready, _, _ = select.select(waiting_on, [], [], timeout_s)
            now = time.monotonic()
            if self._wake_r in ready:
                self._drain_wake_pipe()
            if self._signal is not None:
                logic.on_close(now, f"stopped by signal {signal.Signals(self._signal).name}")
            while self._from_base:  # before the control messages: a RESUME sees the newest state
                sensors, message = self._from_base.popleft()
                if sensors is not None:
                    logic.on_feedback(now, sensors)
                else:
                    logic.on_packet_without_sensors()
                relay.append(message)
            if self._control is not None and self._control in ready:
                self._receive(logic, link)

    def _receive(self, logic: DeadmanLogic, link: serial.SerialBase) -> None:
        assert self._control is not None
        for _ in range(MAX_MESSAGES_PER_WAKE):  # then back to poll: a flood cannot starve it
            try:
                data = self._control.recv(MAX_MESSAGE_BYTES, socket.MSG_DONTWAIT)
            except BlockingIOError:
                return
            except OSError:
                data = b""
            # read after the message arrived: its sender's stamp is never later than this
            now = time.monotonic()
            if not data:
                logic.on_control_gone(now)
                self._control.close()
                self._control = None
                return
            try:
                message = decode_control(data)
            except (ValueError, UnicodeDecodeError) as exc:
                logic.on_malformed(now, str(exc))
                continue
            if isinstance(message, Arm):
                logic.on_arm(now, message.heartbeat)
            elif isinstance(message, Resume):
                logic.on_resume(now, message.heartbeat)
            elif isinstance(message, Disarm):
                logic.on_disarm(now, message.heartbeat)
            elif isinstance(message, Command):
                logic.on_command(message.command, now, message.heartbeat)
            elif isinstance(message, RawCommand):
                link.write(command_packet(message.sub_payloads))
            elif isinstance(message, Close):
                logic.on_close(now)

    def _drain_wake_pipe(self) -> None:
        try:
            while os.read(self._wake_r, 512):
                pass
        except BlockingIOError:
            pass

    def _shutdown(self, reader: threading.Thread) -> None:
        """Last words: one more stop (what is queued for a device that stopped reading dropped
        first, its leaving waited for within the write timeout: `kobuki_port.put_stop`), close.
        Never raises."""
        self._reading.clear()
        link = self._link
        if link is not None:
            try:
                put_stop(link, STOP_PACKET, 1, self._write_timeout_s)
            except PORT_ERRORS:
                pass
            reader.join(timeout=4 * READ_TIMEOUT_S)
            try:
                link.close()
            except PORT_ERRORS:
                pass
        if self._control is not None:
            self._control.close()

    def install_signal_handlers(self) -> None:
        signal.set_wakeup_fd(self._wake_w)
        for signum in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGQUIT):
            signal.signal(signum, self._on_signal)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lanewarden.actuation.deadman",
                                     description="Own the Kobuki's port; stop it if we go quiet.")
    parser.add_argument("--port", required=True)
    parser.add_argument("--control-fd", type=int, required=True)
    parser.add_argument("--command-rate-hz", type=float, default=50.0)
    parser.add_argument("--heartbeat-timeout-s", type=float, default=0.2)
    parser.add_argument("--orphan-stop-s", type=float, default=0.5)
    parser.add_argument("--write-timeout-s", type=float, default=0.5)
    parser.add_argument("--feedback-timeout-s", type=float, default=0.2)
    envelope = Envelope()
    parser.add_argument("--max-linear-m-s", type=float, default=envelope.max_linear_m_s)
    parser.add_argument("--max-angular-rad-s", type=float, default=envelope.max_angular_rad_s)
    parser.add_argument("--max-linear-accel-m-s2", type=float,
                        default=envelope.max_linear_accel_m_s2)
    parser.add_argument("--max-angular-accel-rad-s2", type=float,
                        default=envelope.max_angular_accel_rad_s2)
    args = parser.parse_args(argv)
    control = socket.socket(fileno=args.control_fd)
    settings = DeadmanSettings(
        heartbeat_timeout_s=args.heartbeat_timeout_s, command_period_s=1.0 / args.command_rate_hz,
        orphan_stop_s=args.orphan_stop_s, feedback_timeout_s=args.feedback_timeout_s,
        envelope=Envelope(args.max_linear_m_s, args.max_angular_rad_s,
                          args.max_linear_accel_m_s2, args.max_angular_accel_rad_s2))
    spare_from_oom()  # (best effort, as the priority: root only)
    process = DeadmanProcess(args.port, control, settings, args.write_timeout_s,
                             raise_priority())
    process.install_signal_handlers()
    return process.run()


if __name__ == "__main__":
    sys.exit(main())
