"""Decoding of the Kobuki's feedback payloads into typed, frozen dataclasses (pure bytes in).

`decode_feedback(payload)` walks the run of sub-payloads (`[id][len][data]`) of ONE valid packet
(framing and checksum are `kobuki_framing`'s job). Unknown ids are skipped by their length; a
known id whose data is shorter than its documented layout is reported as malformed, not decoded;
a sub-payload whose length runs past the end of the payload ends the walk (`truncated`). Longer
data than documented is accepted and its documented prefix decoded (newer firmware appends).

Never raises on any payload, never does I/O, never reads a clock.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any


class FeedbackId(IntEnum):
    BASIC_SENSOR_DATA = 1
    DOCKING_IR = 3
    INERTIAL = 4
    CLIFF_ADC = 5
    CURRENT = 6
    HARDWARE_VERSION = 10
    FIRMWARE_VERSION = 11
    RAW_GYRO = 13
    GPIO = 16
    UDID = 19
    CONTROLLER_INFO = 21


class Bumper:
    RIGHT = 1
    CENTRE = 2
    LEFT = 4


class WheelDrop:
    RIGHT = 1
    LEFT = 2


class Cliff:
    RIGHT = 1
    CENTRE = 2
    LEFT = 4


#: The side each hazard bit stands for, in the order an operator reads them (left to right).
BUMPER_SIDES: tuple[tuple[int, str], ...] = (
    (Bumper.LEFT, "left"), (Bumper.CENTRE, "centre"), (Bumper.RIGHT, "right"))
CLIFF_SIDES: tuple[tuple[int, str], ...] = (
    (Cliff.LEFT, "left"), (Cliff.CENTRE, "centre"), (Cliff.RIGHT, "right"))
WHEEL_DROP_SIDES: tuple[tuple[int, str], ...] = (
    (WheelDrop.LEFT, "left"), (WheelDrop.RIGHT, "right"))


def side_names(bits: int, sides: tuple[tuple[int, str], ...]) -> list[str]:
    """The names of the sides whose bit is set in `bits` (left to right)."""
    return [name for bit, name in sides if bits & bit]


@dataclass(frozen=True)
class BasicSensorData:
    """Sub-payload 1. Encoders are raw u16 ticks (they wrap); battery in units of 0.1 V."""

    timestamp_ms: int
    bumper: int
    wheel_drop: int
    cliff: int
    left_encoder: int
    right_encoder: int
    left_pwm: int
    right_pwm: int
    buttons: int
    charger: int
    battery_dv: int
    overcurrent: int

    @property
    def battery_v(self) -> float:
        return self.battery_dv / 10.0


@dataclass(frozen=True)
class DockingIR:
    """Sub-payload 3: the docking station's IR signal seen by the right, centre, left receivers."""

    right: int
    centre: int
    left: int


@dataclass(frozen=True)
class Inertial:
    """Sub-payload 4: heading in 0.01° and its rate in 0.01°/s (gyro-integrated on the base)."""

    angle_centideg: int
    angle_rate_centideg_s: int

    @property
    def angle_rad(self) -> float:
        return math.radians(self.angle_centideg / 100.0)

    @property
    def angle_rate_rad_s(self) -> float:
        return math.radians(self.angle_rate_centideg_s / 100.0)


@dataclass(frozen=True)
class CliffADC:
    """Sub-payload 5: the three cliff sensors' raw ADC readings (right, centre, left)."""

    right: int
    centre: int
    left: int


@dataclass(frozen=True)
class MotorCurrent:
    """Sub-payload 6: wheel motor currents in units of 10 mA."""

    left_10ma: int
    right_10ma: int

    @property
    def left_a(self) -> float:
        return self.left_10ma / 100.0

    @property
    def right_a(self) -> float:
        return self.right_10ma / 100.0


#: Raw gyro scale: degrees per second per count.
RAW_GYRO_DEG_S_PER_COUNT = 0.00875


@dataclass(frozen=True)
class RawGyro:
    """Sub-payload 13: N raw (x, y, z) gyro samples in counts of 0.00875 °/s."""

    frame_id: int
    samples: tuple[tuple[int, int, int], ...]


@dataclass(frozen=True)
class GPIO:
    """Sub-payload 16: digital inputs (bit field) and four analog inputs (raw ADC)."""

    digital_in: int
    analog_in: tuple[int, int, int, int]


@dataclass(frozen=True)
class Version:
    """Sub-payloads 10/11: a u32 0x00MMmmpp version."""

    major: int
    minor: int
    patch: int

    def __str__(self) -> str:
        return f"{self.major}.{self.minor}.{self.patch}"


@dataclass(frozen=True)
class UDID:
    """Sub-payload 19: the base's unique device id, three u32 words."""

    words: tuple[int, int, int]

    def __str__(self) -> str:
        return "-".join(f"{word:08X}" for word in self.words)


