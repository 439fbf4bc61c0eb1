"""Encoders for every command the host sends the Kobuki, as pure bytes.

Each `encode_*` returns one sub-payload (`[id][len][data]`, little-endian); `command_packet`
frames one or more of them for the wire. `velocity_to_speed_radius` converts a body-frame
(v, ω) into the base-control (speed, radius) exactly as the reference driver does (same
operation order, clamp to int16, truncation toward zero), so worked packets match bit for bit.

Never does I/O and never decides whether a command is safe: limits and the dead-man live in the
layers that own them.
"""

from __future__ import annotations

import math
import struct
from enum import IntEnum, IntFlag

from lanewarden.actuation.base import VelocityCommand
from lanewarden.actuation.kobuki_framing import frame_packet
from lanewarden.actuation.kobuki_geometry import WHEEL_BASE_M


class CommandId(IntEnum):
    BASE_CONTROL = 1
    SOUND = 3
    SOUND_SEQUENCE = 4
    REQUEST_EXTRA = 9
    GENERAL_PURPOSE_OUTPUT = 12
    SET_CONTROLLER_GAIN = 13
    GET_CONTROLLER_GAIN = 14


class SoundSequence(IntEnum):
    ON = 0
    OFF = 1
    RECHARGE = 2
    BUTTON = 3
    ERROR = 4
    CLEANING_START = 5
    CLEANING_END = 6


class ExtraRequest(IntFlag):
    HARDWARE_VERSION = 0x01
    FIRMWARE_VERSION = 0x02
    UDID = 0x08


#: GPO bits for the external power rails (5 V / 12 V): GPO rewrites all 16 bits, keep these set.
GPO_EXTERNAL_POWER = 0x00F0
#: Below this the reference driver treats ω (or v) as zero.
EPSILON = 1e-4
#: Seconds per sound-note unit: note = 1 / (f · 2.75 µs).
SOUND_NOTE_UNIT_S = 2.75e-6

INT16_MIN, INT16_MAX = -32768, 32767


def clamp_int16(value: float) -> int:
    """Bound to int16, then truncate toward zero (the reference driver's `bound()` + cast)."""
    if value > INT16_MAX:
        return INT16_MAX
    if value < INT16_MIN:
        return INT16_MIN
    return int(value)


def velocity_to_speed_radius(linear_m_s: float, angular_rad_s: float) -> tuple[int, int]:
    """Body-frame (v m/s, ω rad/s) -> base-control (speed mm/s, radius mm), as int16.

    - |ω| < ε: straight, radius 0, speed 1000·v.
    - R = 1000·v/ω; |v| < ε or |R| ≤ 1: spin in place, speed 1000·b·ω/2, radius 1.
    - else radius R and speed (R ± b/2·1000)·ω: the outer wheel's speed.
    Raises ValueError for a non-finite input (never encodes NaN as some speed).
    """
    if not (math.isfinite(linear_m_s) and math.isfinite(angular_rad_s)):
        raise ValueError(f"non-finite velocity ({linear_m_s!r}, {angular_rad_s!r})")
    if abs(angular_rad_s) < EPSILON:
        return clamp_int16(1000.0 * linear_m_s), 0
    radius = linear_m_s * 1000.0 / angular_rad_s
    if abs(linear_m_s) < EPSILON or abs(radius) <= 1.0:
        return clamp_int16(1000.0 * WHEEL_BASE_M * angular_rad_s / 2.0), 1
    half_base_mm = 1000.0 * WHEEL_BASE_M / 2.0
    speed = (radius + half_base_mm) * angular_rad_s if radius > 0.0 else \
        (radius - half_base_mm) * angular_rad_s
    return clamp_int16(speed), clamp_int16(radius)


def _sub_payload(command_id: CommandId, data: bytes) -> bytes:
    return bytes([command_id, len(data)]) + data


def encode_base_control(speed_mm_s: int, radius_mm: int) -> bytes:
    """Base Control (id 1): int16 speed mm/s, int16 radius mm."""
    return _sub_payload(CommandId.BASE_CONTROL, struct.pack("<hh", speed_mm_s, radius_mm))


def encode_velocity(command: VelocityCommand) -> bytes:
    """Base Control sub-payload for a body-frame velocity command."""
    return encode_base_control(*velocity_to_speed_radius(command.linear_m_s,
                                                         command.angular_rad_s))


def encode_sound(frequency_hz: float, duration_ms: int) -> bytes:
    """Sound (id 3): uint16 note = 1/(f·2.75e-6) (truncated), uint8 duration ms."""
    if not (math.isfinite(frequency_hz) and frequency_hz > 0.0):
        raise ValueError(f"sound frequency {frequency_hz!r} Hz: expected a positive number")
    note = int(1.0 / (frequency_hz * SOUND_NOTE_UNIT_S))
    if not 0 < note <= 0xFFFF:
        raise ValueError(f"sound frequency {frequency_hz!r} Hz gives note {note}: out of range")
    if not 0 <= duration_ms <= 0xFF:
        raise ValueError(f"sound duration {duration_ms} ms: expected 0..255")
    return _sub_payload(CommandId.SOUND, struct.pack("<HB", note, duration_ms))


def encode_sound_sequence(sequence: SoundSequence) -> bytes:
    """Sound Sequence (id 4): one of the base's built-in tunes."""
    return _sub_payload(CommandId.SOUND_SEQUENCE, bytes([SoundSequence(sequence)]))


def encode_request_extra(flags: int) -> bytes:
    """Request Extra (id 9): ask for hardware/firmware version and/or UDID (ExtraRequest bits)."""
    if not 0 <= flags <= 0xFFFF:
        raise ValueError(f"request-extra flags {flags:#x}: expected 16 bits")
    return _sub_payload(CommandId.REQUEST_EXTRA, struct.pack("<H", flags))


def encode_general_purpose_output(bits: int) -> bytes:
    """General Purpose Output (id 12): all 16 bits at once (see GPO_EXTERNAL_POWER)."""
    if not 0 <= bits <= 0xFFFF:
        raise ValueError(f"GPO bits {bits:#x}: expected 16 bits")
    return _sub_payload(CommandId.GENERAL_PURPOSE_OUTPUT, struct.pack("<H", bits))


def encode_set_controller_gain(controller_type: int, p_gain: float, i_gain: float,
                               d_gain: float) -> bytes:
    """Set Controller Gain (id 13): uint8 type, uint32 P, I, D each ×1000 (rounded)."""
    if not 0 <= controller_type <= 0xFF:
        raise ValueError(f"controller type {controller_type}: expected 0..255")
    scaled = []
    for name, gain in (("P", p_gain), ("I", i_gain), ("D", d_gain)):
        value = round(gain * 1000.0) if math.isfinite(gain) else -1
        if not 0 <= value <= 0xFFFFFFFF:
            raise ValueError(f"controller gain {name} = {gain!r}: expected 0..4294967.295")
        scaled.append(value)
    return _sub_payload(CommandId.SET_CONTROLLER_GAIN,
                        struct.pack("<BIII", controller_type, *scaled))


def encode_get_controller_gain() -> bytes:
    """Get Controller Gain (id 14): the base answers with a Controller Info sub-payload."""
    return _sub_payload(CommandId.GET_CONTROLLER_GAIN, b"\x00")


def command_packet(*sub_payloads: bytes) -> bytes:
    """Frame one or more command sub-payloads into one wire packet."""
    return frame_packet(b"".join(sub_payloads))


#: The packet that stops the base: base control, speed 0, radius 0.
STOP_PACKET = command_packet(encode_base_control(0, 0))
