"""The control <-> dead-man messages: round trips, and strict rejection of anything malformed."""

from __future__ import annotations

import pytest

from lanewarden.actuation.base import VelocityCommand
from lanewarden.actuation.deadman_logic import DeadmanMode
from lanewarden.actuation.deadman_messages import (
    Arm,
    Close,
    Command,
    ControlMessage,
    DeadmanMessage,
    FeedbackReceived,
    LinkLost,
    ModeChanged,
    OpenFailed,
    PortOpened,
    RawCommand,
    check_non_motion,
    decode_control,
    decode_deadman,
    encode_control,
    encode_deadman,
)
from lanewarden.actuation.kobuki_commands import encode_request_extra, encode_sound


@pytest.mark.parametrize("message", [
    Arm(), Close(), Command(VelocityCommand(0.1234567890123, -1e-9)),
    Command(VelocityCommand(0.0, 0.0)),
    RawCommand(encode_request_extra(0x0B) + encode_sound(440.0, 10)),
])
def test_control_round_trip(message: ControlMessage) -> None:
    assert decode_control(encode_control(message)) == message


@pytest.mark.parametrize("message", [
    PortOpened(True), PortOpened(False), OpenFailed("/dev/x: permission denied: add ..."),
    FeedbackReceived(3, bytes(range(77))), ModeChanged(DeadmanMode.TRIPPED, "no heartbeat"),
    LinkLost("/dev/x: serial link lost (EIO)"),
])
def test_deadman_round_trip(message: DeadmanMessage) -> None:
    assert decode_deadman(encode_deadman(message)) == message


def test_multi_line_text_becomes_one_line() -> None:
    message = decode_deadman(encode_deadman(LinkLost("a\nb\t c")))
    assert message == LinkLost("a b c")


@pytest.mark.parametrize("data", [
    b"", b"ARM now", b"CMD 0.1", b"CMD 0.1 nan", b"CMD inf 0", b"CMD a b", b"GO 1 2",
    b"RAW", b"RAW zz", b"RAW 01040000", b"RAW 0104000000000000",  # base control via RAW
    b"RAW 0902", b"RAW 09020b", b"\xff\xfe",
])
def test_malformed_control_messages_are_rejected(data: bytes) -> None:
    with pytest.raises((ValueError, UnicodeDecodeError)):
        decode_control(data)


def test_raw_may_not_carry_motion() -> None:
    with pytest.raises(ValueError, match="base control"):
        check_non_motion(encode_sound(440.0, 1) + bytes([1, 4, 100, 0, 0, 0]))
    check_non_motion(encode_request_extra(1))


@pytest.mark.parametrize("data", [b"", b"OPEN 2", b"FB x 00", b"FB 1 zz", b"MODE flying x",
                                  b"HELLO"])
def test_malformed_deadman_messages_are_rejected(data: bytes) -> None:
    with pytest.raises(ValueError):
        decode_deadman(data)
