"""Decoding feedback payloads into typed dataclasses; unknown, short and truncated sub-payloads."""

from __future__ import annotations

import math
import struct

from hypothesis import given, settings
from hypothesis import strategies as st

from lanewarden.actuation.kobuki_feedback import (
    GPIO,
    UDID,
    BasicSensorData,
    CliffADC,
    ControllerInfo,
    DockingIR,
    FeedbackPacket,
    Inertial,
    MotorCurrent,
    RawGyro,
    Version,
    decode_feedback,
)


def sub(sub_id: int, data: bytes) -> bytes:
    return bytes([sub_id, len(data)]) + data


BASIC = struct.pack("<HBBBHHbbBBBB", 4321, 5, 2, 4, 65535, 12, -3, 7, 1, 2, 161, 3)
STREAM_PAYLOAD = b"".join([
    sub(1, BASIC),
    sub(3, bytes([1, 2, 3])),
    sub(4, struct.pack("<hh", -9000, 250) + bytes(3)),
    sub(5, struct.pack("<HHH", 100, 200, 300)),
    sub(6, bytes([15, 250])),
    sub(13, bytes([9, 6]) + struct.pack("<6h", 1, -2, 3, -4, 5, -6)),
    sub(16, struct.pack("<HHHHH", 0b1010, 1, 2, 3, 4095) + bytes(6)),
])


def test_a_typical_stream_packet() -> None:
    assert len(STREAM_PAYLOAD) == 0x4D  # the doc's typical LEN
    packet = decode_feedback(STREAM_PAYLOAD)
    assert packet.basic == BasicSensorData(
        timestamp_ms=4321, bumper=5, wheel_drop=2, cliff=4, left_encoder=65535,
        right_encoder=12, left_pwm=-3, right_pwm=7, buttons=1, charger=2, battery_dv=161,
        overcurrent=3)
    assert packet.basic.battery_v == 16.1
    assert packet.docking_ir == DockingIR(right=1, centre=2, left=3)
    assert packet.inertial == Inertial(-9000, 250)
    assert math.isclose(packet.inertial.angle_rad, math.radians(-90.0))
    assert packet.cliff_adc == CliffADC(100, 200, 300)
    assert packet.current == MotorCurrent(15, 250)
    assert packet.current.right_a == 2.5
    assert packet.raw_gyro == RawGyro(9, ((1, -2, 3), (-4, 5, -6)))
    assert packet.gpio == GPIO(0b1010, (1, 2, 3, 4095))
    assert (packet.unknown_ids, packet.malformed_ids, packet.truncated) == ((), (), False)


def test_versions_udid_and_controller_info() -> None:
    payload = (sub(10, struct.pack("<I", 0x00010004)) + sub(11, struct.pack("<I", 0x00010200))
               + sub(19, struct.pack("<III", 1, 0xDEADBEEF, 3))
               + sub(21, struct.pack("<BIII", 1, 100, 200, 5)))
    packet = decode_feedback(payload)
    assert packet.hardware_version == Version(1, 0, 4)
    assert str(packet.firmware_version) == "1.2.0"
    assert packet.udid == UDID((1, 0xDEADBEEF, 3))
    assert str(packet.udid) == "00000001-DEADBEEF-00000003"
    assert packet.controller_info == ControllerInfo(1, 100, 200, 5)
    assert packet.controller_info.gains == (0.1, 0.2, 0.005)


def test_unknown_ids_are_skipped_by_length() -> None:
    payload = sub(99, bytes([1, 0xAA, 0x55])) + sub(200, b"") + sub(6, bytes([1, 2]))
    packet = decode_feedback(payload)
    assert packet.unknown_ids == (99, 200)
    assert packet.current == MotorCurrent(1, 2)


def test_short_known_sub_payload_is_malformed_not_decoded() -> None:
    packet = decode_feedback(sub(1, BASIC[:4]) + sub(6, bytes([1, 2])))
    assert packet.basic is None
    assert packet.malformed_ids == (1,)
    assert packet.current == MotorCurrent(1, 2)


def test_longer_than_documented_decodes_the_documented_prefix() -> None:
    packet = decode_feedback(sub(4, struct.pack("<hh", 10, 20) + bytes(5)))
    assert packet.inertial == Inertial(10, 20)


def test_inconsistent_raw_gyro_is_malformed() -> None:
    packet = decode_feedback(sub(13, bytes([1, 6]) + struct.pack("<3h", 1, 2, 3)))
    assert packet.raw_gyro is None and packet.malformed_ids == (13,)


def test_truncated_sub_payload_ends_the_walk() -> None:
    packet = decode_feedback(sub(6, bytes([1, 2])) + bytes([1, 15]) + BASIC[:5])
    assert packet.truncated
    assert packet.current == MotorCurrent(1, 2)
    assert packet.basic is None
    assert decode_feedback(sub(6, bytes([1, 2])) + bytes([3])).truncated


@settings(derandomize=True, max_examples=300, deadline=None)
@given(st.binary(max_size=255))
def test_any_payload_decodes_without_raising(payload: bytes) -> None:
    assert isinstance(decode_feedback(payload), FeedbackPacket)
