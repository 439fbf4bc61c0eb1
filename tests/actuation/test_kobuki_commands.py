"""Command encoding against every worked packet in the protocol doc, and the (v, ω) rules."""

from __future__ import annotations

import math
import struct

import pytest

from lanewarden.actuation.base import VelocityCommand
from lanewarden.actuation.kobuki_commands import (
    STOP_PACKET,
    ExtraRequest,
    SoundSequence,
    command_packet,
    encode_base_control,
    encode_general_purpose_output,
    encode_get_controller_gain,
    encode_request_extra,
    encode_set_controller_gain,
    encode_sound,
    encode_sound_sequence,
    encode_velocity,
    velocity_to_speed_radius,
)

# (meaning, packet built by our encoders, hex from ../shared/docs/kobuki-protocol.md)
WORKED_PACKETS = [
    ("stop", command_packet(encode_velocity(VelocityCommand(0.0, 0.0))),
     "AA 55 06 01 04 00 00 00 00 03"),
    ("100 mm/s straight", command_packet(encode_velocity(VelocityCommand(0.1, 0.0))),
     "AA 55 06 01 04 64 00 00 00 67"),
    ("-100 mm/s straight", command_packet(encode_velocity(VelocityCommand(-0.1, 0.0))),
     "AA 55 06 01 04 9C FF 00 00 60"),
    ("spin +1 rad/s", command_packet(encode_velocity(VelocityCommand(0.0, 1.0))),
     "AA 55 06 01 04 73 00 01 00 71"),
    ("spin -1 rad/s", command_packet(encode_velocity(VelocityCommand(0.0, -1.0))),
     "AA 55 06 01 04 8D FF 01 00 70"),
    ("v 0.2, w 0.5", command_packet(encode_velocity(VelocityCommand(0.2, 0.5))),
     "AA 55 06 01 04 01 01 90 01 92"),
    ("speed 100, radius -100", command_packet(encode_base_control(100, -100)),
     "AA 55 06 01 04 64 00 9C FF 04"),
    ("sound sequence button", command_packet(encode_sound_sequence(SoundSequence.BUTTON)),
     "AA 55 03 04 01 03 05"),
    ("request extra 0x000B", command_packet(encode_request_extra(
        ExtraRequest.HARDWARE_VERSION | ExtraRequest.FIRMWARE_VERSION | ExtraRequest.UDID)),
     "AA 55 04 09 02 0B 00 04"),
    ("GPO 0x00F0", command_packet(encode_general_purpose_output(0x00F0)),
     "AA 55 04 0C 02 F0 00 FA"),
]


@pytest.mark.parametrize(("meaning", "packet", "expected"), WORKED_PACKETS,
                         ids=[row[0] for row in WORKED_PACKETS])
def test_worked_packets(meaning: str, packet: bytes, expected: str) -> None:
    assert packet == bytes.fromhex(expected), meaning


def test_stop_packet_constant() -> None:
    assert STOP_PACKET == bytes.fromhex("AA 55 06 01 04 00 00 00 00 03")


@pytest.mark.parametrize(
    ("v", "w", "expected"),
    [
        (0.0, 0.0, (0, 0)),
        (0.3, 0.0, (300, 0)),
        (0.3, 0.99e-4, (300, 0)),           # |w| < 1e-4: straight
        (0.3, -0.99e-4, (300, 0)),
        (0.0, 2.0, (230, 1)),               # spin: speed = 1000 b w / 2
        (0.0, -2.0, (-230, 1)),
        (0.99e-4, 0.5, (57, 1)),            # |v| < 1e-4: spin
        (0.0005, 0.5, (57, 1)),             # |R| = 1 mm: spin
        (0.2, 0.5, (257, 400)),             # outer wheel speed (R + 115) w
        (0.2, -0.5, (257, -400)),           # R < 0: (R - 115) w, forward turning right
        (-0.2, 0.5, (-257, -400)),          # reversing, w > 0: R < 0, speed < 0
        (-0.2, -0.5, (-257, 400)),
        (0.1, 1.0, (215, 100)),
        (0.3001, 0.7, (380, 428)),          # truncation toward zero (380.6, 428.7)
        (-0.3001, 0.7, (-380, -428)),       # ... also for negatives (not -381, -429)
        (50.0, 0.0, (32767, 0)),            # int16 clamp
        (-50.0, 0.0, (-32768, 0)),
        (0.0, 400.0, (32767, 1)),           # spin speed clamped
        (0.7, 0.00011, (700, 32767)),       # huge radius clamped, speed is not
        (-0.7, 0.00011, (-700, -32768)),
        (40.0, 2.0, (32767, 20000)),        # outer-wheel speed clamped, radius is not
        (-40.0, 2.0, (-32768, -20000)),
    ],
)
def test_velocity_to_speed_radius(v: float, w: float, expected: tuple[int, int]) -> None:
    assert velocity_to_speed_radius(v, w) == expected


def test_speed_is_outer_wheel_and_radius_is_curvature() -> None:
    speed, radius = velocity_to_speed_radius(0.4, 0.8)
    assert radius == 500
    # the outer (right) wheel at R + b/2 = 615 mm turns at 0.8 rad/s
    assert speed == math.trunc(615 * 0.8)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_velocity_is_refused(bad: float) -> None:
    with pytest.raises(ValueError, match="non-finite"):
        velocity_to_speed_radius(bad, 0.0)
    with pytest.raises(ValueError, match="non-finite"):
        velocity_to_speed_radius(0.1, bad)


def test_sound_note_and_duration() -> None:
    # 440 Hz: 1 / (440 * 2.75e-6) = 826.44 -> 826 = 0x033A
    assert encode_sound(440.0, 100) == bytes([3, 3, 0x3A, 0x03, 100])
    with pytest.raises(ValueError, match="duration"):
        encode_sound(440.0, 256)
    with pytest.raises(ValueError, match="frequency"):
        encode_sound(0.0, 10)
    with pytest.raises(ValueError, match="out of range"):
        encode_sound(1.0, 10)  # note 363636 does not fit 16 bits


def test_every_sound_sequence() -> None:
    assert [encode_sound_sequence(seq) for seq in SoundSequence] == [
        bytes([4, 1, value]) for value in range(7)]


def test_controller_gains() -> None:
    payload = encode_set_controller_gain(1, 0.1, 2.0, 0.0025)
    assert payload[:2] == bytes([13, 13])
    assert struct.unpack("<BIII", payload[2:]) == (1, 100, 2000, 2)  # x1000, rounded
    with pytest.raises(ValueError, match="gain I"):
        encode_set_controller_gain(1, 0.1, -1.0, 0.0)
    with pytest.raises(ValueError, match="gain D"):
        encode_set_controller_gain(1, 0.1, 1.0, math.nan)
    assert encode_get_controller_gain() == bytes([14, 1, 0])


def test_sixteen_bit_fields_are_checked() -> None:
    with pytest.raises(ValueError, match="16 bits"):
        encode_request_extra(0x10000)
    with pytest.raises(ValueError, match="16 bits"):
        encode_general_purpose_output(-1)


def test_several_sub_payloads_in_one_packet() -> None:
    packet = command_packet(encode_base_control(0, 0), encode_sound_sequence(SoundSequence.ON))
    assert packet == bytes.fromhex("AA 55 09 01 04 00 00 00 00 04 01 00") + bytes(
        [0x09 ^ 0x01 ^ 0x04 ^ 0x04 ^ 0x01])
