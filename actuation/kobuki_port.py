"""Finding and opening the Kobuki's serial port, and saying in one line what to do when we can't.

The only place pyserial's open errors are translated. `open_kobuki_serial` is called by the
dead-man process (the port's only owner); the rest is pure and shared with the control side.
Never writes to the port.
"""

from __future__ import annotations

import errno
import os
from collections.abc import Callable, Sequence

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
