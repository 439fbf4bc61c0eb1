"""Port resolution and the one-line open errors (the real pyserial error types at the boundary)."""

from __future__ import annotations

import errno
from pathlib import Path

import pytest
import serial

from lanewarden.actuation.kobuki_port import describe_open_error, open_kobuki_serial, resolve_port


def test_requested_port_wins() -> None:
    assert resolve_port("/dev/ttyACM3", exists=lambda path: False) == "/dev/ttyACM3"


def test_default_order_is_kobuki_then_ttyusb0() -> None:
    assert resolve_port(None, exists=lambda path: True) == "/dev/kobuki"
    assert resolve_port(None, exists=lambda path: path == "/dev/ttyUSB0") == "/dev/ttyUSB0"


def test_no_port_anywhere_names_both_and_the_fix() -> None:
    with pytest.raises(LookupError) as info:
        resolve_port(None, exists=lambda path: False)
    message = str(info.value)
    assert "/dev/kobuki" in message and "/dev/ttyUSB0" in message and "udev" in message
    assert "\n" not in message


@pytest.mark.parametrize(("code", "expected"), [
    (errno.EACCES, "dialout"), (errno.EPERM, "udev rule"), (errno.ENOENT, "no such device"),
    (errno.EAGAIN, "in use by another process"), (errno.EIO, "cannot open the serial port"),
])
def test_open_errors_are_one_line_with_the_port_and_fix(code: int, expected: str) -> None:
    exc = serial.SerialException(code, f"could not open port /dev/kobuki: [Errno {code}]\nx")
    message = describe_open_error("/dev/kobuki", exc)
    assert message.startswith("/dev/kobuki: ")
    assert expected in message
    assert "\n" not in message


def test_permission_hint_names_group_and_udev_rule() -> None:
    message = describe_open_error("/dev/ttyUSB0", PermissionError(errno.EACCES, "denied"))
    assert "dialout" in message and "udev" in message


def test_opening_a_missing_device_raises_what_describe_understands(tmp_path: Path) -> None:
    missing = str(tmp_path / "ttyKobuki")
    with pytest.raises(serial.SerialException) as info:
        open_kobuki_serial(missing, read_timeout_s=0.01, write_timeout_s=0.01)
    assert "no such device" in describe_open_error(missing, info.value)


def test_loop_url_opens_without_low_latency_support() -> None:
    link, low_latency = open_kobuki_serial("loop://", read_timeout_s=0.01, write_timeout_s=0.01)
    try:
        assert link.baudrate == 115200 and (link.bytesize, link.parity, link.stopbits) == (
            8, "N", 1)
        assert low_latency is False
    finally:
        link.close()
