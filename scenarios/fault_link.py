"""The base as the control loop sees it, with the base-side faults: `FaultyLink` wraps a SimBase.

SimBase has no serial link, so the link faults are modelled where the control loop meets them,
with the real protocol code in the path:

- link_garbage / checksum_storm: while one is active, the base's 50 Hz feedback stream is really
  encoded as Kobuki packets (basic sensor data), garbage bytes are inserted between packets or
  the checksums of exactly that fraction of the packets corrupted (from the storm's first), and
  the bytes go through the real framing parser (`PacketReader`) and decoder
  (`decode_feedback`). Feedback is only as fresh as the newest packet that survived, as with
  `KobukiBase` (only basic sensor data proves a live link).
- write_blocks: writes to the port block: commands no longer reach the motors (the base keeps the
  command it had). After `write_timeout_s` the dead-man gives the link up (the port's write
  timeout) and every later send raises, as `KobukiBase.send` does after a lost link; when the
  write finally completes, the dead-man's last act, a stop, reaches the base.
- low_battery: the feedback reports `battery_v`.
- bumper / cliff / wheel_drop / base_link_loss act on SimBase itself (`inject`,
  `set_link_alive`).

Every alteration is noted in `altered` (name -> (step counter, time) of the latest), so the fault
schedule can log the step where a fault took effect. Never reads a clock.
"""

from __future__ import annotations

import struct

import numpy as np

from lanewarden.actuation.base import STOP, BaseFeedback, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.actuation.kobuki_feedback import decode_feedback
from lanewarden.actuation.kobuki_framing import PacketReader, frame_packet
from lanewarden.actuation.sim_base import SimBase

#: The Kobuki streams its feedback at 50 Hz.
FEEDBACK_PERIOD_S = 0.02
#: Most garbage bytes inserted between two packets (at intensity 1).
MAX_GARBAGE_BYTES = 64


def basic_sensor_packet(timestamp_ms: int, feedback: BaseFeedback) -> bytes:
    """One feedback packet as the Kobuki sends it: sub-payload 1 (basic sensor data) only."""
    battery_dv = 0 if feedback.battery_v is None else max(0, min(255, round(
        feedback.battery_v * 10)))
    basic = struct.pack("<HBBBHHbbBBBB", timestamp_ms % 65536, feedback.bumper,
                        feedback.wheel_drop, feedback.cliff, 0, 0, 0, 0, feedback.buttons, 0,
                        battery_dv, 0)
    return frame_packet(bytes([1, len(basic)]) + basic)


class FaultyLink:
    """The Base the control loop drives in a simulation: SimBase behind the link faults."""

    def __init__(self, base: SimBase, write_timeout_s: float, seed: int) -> None:
        self.base = base
        self._write_timeout_s = write_timeout_s
        self._rng = np.random.default_rng([seed, 0x11AB])
        self.garbage_intensity = 0.0
        self.checksum_storm_intensity = 0.0
        self.battery_v: float | None = None
        self.altered: dict[str, float] = {}
        self._blocked_since: float | None = None
        self._held: VelocityCommand | None = None
        self._lost: str | None = None
        self._reader = PacketReader()
        self._wire_time_s: float | None = None
        self._wire_feedback: BaseFeedback | None = None
        self._storm_debt = 1.0

    # ---- fault switches (the schedule calls these) --------------------------------------------
    @property
    def wire_faulty(self) -> bool:
        return self.garbage_intensity > 0.0 or self.checksum_storm_intensity > 0.0

    def block_writes(self, now: float) -> None:
        if self._blocked_since is None:
            self._blocked_since = now

    def unblock_writes(self, now: float) -> None:
        """The blocked write completes: a lost link's last act is the dead-man's stop."""
        if self._blocked_since is None:
            return
        self._blocked_since = None
        if self._lost is not None:
            self.base.send(STOP, now)
        elif self._held is not None:
            self.base.send(self._held, now)
        self._held = None

    # ---- the Base interface -------------------------------------------------------------------
    def send(self, command: VelocityCommand, now: float) -> None:
        if self._lost is not None:
            raise ActuationError(self._lost)
        if self._blocked_since is not None:
            self.altered["write_blocks"] = now
            if now - self._blocked_since >= self._write_timeout_s:
                self._lost = (f"simulated port: write blocked for {self._write_timeout_s:g} s "
                              "(link lost)")
                raise ActuationError(self._lost)
            self._held = command
            return
        self.base.send(command, now)

    def feedback(self, now: float) -> BaseFeedback:
        direct = self.base.feedback(now)
        if direct.bumper or direct.cliff or direct.wheel_drop:
            self.altered["bits"] = now
        if direct.received_at_s is not None and direct.received_at_s < now:
            self.altered["link_loss"] = now
        if self.battery_v is not None:
            direct = _with(direct, battery_v=self.battery_v)
            self.altered["low_battery"] = now
        if not self.wire_faulty:
            self._wire_time_s = None
            self._wire_feedback = direct
            self._storm_debt = 1.0
            return direct
        return self._through_wire(now, direct)

    def close(self) -> None:
        self.base.close()

    # ---- the serial wire ----------------------------------------------------------------------
    def _through_wire(self, now: float, state: BaseFeedback) -> BaseFeedback:
        """Packets due since the last call, through the faulty wire and the real parser."""
        if self._wire_time_s is None:
            self._wire_time_s = now - FEEDBACK_PERIOD_S
        previous = self._wire_feedback
        checksum_errors, skipped = self._reader.checksum_errors, self._reader.skipped_bytes
        while self._wire_time_s + FEEDBACK_PERIOD_S <= now + 1e-9:
            self._wire_time_s += FEEDBACK_PERIOD_S
            sent_at = self._wire_time_s
            if state.received_at_s is not None and state.received_at_s < sent_at - 1e-9:
                continue  # the base itself is silent (base_link_loss)
            packet = bytearray(basic_sensor_packet(round(sent_at * 1000), state))
            # Exactly the `intensity` fraction of packets, starting with the first of the storm.
            self._storm_debt += self.checksum_storm_intensity
            if self.checksum_storm_intensity > 0.0 and self._storm_debt >= 1.0 - 1e-9:
                self._storm_debt -= 1.0
                packet[-1] ^= 1 + int(self._rng.integers(0, 255))
            garbage = round(self.garbage_intensity * MAX_GARBAGE_BYTES)
            noise = self._rng.integers(0, 256, garbage, dtype=np.uint8).tobytes()
            for payload in self._reader.feed(noise + bytes(packet)):
                decoded = decode_feedback(payload)
                if decoded.basic is not None:
                    basic = decoded.basic
                    previous = BaseFeedback(
                        received_at_s=sent_at, bumper=basic.bumper, wheel_drop=basic.wheel_drop,
                        cliff=basic.cliff, buttons=basic.buttons, battery_v=basic.battery_v,
                        odometry=state.odometry)
        if self._reader.checksum_errors > checksum_errors:
            self.altered["checksum_storm"] = now
        if self._reader.skipped_bytes > skipped:
            self.altered["link_garbage"] = now
        self._wire_feedback = previous
        return previous if previous is not None else BaseFeedback()


def _with(feedback: BaseFeedback, *, battery_v: float) -> BaseFeedback:
    return BaseFeedback(received_at_s=feedback.received_at_s, bumper=feedback.bumper,
                        wheel_drop=feedback.wheel_drop, cliff=feedback.cliff,
                        buttons=feedback.buttons, battery_v=battery_v,
                        odometry=feedback.odometry)
