"""The control <-> dead-man messages: round trips, and strict rejection of anything malformed."""

from __future__ import annotations

import pytest

from lanewarden.actuation.base import VelocityCommand
from lanewarden.actuation.deadman_logic import DeadmanMode, Heartbeat
from lanewarden.actuation.deadman_messages import (
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
    check_non_motion,
    decode_control,
    decode_deadman,
    decode_hello,
    encode_control,
    encode_deadman,
    version_mismatch,
)
from lanewarden.actuation.kobuki_commands import encode_request_extra, encode_sound

BEAT = Heartbeat(17, 12345.678901234)


@pytest.mark.parametrize("message", [
    Arm(BEAT), Resume(Heartbeat(18, 12345.7)), Disarm(Heartbeat(0, 1e-07)), Close(),
    Command(VelocityCommand(0.1234567890123, -1e-9), BEAT),
    Command(VelocityCommand(0.0, 0.0), Heartbeat(999_999_999, 3.0e5)),
    RawCommand(encode_request_extra(0x0B) + encode_sound(440.0, 10)),
])
def test_control_round_trip(message: ControlMessage) -> None:
    assert decode_control(encode_control(message)) == message


def test_heartbeats_are_written_as_sequence_then_stamp() -> None:
    assert encode_control(Command(VelocityCommand(0.25, -0.5), Heartbeat(3, 812.5))) == \
        b"CMD 3 812.5 0.25 -0.5"
    assert encode_control(Arm(Heartbeat(0, 1.0))) == b"ARM 0 1.0"
    assert encode_control(Resume(Heartbeat(5, 3.0))) == b"RESUME 5 3.0"
    assert encode_control(Disarm(Heartbeat(4, 2.0))) == b"DISARM 4 2.0"
    assert encode_deadman(OnTheWire(3, 7.25, VelocityCommand(0.0, 0.0))) == b"WIRE 3 7.25 0.0 0.0"


@pytest.mark.parametrize("message", [
    PortOpened(True, True, "SCHED_FIFO 10"), PortOpened(False, False, "normal priority: no"),
    OpenFailed("/dev/x: permission denied: add ..."),
    OnTheWire(-1, 0.5, VelocityCommand(0.0, 0.0)),
    OnTheWire(41, 81234.123456789, VelocityCommand(0.2, -1e-3)),
    FeedbackReceived(3, bytes(range(77))), ModeChanged(DeadmanMode.TRIPPED, "no heartbeat"),
    ModeChanged(DeadmanMode.LATCHED, "bumper pressed (left)"),
    Hello(2, "0.1.0", "/home/me/my lanewarden/lanewarden"),
    LinkLost("/dev/x: serial link lost (EIO)"),
])
def test_deadman_round_trip(message: DeadmanMessage) -> None:
    assert decode_deadman(encode_deadman(message)) == message


def test_multi_line_text_becomes_one_line() -> None:
    message = decode_deadman(encode_deadman(LinkLost("a\nb\t c")))
    assert message == LinkLost("a b c")


@pytest.mark.parametrize("data", [
    b"", b"ARM", b"ARM now", b"ARM 1", b"ARM -1 2.0", b"ARM 1 nan", b"ARM 1 inf", b"ARM 1_0 2.0",
    b"ARM 1 2.0 3", b"DISARM", b"DISARM 1 1e999", b"CMD 0.1", b"CMD 0.1 0.2",
    b"CMD 1 2.0 0.1 nan", b"CMD 1 2.0 inf 0", b"CMD 1 2.0 a b", b"CMD 1.5 2.0 0 0",
    b"CMD 1 2.0 0 0 0", b"CMD 1 2.0 1_0 0", b"CMD 1 2.0  0", b"CMD +1 2.0 0 0", b"GO 1 2",
    b"RAW", b"RAW zz", b"RAW 01040000", b"RAW 0104000000000000",  # base control via RAW
    b"RAW 0902", b"RAW 09020b", b"\xff\xfe", b"RESUME", b"RESUME 1 nan", b"RESUME 1 2.0 3",
    b"HELLO 2 0.1.0 /x",  # HELLO only as the first message, read by decode_hello
])
def test_malformed_control_messages_are_rejected(data: bytes) -> None:
    with pytest.raises((ValueError, UnicodeDecodeError)):
        decode_control(data)


def test_raw_may_not_carry_motion() -> None:
    with pytest.raises(ValueError, match="base control"):
        check_non_motion(encode_sound(440.0, 1) + bytes([1, 4, 100, 0, 0, 0]))
    check_non_motion(encode_request_extra(1))


@pytest.mark.parametrize("data", [b"", b"OPEN 2", b"OPEN 1", b"OPEN 1 2 x", b"OPEN 1 1 ",
                                  b"FB x 00", b"FB 1 zz", b"MODE flying x", b"HELLO", b"WIRE",
                                  b"WIRE 1 0.0 0.0", b"WIRE -2 1.0 0.0 0.0",
                                  b"WIRE 1 1.0 nan 0.0", b"WIRE 1 inf 0.0 0.0",
                                  b"WIRE 1 1.0 0.0 0.0 0.0"])
def test_malformed_deadman_messages_are_rejected(data: bytes) -> None:
    with pytest.raises(ValueError):
        decode_deadman(data)


def test_hello_is_one_fixed_layout_both_ways() -> None:
    hello = Hello(2, "0.1.0", "/opt/lanewarden")
    assert encode_control(hello) == encode_deadman(hello) == b"HELLO 2 0.1.0 /opt/lanewarden"
    assert decode_hello(b"HELLO 2 0.1.0 /opt/lanewarden") == hello
    for data in (b"ARM 1 2.0", b"HELLO", b"HELLO x 0.1.0 /a", b"HELLO 2 0.1.0", b"HELLO 2  /a"):
        with pytest.raises(ValueError):
            decode_hello(data)


def test_our_hello_names_this_package() -> None:
    import lanewarden

    ours = Hello.ours()
    assert ours.package_version == lanewarden.__version__
    assert lanewarden.__file__.startswith(ours.package_folder)


@pytest.mark.parametrize(("theirs", "mismatch"), [
    (Hello(2, "0.1.0", "/elsewhere"), None),  # another folder, the same code version: fine
    (Hello(3, "0.1.0", "/a"), "lanewarden 0.1.0 (dead-man protocol 3) from /a, but this side is "
                              "lanewarden 0.1.0 (dead-man protocol 2) from /here"),
    (Hello(2, "0.2.0", "/a"), "lanewarden 0.2.0 (dead-man protocol 2) from /a, but this side is "
                              "lanewarden 0.1.0 (dead-man protocol 2) from /here"),
])
def test_versions_must_match(theirs: Hello, mismatch: str | None) -> None:
    assert version_mismatch(Hello(2, "0.1.0", "/here"), theirs) == mismatch
