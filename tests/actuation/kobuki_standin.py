"""A stand-in Kobuki on a pseudo-terminal, written from ../shared/docs/kobuki-protocol.md only.

TEST code (never shipped, and deliberately independent of actuation's codec so the two cannot
share a bug): it streams a feedback packet with every sub-payload at 50 Hz (LEN 0x4D), answers
Request Extra with hardware/firmware version and UDID, moves its encoders according to the last
base-control command, and records every command packet it receives with its arrival time
(time.monotonic, comparable across processes).

Use `port` as the serial port: a link to the pty slave (`device`), as udev's /dev/kobuki is, in a
folder of its own. `unplug()` removes it with the pty: a driver trying the port again (a stop
after the link failed) never reaches a pty another test opened later under the same number.
`sensor_changes` lists when a feedback packet first carried each new (bumper, cliff, wheel drop)
state (the time just before its write);
`press(...)` sets the bits and returns that time for them.
`unplug()` closes the master under the driver (and removes `port`). `unplug_on_motion=True` does
that on the first non-zero base-control command.
`corrupt_every=N` spoils the checksum of every Nth feedback packet.
"""

from __future__ import annotations

import math
import os
import select
import shutil
import struct
import tempfile
import threading
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType

STOP_PACKET = bytes.fromhex("AA 55 06 01 04 00 00 00 00 03")
TICKS_PER_METRE = 2578.33 / (2 * math.pi * 0.035)
HALF_WHEEL_BASE_MM = 115.0


def _frame(payload: bytes) -> bytes:
    cs = len(payload)
    for byte in payload:
        cs ^= byte
    return b"\xaa\x55" + bytes([len(payload)]) + payload + bytes([cs])


@dataclass(frozen=True)
class ReceivedPacket:
    arrival_s: float
    packet: bytes  # the whole frame as received

    @property
    def payload(self) -> bytes:
        return self.packet[3:-1]

    @property
    def base_control(self) -> tuple[int, int] | None:
        """(speed mm/s, radius mm) when this packet is a lone base-control command."""
        payload = self.payload
        if len(payload) == 6 and payload[0] == 1 and payload[1] == 4:
            speed, radius = struct.unpack("<hh", payload[2:6])
            return speed, radius
        return None


