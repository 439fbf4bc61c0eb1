"""The base-side faults through the real Kobuki packet parser: garbage, checksum storms, a blocked
write, low battery."""

from __future__ import annotations

import pytest

from lanewarden.actuation.base import STOP, BaseFeedback, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.actuation.kobuki_feedback import decode_feedback
from lanewarden.actuation.kobuki_framing import PacketReader
from lanewarden.actuation.sim_base import SimBase
from lanewarden.scenarios.fault_link import FaultyLink, basic_sensor_packet

DT = 1 / 30


def ticks(link: FaultyLink, start: int, stop: int) -> BaseFeedback:
    feedback = BaseFeedback()
    for k in range(start, stop):
        feedback = link.feedback(k * DT)
    return feedback


def test_basic_sensor_packet_decodes_with_the_real_parser() -> None:
    packet = basic_sensor_packet(1234, BaseFeedback(bumper=2, cliff=4, wheel_drop=1,
                                                    battery_v=15.3))
    reader = PacketReader()
    (payload,) = reader.feed(b"\x00\xaa" + packet)
    basic = decode_feedback(payload).basic
    assert basic is not None
    assert (basic.timestamp_ms, basic.bumper, basic.cliff, basic.wheel_drop, basic.battery_dv) \
        == (1234, 2, 4, 1, 153)


def test_garbage_between_packets_is_skipped_and_feedback_stays_fresh() -> None:
    link = FaultyLink(SimBase(), write_timeout_s=0.5, seed=1)
    ticks(link, 0, 5)
    link.garbage_intensity = 1.0
    feedback = ticks(link, 5, 60)
    assert "link_garbage" in link.altered
    assert feedback.received_at_s is not None
    assert 59 * DT - feedback.received_at_s <= 0.1  # still fresh (within base_feedback_late_s)


def test_a_full_checksum_storm_starves_the_feedback() -> None:
    link = FaultyLink(SimBase(), write_timeout_s=0.5, seed=1)
    before = ticks(link, 0, 5)
    link.checksum_storm_intensity = 1.0
    during = ticks(link, 5, 30)
    assert "checksum_storm" in link.altered
    assert during.received_at_s is not None and before.received_at_s is not None
    assert during.received_at_s <= 5 * DT  # nothing valid since the storm began
    link.checksum_storm_intensity = 0.0
    after = ticks(link, 30, 32)
    assert after.received_at_s == pytest.approx(31 * DT)


def test_a_blocked_write_holds_the_old_command_then_loses_the_link_then_stops() -> None:
    base = SimBase()
    link = FaultyLink(base, write_timeout_s=0.5, seed=1)
    link.send(VelocityCommand(0.2, 0.0), 0.0)
    link.block_writes(1.0)
    link.send(STOP, 1.1)  # never reaches the motors
    assert base.commanded == VelocityCommand(0.2, 0.0)
    with pytest.raises(ActuationError, match="write blocked"):
        link.send(STOP, 1.5)
    with pytest.raises(ActuationError):
        link.send(STOP, 1.6)  # lost for good
    link.unblock_writes(2.0)  # the dead-man's last stop gets through
    assert base.commanded == STOP


def test_low_battery_is_what_the_feedback_reports() -> None:
    link = FaultyLink(SimBase(), write_timeout_s=0.5, seed=1)
    link.battery_v = 12.5
    assert link.feedback(0.0).battery_v == 12.5
    assert "low_battery" in link.altered