@dataclass(frozen=True)
class ControllerInfo:
    """Sub-payload 21: wheel PID controller type and gains (raw values are gain × 1000)."""

    controller_type: int
    p_gain_milli: int
    i_gain_milli: int
    d_gain_milli: int

    @property
    def gains(self) -> tuple[float, float, float]:
        return (self.p_gain_milli / 1000.0, self.i_gain_milli / 1000.0,
                self.d_gain_milli / 1000.0)


@dataclass(frozen=True)
class FeedbackPacket:
    """Everything one feedback payload carried. A field is None when its sub-payload was absent.

    `unknown_ids`: ids skipped by length; `malformed_ids`: known ids too short to decode;
    `truncated`: a sub-payload ran past the end of the payload (the walk stopped there).
    """

    basic: BasicSensorData | None = None
    docking_ir: DockingIR | None = None
    inertial: Inertial | None = None
    cliff_adc: CliffADC | None = None
    current: MotorCurrent | None = None
    raw_gyro: RawGyro | None = None
    gpio: GPIO | None = None
    hardware_version: Version | None = None
    firmware_version: Version | None = None
    udid: UDID | None = None
    controller_info: ControllerInfo | None = None
    unknown_ids: tuple[int, ...] = field(default=())
    malformed_ids: tuple[int, ...] = field(default=())
    truncated: bool = False


def _basic(data: bytes) -> BasicSensorData:
    return BasicSensorData(*struct.unpack_from("<HBBBHHbbBBBB", data))


def _docking_ir(data: bytes) -> DockingIR:
    return DockingIR(*struct.unpack_from("<BBB", data))


def _inertial(data: bytes) -> Inertial:
    return Inertial(*struct.unpack_from("<hh", data))


def _cliff_adc(data: bytes) -> CliffADC:
    return CliffADC(*struct.unpack_from("<HHH", data))


def _current(data: bytes) -> MotorCurrent:
    return MotorCurrent(*struct.unpack_from("<BB", data))


def _raw_gyro(data: bytes) -> RawGyro:
    frame_id, value_count = struct.unpack_from("<BB", data)
    if value_count % 3 or len(data) < 2 + 2 * value_count:
        raise ValueError("raw gyro sample count does not match its length")
    values = struct.unpack_from(f"<{value_count}h", data, 2)
    samples = tuple((values[i], values[i + 1], values[i + 2]) for i in range(0, value_count, 3))
    return RawGyro(frame_id, samples)


def _gpio(data: bytes) -> GPIO:
    digital, a0, a1, a2, a3 = struct.unpack_from("<HHHHH", data)
    return GPIO(digital, (a0, a1, a2, a3))


def _version(data: bytes) -> Version:
    (value,) = struct.unpack_from("<I", data)
    return Version((value >> 16) & 0xFF, (value >> 8) & 0xFF, value & 0xFF)


def _udid(data: bytes) -> UDID:
    return UDID(struct.unpack_from("<III", data))


def _controller_info(data: bytes) -> ControllerInfo:
    return ControllerInfo(*struct.unpack_from("<BIII", data))


#: id -> (FeedbackPacket field, minimum data length, decoder)
_DECODERS: dict[int, tuple[str, int, Callable[[bytes], Any]]] = {
    FeedbackId.BASIC_SENSOR_DATA: ("basic", 15, _basic),
    FeedbackId.DOCKING_IR: ("docking_ir", 3, _docking_ir),
    FeedbackId.INERTIAL: ("inertial", 7, _inertial),
    FeedbackId.CLIFF_ADC: ("cliff_adc", 6, _cliff_adc),
    FeedbackId.CURRENT: ("current", 2, _current),
    FeedbackId.RAW_GYRO: ("raw_gyro", 2, _raw_gyro),
    FeedbackId.GPIO: ("gpio", 16, _gpio),
    FeedbackId.HARDWARE_VERSION: ("hardware_version", 4, _version),
    FeedbackId.FIRMWARE_VERSION: ("firmware_version", 4, _version),
    FeedbackId.UDID: ("udid", 12, _udid),
    FeedbackId.CONTROLLER_INFO: ("controller_info", 13, _controller_info),
}


def decode_feedback(payload: bytes) -> FeedbackPacket:
    """Decode the sub-payloads of one valid feedback payload. Never raises."""
    decoded: dict[str, Any] = {}
    unknown: list[int] = []
    malformed: list[int] = []
    truncated = False
    index = 0
    while index < len(payload):
        if index + 2 > len(payload):
            truncated = True
            break
        sub_id, length = payload[index], payload[index + 1]
        data = payload[index + 2:index + 2 + length]
        if len(data) < length:
            truncated = True
            break
        index += 2 + length
        decoder = _DECODERS.get(sub_id)
        if decoder is None:
            unknown.append(sub_id)
            continue
        name, min_length, decode = decoder
        if length < min_length:
            malformed.append(sub_id)
            continue
        try:
            decoded[name] = decode(data)
        except (ValueError, struct.error):
            malformed.append(sub_id)
    return FeedbackPacket(**decoded, unknown_ids=tuple(unknown),
                          malformed_ids=tuple(malformed), truncated=truncated)