class KobukiStandIn:
    def __init__(self, *, stream: bool = True, period_s: float = 0.02,
                 unplug_on_motion: bool = False, corrupt_every: int = 0) -> None:
        self.stream = stream
        self.corrupt_every = corrupt_every
        self.period_s = period_s
        self.unplug_on_motion = unplug_on_motion
        self.hardware_version = (1, 0, 4)
        self.firmware_version = (1, 2, 0)
        self.udid = (0x12345678, 0x9ABCDEF0, 0x0BADCAFE)
        self.battery_dv = 162
        self.bumper = 0
        self.cliff = 0
        self.wheel_drop = 0
        self.buttons = 0
        #: a device replaying one packet: the base's time stamp no longer advances
        self.replaying = False
        self.received: list[ReceivedPacket] = []
        self.sensor_changes: list[tuple[float, tuple[int, int, int]]] = []
        self.feedback_sent = 0
        self._cond = threading.Condition()
        self._write_lock = threading.Lock()
        self._running = threading.Event()
        self._unplugging = threading.Event()
        self._speed_radius = (0, 0)
        # start near the u16 wrap so a drive crosses it
        self._left_ticks = 65500.0
        self._right_ticks = 65500.0
        self._timestamp_ms = 0
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no line discipline, before anyone reads
        os.set_blocking(self._master, False)
        self.device = os.ttyname(self._slave)
        self._link_folder = tempfile.mkdtemp(prefix="kobuki-standin-")
        self.port = os.path.join(self._link_folder, "kobuki")
        os.symlink(self.device, self.port)
        self._threads = [threading.Thread(target=self._stream_feedback, daemon=True),
                         threading.Thread(target=self._read_commands, daemon=True)]
        self._unplugged = False

    # ---- lifecycle ----------------------------------------------------------------------------
    def __enter__(self) -> KobukiStandIn:
        self._running.set()
        for thread in self._threads:
            thread.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.unplug()

    def unplug(self) -> None:
        """Close the pty under the driver (the USB cable pulled)."""
        self._running.clear()
        self._unplugging.set()
        for thread in self._threads:
            if thread is not threading.current_thread() and thread.ident is not None:
                thread.join(timeout=2.0)
        with self._cond:
            if not self._unplugged:
                self._unplugged = True
                shutil.rmtree(self._link_folder, ignore_errors=True)  # (gone from its path first)
                os.close(self._master)
                os.close(self._slave)
            self._cond.notify_all()

    # ---- what the tests look at ---------------------------------------------------------------
    def set_sensors(self, *, bumper: int | None = None, cliff: int | None = None,
                    wheel_drop: int | None = None) -> None:
        with self._cond:
            self.bumper = self.bumper if bumper is None else bumper
            self.cliff = self.cliff if cliff is None else cliff
            self.wheel_drop = self.wheel_drop if wheel_drop is None else wheel_drop

    def wait_for(self, predicate: Callable[[list[ReceivedPacket]], bool],
                 timeout_s: float) -> bool:
        """Wait until `predicate(received packets)` holds, up to `timeout_s`."""
        with self._cond:
            return self._cond.wait_for(lambda: predicate(self.received), timeout_s)

    def press(self, *, bumper: int | None = None, cliff: int | None = None,
              wheel_drop: int | None = None, timeout_s: float = 5.0) -> float:
        """`set_sensors(...)`, then wait for the first feedback packet carrying the new bits:
        the time just before its write (time.monotonic). RuntimeError if none within
        `timeout_s`."""
        since_s = time.monotonic()
        self.set_sensors(bumper=bumper, cliff=cliff, wheel_drop=wheel_drop)
        with self._cond:
            state = (self.bumper, self.cliff, self.wheel_drop)

            def written() -> float | None:
                return next((t for t, bits in self.sensor_changes
                             if t >= since_s and bits == state), None)

            if not self._cond.wait_for(lambda: written() is not None, timeout_s):
                raise RuntimeError(f"the stand-in wrote no packet with the bits {state}")
            when = written()
        assert when is not None
        return when

    def snapshot(self) -> list[ReceivedPacket]:
        with self._cond:
            return list(self.received)

    def base_controls(self) -> list[tuple[float, tuple[int, int]]]:
        return [(p.arrival_s, bc) for p in self.snapshot() if (bc := p.base_control) is not None]

    # ---- the simulated base -------------------------------------------------------------------
    def _write(self, packet: bytes) -> float:
        """Write `packet` to the driver; returns the time just before the write."""
        with self._write_lock:
            sent_s = time.monotonic()
            if not self._running.is_set():
                return sent_s
            try:
                os.write(self._master, packet)
            except (BlockingIOError, OSError):
                pass  # nobody reading the slave: a real UART drops bytes too
            return sent_s

    def _feedback_packet(self, hazards: tuple[int, int, int]) -> bytes:
        bumper, cliff, wheel_drop = hazards
        with self._cond:
            speed, radius = self._speed_radius
            if radius == 0:
                left_mm_s = right_mm_s = float(speed)
            elif radius == 1:
                left_mm_s, right_mm_s = -float(speed), float(speed)
            else:
                omega = speed / (radius + math.copysign(HALF_WHEEL_BASE_MM, radius))
                left_mm_s = omega * (radius - HALF_WHEEL_BASE_MM)
                right_mm_s = omega * (radius + HALF_WHEEL_BASE_MM)
            self._left_ticks += left_mm_s / 1000.0 * self.period_s * TICKS_PER_METRE
            self._right_ticks += right_mm_s / 1000.0 * self.period_s * TICKS_PER_METRE
            if not self.replaying:
                self._timestamp_ms = (self._timestamp_ms + round(self.period_s * 1000)) % 65536
            basic = struct.pack("<HBBBHHbbBBBB", self._timestamp_ms, bumper,
                                wheel_drop, cliff,
                                int(self._left_ticks) % 65536, int(self._right_ticks) % 65536,
                                0, 0, self.buttons, 0, self.battery_dv, 0)
        subs = [
            (1, basic),
            (3, bytes([0, 0, 0])),
            (4, struct.pack("<hh", 1234, -5) + bytes(3)),
            (5, struct.pack("<HHH", 2000, 2100, 2200)),
            (6, bytes([12, 13])),
            (13, bytes([7, 6]) + struct.pack("<6h", 1, 2, 3, 4, 5, 6)),
            (16, struct.pack("<HHHHH", 0x0F, 10, 20, 30, 40) + bytes(6)),
        ]
        return _frame(b"".join(bytes([sub_id, len(data)]) + data for sub_id, data in subs))

    def _stream_feedback(self) -> None:
        # paces the simulated hardware's 50 Hz stream (this is the device, not a test waiting)
        next_s = time.monotonic()
        while self._running.is_set():
            if self.stream:
                with self._cond:
                    hazards = (self.bumper, self.cliff, self.wheel_drop)
                packet = self._feedback_packet(hazards)
                self.feedback_sent += 1
                corrupt = self.corrupt_every and self.feedback_sent % self.corrupt_every == 0
                if corrupt:
                    packet = packet[:-1] + bytes([packet[-1] ^ 0x5A])  # bad checksum
                sent_s = self._write(packet)
                with self._cond:
                    if not corrupt and (not self.sensor_changes
                                        or self.sensor_changes[-1][1] != hazards):
                        self.sensor_changes.append((sent_s, hazards))
                        self._cond.notify_all()
            next_s += self.period_s
            self._unplugging.wait(max(0.0, next_s - time.monotonic()))

    def _answer_request_extra(self, flags: int) -> None:
        subs = b""
        if flags & 0x01:
            subs += bytes([10, 4]) + struct.pack("<I", self._version(self.hardware_version))
        if flags & 0x02:
            subs += bytes([11, 4]) + struct.pack("<I", self._version(self.firmware_version))
        if flags & 0x08:
            subs += bytes([19, 12]) + struct.pack("<III", *self.udid)
        if subs:
            self._write(_frame(subs))

    @staticmethod
    def _version(version: tuple[int, int, int]) -> int:
        return (version[0] << 16) | (version[1] << 8) | version[2]

    def _read_commands(self) -> None:
        buffer = bytearray()
        while self._running.is_set():
            try:
                ready, _, _ = select.select([self._master], [], [], 0.05)
                data = os.read(self._master, 4096) if ready else b""
            except BlockingIOError:
                continue
            except OSError:
                data = b""  # slave side not open (EIO): nothing to read yet
            if not data:
                continue
            arrival_s = time.monotonic()
            buffer += data
            while True:
                start = buffer.find(b"\xaa\x55")
                if start < 0:
                    del buffer[:-1]
                    break
                del buffer[:start]
                if len(buffer) < 3 or len(buffer) < buffer[2] + 4:
                    break
                packet = bytes(buffer[:buffer[2] + 4])
                cs = 0
                for byte in packet[2:]:
                    cs ^= byte
                if cs != 0:
                    del buffer[:1]
                    continue
                del buffer[:len(packet)]
                self._on_command(ReceivedPacket(arrival_s, packet))

    def _on_command(self, received: ReceivedPacket) -> None:
        payload = received.payload
        unplug = False
        with self._cond:
            self.received.append(received)
            control = received.base_control
            if control is not None:
                self._speed_radius = control
                unplug = self.unplug_on_motion and control != (0, 0)
            self._cond.notify_all()
        if len(payload) == 4 and payload[0] == 9 and payload[1] == 2:
            self._answer_request_extra(struct.unpack("<H", payload[2:4])[0])
        if unplug:
            threading.Thread(target=self.unplug, daemon=True).start()
