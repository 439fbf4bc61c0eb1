"""A stop written after the link failed reaches the base (an attacker's review of the serial
side, with a Kobuki stand-in on a pty):

- A device that stopped reading, and reads again: the motion the OS held for it had been
  delivered after the stop was given up (the write timed out), so the base got 200 mm/s last.
  What is queued and not taken is now dropped first, and the stop comes last.
- A device that vanished (a USB glitch) and came back at its path: nothing reopened the port,
  and the run said "halted" while the firmware drove its last command. The port is now tried
  again for a while; a stop that never went out is said plainly.

Real pseudo-terminals and the real pyserial; the port reached through a link in the test's
folder, as udev's /dev/kobuki is."""

from __future__ import annotations

import os
import tty
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial

from lanewarden.actuation.deadman_logic import CLOSE_STOP_PACKETS
from lanewarden.actuation.kobuki_commands import STOP_PACKET, command_packet, encode_base_control
from lanewarden.actuation.kobuki_port import open_kobuki_serial, stop_through_port

MOTION = command_packet(encode_base_control(200, 0))


@pytest.fixture
def pty_device() -> Iterator[tuple[int, str]]:
    """(the device's end, the port's path): a raw pty nobody on the device's side reads yet."""
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    try:
        yield master, os.ttyname(slave)
    finally:
        os.close(master)
        os.close(slave)


def read_all(master: int) -> bytes:
    received = b""
    while True:
        try:
            chunk = os.read(master, 65536)
        except BlockingIOError:
            return received
        if not chunk:
            return received
        received += chunk


def test_a_stop_after_a_stall_comes_after_the_motion_held_back(
        pty_device: tuple[int, str]) -> None:
    master, port = pty_device
    link, _ = open_kobuki_serial(port, read_timeout_s=0.0, write_timeout_s=0.05)
    with pytest.raises(serial.SerialTimeoutException):  # the device reads nothing: it fills
        while True:
            link.write(MOTION)
    link.close()  # (the dead-man, killed for its silence)
    said = stop_through_port(port, STOP_PACKET, CLOSE_STOP_PACKETS, 0.5)
    assert said == (True, "a stop was written to the port directly")
    received = read_all(master)  # the device reads again
    assert received.endswith(STOP_PACKET * CLOSE_STOP_PACKETS)
    assert MOTION not in received[-len(STOP_PACKET) * CLOSE_STOP_PACKETS - len(MOTION):]


def test_a_device_that_comes_back_at_its_path_gets_the_stop(
        pty_device: tuple[int, str], tmp_path: Path) -> None:
    master, device = pty_device
    port = tmp_path / "kobuki"  # (absent: the device is gone)
    tries: list[float] = []

    def wait(seconds: float) -> None:  # between tries: the device is back after the second
        tries.append(seconds)
        if len(tries) == 2:
            port.symlink_to(device)

    written, said = stop_through_port(str(port), STOP_PACKET, CLOSE_STOP_PACKETS, 0.5, wait=wait)
    assert written and said.startswith("a stop was written to the port directly (at try 3, "), said
    assert read_all(master) == STOP_PACKET * CLOSE_STOP_PACKETS


def test_a_device_that_never_comes_back_is_said_plainly(tmp_path: Path) -> None:
    written, said = stop_through_port(str(tmp_path / "kobuki"), STOP_PACKET, CLOSE_STOP_PACKETS,
                                      0.5, retry_s=0.0)
    assert not written
    assert said.startswith("could not write a stop to the port (")
    assert said.endswith(", tried for 0 s): the base may still be driving its last command: "
                         "switch it off"), said
