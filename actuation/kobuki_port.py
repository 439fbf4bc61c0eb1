"""Finding and opening the Kobuki's serial port, and saying in one line what to do when we can't.

The only place pyserial's open errors are translated. `open_kobuki_serial` is called by the
dead-man process (the port's only owner); the rest is pure and shared with the control side.
Never writes to the port.
"""

from __future__ import annotations

import errno
import os
import time
from collections.abc import Callable, Sequence
from typing import NamedTuple

import serial

#: Where the Kobuki appears: the vendor udev rule's symlink, then the plain FTDI device.
DEFAULT_PORTS: tuple[str, ...] = ("/dev/kobuki", "/dev/ttyUSB0")
BAUD_RATE = 115200

UDEV_HINT = ("install the Kobuki udev rule (it creates /dev/kobuki and sets the FTDI latency "
             "timer to 1 ms)")
PERMISSION_HINT = ("add your user to the 'dialout' group (sudo usermod -aG dialout $USER, then "
                   f"log in again) or {UDEV_HINT}")
NO_FEEDBACK_HINT = ("is the base switched on and is this its port? a Kobuki streams feedback "
                    f"at 50 Hz; check the cable, or {UDEV_HINT}")


def is_url(port: str) -> bool:
    """A pyserial URL (loop://, socket://, ...) rather than a device path."""
    return "://" in port


def resolve_port(requested: str | None, candidates: Sequence[str] = DEFAULT_PORTS,
                 exists: Callable[[str], bool] = os.path.exists) -> str:
    """The port to open: `requested` if given, else the first default that exists.

    Raises LookupError (with the one-line reason) when nothing is requested and no default exists.
    """
    if requested:
        return requested
    for candidate in candidates:
        if exists(candidate):
            return candidate
    raise LookupError(
        f"no Kobuki port found (tried {', '.join(candidates)}): plug in and switch on the base, "
        f"pass --port, or {UDEV_HINT}"
    )


def describe_open_error(port: str, exc: BaseException) -> str:
    """One line naming the port, what went wrong and the likely fix."""
    code = getattr(exc, "errno", None)
    if code in (errno.EACCES, errno.EPERM):
        return f"{port}: permission denied: {PERMISSION_HINT}"
    if code in (errno.ENOENT, errno.ENODEV, errno.ENXIO):
        return (f"{port}: no such device: plug in and switch on the base, check --port, "
                f"or {UDEV_HINT}")
    if code in (errno.EAGAIN, errno.EWOULDBLOCK, errno.EBUSY):
        return (f"{port}: port is in use by another process (another lanewarden, or a ROS "
                "kobuki node?): stop it first")
    detail = " ".join(str(exc).split()) or type(exc).__name__
    return f"{port}: cannot open the serial port ({detail})"


def open_kobuki_serial(port: str, *, read_timeout_s: float,
                       write_timeout_s: float) -> tuple[serial.SerialBase, bool]:
    """Open `port` at 115200 8N1, no flow control, exclusively; low latency where supported.

    Returns (port, low_latency_enabled). Raises serial.SerialException / OSError / ValueError from
    pyserial unchanged: the caller translates them with `describe_open_error`.
    """
    link = serial.serial_for_url(
        port, baudrate=BAUD_RATE, bytesize=serial.EIGHTBITS, parity=serial.PARITY_NONE,
        stopbits=serial.STOPBITS_ONE, xonxoff=False, rtscts=False, dsrdtr=False,
        timeout=read_timeout_s, write_timeout=write_timeout_s,
        exclusive=None if is_url(port) else True,
    )
    low_latency = False
    set_low_latency = getattr(link, "set_low_latency_mode", None)
    if set_low_latency is not None:
        try:
            set_low_latency(True)
            low_latency = True
        except (ValueError, OSError):
            low_latency = False  # e.g. a pseudo-terminal: no serial_struct to set
    return link, low_latency


try:
    from termios import error as _TermiosError  # pyserial lets tcflush's through (not an OSError)
except ImportError:  # (not POSIX)
    class _TermiosError(Exception):  # type: ignore[no-redef]
        pass

#: pyserial's errors on a port that is gone, stalled or closed.
PORT_ERRORS = (serial.SerialException, OSError, ValueError, TypeError, _TermiosError)
#: A stop that could not reach the base is tried again, the port reopened, for this long (a USB
#: glitch or re-enumeration: udev brings the device back within about a second)...
STOP_RETRY_S = 2.0
#: ... every this many seconds.
STOP_RETRY_EVERY_S = 0.05
#: While a stop leaves the OS's buffer, how often the buffer is looked at.
_DRAIN_POLL_S = 0.002


def put_stop(link: serial.SerialBase, packet: bytes, count: int, drain_s: float) -> None:
    """Write `packet` (the stop) `count` times on `link`, first dropping what the OS holds for
    the device and it has not taken: a device that stopped reading and then reads again would get
    that motion before the stop (an attacker's review: 200 mm/s came last). Then wait up to
    `drain_s` for the stop to leave (pyserial's flush() is tcdrain, which waits without bound on
    a stalled adapter). Raises pyserial's errors (PORT_ERRORS) when the stop cannot be written."""
    try:
        link.reset_output_buffer()
    except PORT_ERRORS:
        pass  # (what cannot be dropped is sent first: the stop still comes after it)
    for _ in range(count):
        link.write(packet)
    deadline_s = time.monotonic() + drain_s
    while time.monotonic() < deadline_s:
        try:
            if not link.out_waiting:
                return
        except PORT_ERRORS:
            return  # (no way to tell: the stop is handed to the OS)
        time.sleep(_DRAIN_POLL_S)


class StopOutcome(NamedTuple):
    """Whether a stop went out (`written`), and one line saying so (`line`)."""

    written: bool
    line: str


def stop_through_port(port: str, packet: bytes, count: int, write_timeout_s: float,
                      retry_s: float = STOP_RETRY_S,
                      wait: Callable[[float], None] = time.sleep) -> StopOutcome:
    """Open `port` and put the stop on it (`put_stop`), trying again every STOP_RETRY_EVERY_S
    for `retry_s` while the port cannot be opened or written (a device that vanished may come
    back; `wait(seconds)` waits between tries). Whether the stop went out, and one line saying
    so (where it did not: that the base may still be driving its last command). Never raises. Call
    only when nothing else holds the port (two writers must never race)."""
    start_s = time.monotonic()
    tries = 0
    while True:
        tries += 1
        try:
            link, _ = open_kobuki_serial(port, read_timeout_s=0.0,
                                         write_timeout_s=write_timeout_s)
        except PORT_ERRORS as exc:
            why = describe_open_error(port, exc)
        else:
            try:
                put_stop(link, packet, count, write_timeout_s)
                return StopOutcome(True, "a stop was written to the port directly" + (
                    "" if tries == 1 else
                    f" (at try {tries}, {time.monotonic() - start_s:.2f} s after the first)"))
            except PORT_ERRORS as exc:
                why = " ".join(str(exc).split()) or type(exc).__name__
            finally:
                try:
                    link.close()
                except PORT_ERRORS:
                    pass
        if time.monotonic() - start_s >= retry_s:
            return StopOutcome(False, f"could not write a stop to the port ({why}, tried for "
                               f"{retry_s:g} s): the base may still be driving its last "
                               "command: switch it off")
        wait(STOP_RETRY_EVERY_S)
