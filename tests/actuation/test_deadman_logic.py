"""The dead-man's decision logic on a fake clock: every mode x every input, its timing rules, its
own hazard latch and the envelope it keeps every forwarded command in."""

from __future__ import annotations

import itertools
from collections.abc import Callable

import pytest

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.actuation.deadman_logic import (
    CLOSE_STOP_PACKETS,
    DeadmanLogic,
    DeadmanMode,
    DeadmanSettings,
    Envelope,
    Heartbeat,
    SafetySensors,
)

#: An envelope that never binds (the table tests are about modes, not ramps).
WIDE = Envelope(max_linear_accel_m_s2=1e6, max_angular_accel_rad_s2=1e6)
SETTINGS = DeadmanSettings(heartbeat_timeout_s=0.2, command_period_s=0.02, orphan_stop_s=0.5,
                           feedback_timeout_s=0.2, envelope=WIDE)
MOVE = VelocityCommand(0.3, 0.1)
OTHER_MOVE = VelocityCommand(0.2, -0.4)
_SEQUENCE = itertools.count()


def beat(sent_s: float) -> Heartbeat:
    """A heartbeat sent at `sent_s`, numbered after every earlier one."""
    return Heartbeat(next(_SEQUENCE), sent_s)


def arm(logic: DeadmanLogic, t: float) -> None:
    logic.on_arm(t, beat(t))


def resume(logic: DeadmanLogic, t: float) -> None:
    logic.on_resume(t, beat(t))


def command(logic: DeadmanLogic, velocity: VelocityCommand, t: float) -> None:
    """A command sent and received at `t`."""
    logic.on_command(velocity, t, beat(t))


def packet(logic: DeadmanLogic, t: float, *, bumper: int = 0, cliff: int = 0,
           wheel_drop: int = 0) -> None:
    """A feedback packet read at `t` with these hazard bits."""
    logic.on_feedback(t, SafetySensors(t, bumper=bumper, cliff=cliff, wheel_drop=wheel_drop))


def new_logic(settings: DeadmanSettings = SETTINGS) -> DeadmanLogic:
    """A logic started at 0.0 that has read one clean feedback packet at 0.0."""
    logic = DeadmanLogic(settings, start_s=0.0)
    packet(logic, 0.0)
    return logic


def _setup(state: str) -> DeadmanLogic:
    """A logic in `state`, having sent packets at 0.00, 0.02, 0.04 (next tick due at 0.06); the
    base's last feedback was read at 0.0 (clean, except in "latched": the bumper is pressed)."""
    logic = new_logic()
    if state in ("armed_stop", "armed_moving", "tripped", "latched"):
        arm(logic, 0.0)
    if state in ("armed_moving", "tripped", "latched"):
        command(logic, MOVE, 0.0)
    if state == "tripped":
        logic.on_malformed(0.0, "garbage")
    if state == "latched":
        packet(logic, 0.0, bumper=2)
    if state == "stopping":
        logic.on_control_gone(0.0)
    for t in (0.0, 0.02, 0.04):
        assert logic.poll(t).send is not None
    return logic


INPUTS: dict[str, Callable[[DeadmanLogic, float], None]] = {
    "arm": arm,
    "resume": resume,
    "disarm": lambda logic, t: logic.on_disarm(t, beat(t)),
    "command_move": lambda logic, t: command(logic, OTHER_MOVE, t),
    "command_stop": lambda logic, t: command(logic, STOP, t),
    "malformed": lambda logic, t: logic.on_malformed(t, "bad"),
    "control_gone": lambda logic, t: logic.on_control_gone(t),
    "close": lambda logic, t: logic.on_close(t),
    "feedback_clear": lambda logic, t: packet(logic, t),
    "feedback_bumper": lambda logic, t: packet(logic, t, bumper=4),
}

D, A, T, L, S = (DeadmanMode.DISARMED, DeadmanMode.ARMED, DeadmanMode.TRIPPED,
                 DeadmanMode.LATCHED, DeadmanMode.STOPPING)
# (state, input) -> (mode after, command on the wire at the next tick, stop sent at once?)
TABLE: dict[tuple[str, str], tuple[DeadmanMode, VelocityCommand, bool]] = {
    ("disarmed", "arm"): (A, STOP, False),
    ("disarmed", "resume"): (A, STOP, False),
    ("disarmed", "disarm"): (D, STOP, False),
    ("disarmed", "command_move"): (D, STOP, False),
    ("disarmed", "command_stop"): (D, STOP, False),
    ("disarmed", "malformed"): (D, STOP, False),
    ("disarmed", "control_gone"): (S, STOP, True),
    ("disarmed", "close"): (S, STOP, True),
    ("disarmed", "feedback_clear"): (D, STOP, False),
    ("disarmed", "feedback_bumper"): (L, STOP, True),
    ("armed_stop", "arm"): (A, STOP, False),
    ("armed_stop", "resume"): (A, STOP, False),
    ("armed_stop", "disarm"): (D, STOP, False),
    ("armed_stop", "command_move"): (A, OTHER_MOVE, False),
    ("armed_stop", "command_stop"): (A, STOP, False),
    ("armed_stop", "malformed"): (T, STOP, True),
    ("armed_stop", "control_gone"): (S, STOP, True),
    ("armed_stop", "close"): (S, STOP, True),
    ("armed_stop", "feedback_clear"): (A, STOP, False),
    ("armed_stop", "feedback_bumper"): (L, STOP, True),
    ("armed_moving", "arm"): (A, MOVE, False),
    ("armed_moving", "resume"): (A, MOVE, False),
    ("armed_moving", "disarm"): (D, STOP, True),
    ("armed_moving", "command_move"): (A, OTHER_MOVE, False),
    ("armed_moving", "command_stop"): (A, STOP, True),
    ("armed_moving", "malformed"): (T, STOP, True),
    ("armed_moving", "control_gone"): (S, STOP, True),
    ("armed_moving", "close"): (S, STOP, True),
    ("armed_moving", "feedback_clear"): (A, MOVE, False),
    ("armed_moving", "feedback_bumper"): (L, STOP, True),
    ("tripped", "arm"): (A, STOP, False),
    ("tripped", "resume"): (A, STOP, False),
    ("tripped", "disarm"): (D, STOP, False),
    ("tripped", "command_move"): (T, STOP, False),
    ("tripped", "command_stop"): (T, STOP, False),
    ("tripped", "malformed"): (T, STOP, False),
    ("tripped", "control_gone"): (S, STOP, True),
    ("tripped", "close"): (S, STOP, True),
    ("tripped", "feedback_clear"): (T, STOP, False),
    ("tripped", "feedback_bumper"): (T, STOP, False),
    ("latched", "arm"): (L, STOP, False),
    ("latched", "resume"): (L, STOP, False),  # refused: the bumper is still pressed
    ("latched", "disarm"): (L, STOP, False),
    ("latched", "command_move"): (L, STOP, False),
    ("latched", "command_stop"): (L, STOP, False),
    ("latched", "malformed"): (L, STOP, False),
    ("latched", "control_gone"): (S, STOP, True),
    ("latched", "close"): (S, STOP, True),
    ("latched", "feedback_clear"): (L, STOP, False),
    ("latched", "feedback_bumper"): (L, STOP, False),
    ("stopping", "arm"): (S, STOP, False),
    ("stopping", "resume"): (S, STOP, False),
    ("stopping", "disarm"): (S, STOP, False),
    ("stopping", "command_move"): (S, STOP, False),
    ("stopping", "command_stop"): (S, STOP, False),
    ("stopping", "malformed"): (S, STOP, False),
    ("stopping", "control_gone"): (S, STOP, False),
    ("stopping", "close"): (S, STOP, False),
    ("stopping", "feedback_clear"): (S, STOP, False),
    ("stopping", "feedback_bumper"): (S, STOP, False),
}


def test_the_table_covers_every_mode_and_input() -> None:
    states = {"disarmed", "armed_stop", "armed_moving", "tripped", "latched", "stopping"}
    assert set(TABLE) == {(state, name) for state in states for name in INPUTS}
    assert {_setup(state).mode for state in states} == set(DeadmanMode)


@pytest.mark.parametrize(("state", "input_name"), sorted(TABLE))
def test_every_mode_and_input(state: str, input_name: str) -> None:
    mode, next_command, stop_at_once = TABLE[(state, input_name)]
    logic = _setup(state)
    INPUTS[input_name](logic, 0.05)
    at_once = logic.poll(0.05)
    assert at_once.send == (STOP if stop_at_once else None)
    assert logic.mode is mode
    tick = logic.poll(max(0.06, logic.next_wakeup_s()))  # an at-once stop restarts the tick
    assert tick.send == next_command
    assert logic.command == next_command


Bits = dict[str, int]
FEEDBACK_PERIOD_S = 0.02


def clean_base(t: float) -> Bits | None:
    """A base streaming clean feedback packets."""
    return {}


def _run(logic: DeadmanLogic, until_s: float,
         inputs: dict[float, Callable[[DeadmanLogic, float], None]],
         base: Callable[[float], Bits | None] = clean_base,
         ) -> tuple[list[tuple[float, VelocityCommand]], bool]:
    """A fake-clock shell: wake at each input time, each feedback packet or `next_wakeup_s`, like
    deadman.py. `base(t)`: the hazard bits of the packet the base streams at t (every 20 ms from
    0.0; read before the inputs due at the same time), or None when it sends none."""
    sent: list[tuple[float, VelocityCommand]] = []
    pending = sorted(inputs)
    next_packet_s = 0.0
    now = 0.0
    for _ in range(100_000):  # a logic that never lets time move on fails instead of hanging
        if now > until_s:
            break
        while next_packet_s <= now:
            bits = base(next_packet_s)
            if bits is not None:
                packet(logic, now, **bits)
            next_packet_s = round(next_packet_s + FEEDBACK_PERIOD_S, 9)
        while pending and pending[0] <= now:
            inputs[pending.pop(0)](logic, now)
        action = logic.poll(now)
        if action.send is not None:
            sent.append((now, action.send))
        if action.finished:
            return sent, True
        now = max(now, min([logic.next_wakeup_s(), next_packet_s] + pending[:1]))
    else:
        pytest.fail(f"the fake-clock shell spun at t = {now}")
    return sent, False


def _every(period_s: float, start_s: float, end_s: float,
           action: Callable[[DeadmanLogic, float], None]
           ) -> dict[float, Callable[[DeadmanLogic, float], None]]:
    count = round((end_s - start_s) / period_s)
    return {round(start_s + i * period_s, 9): action for i in range(count + 1)}


def test_disarmed_sends_stop_at_the_steady_rate_from_the_start() -> None:
    sent, finished = _run(DeadmanLogic(SETTINGS, 0.0), 1.001, {})
    assert not finished
    assert [command for _, command in sent] == [STOP] * 51  # 0.00, 0.02, ..., 1.00
    assert sent[1][0] - sent[0][0] == pytest.approx(0.02)


def test_armed_repeats_an_unchanged_command_at_the_steady_rate() -> None:
    inputs = {0.0: INPUTS["arm"], **_every(0.05, 0.01, 1.0,
                                          lambda lg, t: command(lg, MOVE, t))}
    sent, _ = _run(DeadmanLogic(SETTINGS, 0.0), 1.0, inputs)
    moving = [t for t, command in sent if command == MOVE]
    assert len(moving) >= 49
    assert all(b - a == pytest.approx(0.02) for a, b in zip(moving, moving[1:], strict=False))


def test_heartbeat_silence_stops_at_the_timeout_and_keeps_stopping() -> None:
    last_heartbeat = 0.482
    inputs = {0.0: INPUTS["arm"], **_every(0.03, 0.002, last_heartbeat,
                                          lambda lg, t: command(lg, MOVE, t))}
    logic = DeadmanLogic(SETTINGS, 0.0)
    sent, _ = _run(logic, 3.0, inputs)
    first_stop = next(t for t, command in sent if t > last_heartbeat and command == STOP)
    assert first_stop == pytest.approx(last_heartbeat + SETTINGS.heartbeat_timeout_s)
    assert all(command == STOP for t, command in sent if t >= first_stop)
    assert all(command == MOVE for t, command in sent if 0.0 < t < first_stop)
    assert logic.mode is DeadmanMode.TRIPPED


def test_no_trip_just_before_the_timeout_and_a_trip_exactly_at_it() -> None:
    logic = new_logic()
    arm(logic, 0.0)
    command(logic, MOVE, 0.0)
    logic.poll(0.0)
    packet(logic, 0.1)
    assert logic.next_wakeup_s() == pytest.approx(0.02)
    logic.poll(0.18)
    assert logic.next_wakeup_s() == pytest.approx(0.2)  # heartbeat deadline before next tick
    assert logic.poll(0.1999).events == ()
    action = logic.poll(0.2)
    assert action.send == STOP
    assert [event.mode for event in action.events] == [DeadmanMode.TRIPPED]
    assert "no heartbeat for 0.200 s" in action.events[0].reason


def test_tripped_ignores_a_fresh_command_stream_until_an_explicit_arm() -> None:
    logic = DeadmanLogic(SETTINGS, 0.0)
    inputs = {0.0: INPUTS["arm"], 0.01: lambda lg, t: command(lg, MOVE, t),
              # frozen from 0.01 to 0.5, then the stream resumes without re-arming
              **_every(0.02, 0.5, 2.0, lambda lg, t: command(lg, MOVE, t))}
    sent, _ = _run(logic, 2.0, inputs)
    assert all(command == STOP for t, command in sent if t >= 0.21)
    assert logic.mode is DeadmanMode.TRIPPED
    arm(logic, 2.0)
    assert logic.poll(2.0).events[0].mode is DeadmanMode.ARMED
    assert logic.command == STOP  # arming alone never moves the robot
    command(logic, MOVE, 2.01)
    assert logic.poll(2.03).send == MOVE


def test_control_gone_stops_at_once_for_the_orphan_time_then_finishes() -> None:
    inputs = {0.0: INPUTS["arm"], 0.001: lambda lg, t: command(lg, MOVE, t),
              0.1: INPUTS["control_gone"]}
    sent, finished = _run(DeadmanLogic(SETTINGS, 0.0), 5.0, inputs)
    assert finished
    stops = [t for t, command in sent if t >= 0.1]
    assert stops[0] == pytest.approx(0.1)
    assert stops[-1] == pytest.approx(0.1 + SETTINGS.orphan_stop_s)
    assert all(command == STOP for t, command in sent if t >= 0.1)
    assert len(stops) == pytest.approx(SETTINGS.orphan_stop_s / 0.02 + 1, abs=1)


def test_close_sends_a_short_burst_of_stops_then_finishes() -> None:
    inputs = {0.0: INPUTS["arm"], 0.001: lambda lg, t: command(lg, MOVE, t),
              0.1: INPUTS["close"]}
    sent, finished = _run(DeadmanLogic(SETTINGS, 0.0), 5.0, inputs)
    assert finished
    assert [command for t, command in sent if t >= 0.1] == [STOP] * CLOSE_STOP_PACKETS


def test_events_report_every_mode_change_once() -> None:
    logic = new_logic()
    arm(logic, 0.0)
    arm(logic, 0.01)
    assert [e.mode for e in logic.poll(0.01).events] == [DeadmanMode.ARMED]
    logic.on_malformed(0.02, "CMD nan")
    events = logic.poll(0.02).events
    assert [e.mode for e in events] == [DeadmanMode.TRIPPED] and "CMD nan" in events[0].reason
    logic.on_close(0.03, "stopped by signal SIGTERM")
    logic.on_control_gone(0.03)
    events = logic.poll(0.03).events
    assert [(e.mode, e.reason) for e in events] == [(DeadmanMode.STOPPING,
                                                     "stopped by signal SIGTERM")]
    assert logic.poll(0.04).events == ()


# ---- heartbeats carry the sender's time and sequence ------------------------------------------
def test_a_heartbeat_counts_from_when_it_was_sent_not_when_it_was_read() -> None:
    # sent at 0.10, then the sender froze and the dead-man read it only at 0.35 (it was starved
    # itself): it is 0.25 s old, older than the 0.2 s timeout, so it must not keep the robot going
    logic = new_logic()
    arm(logic, 0.0)
    command(logic, MOVE, 0.05)
    logic.on_command(MOVE, 0.35, beat(0.10))
    action = logic.poll(0.35)
    assert action.send == STOP
    assert logic.mode is DeadmanMode.TRIPPED
    assert "no heartbeat for 0.250 s" in action.events[-1].reason


def test_the_deadline_is_the_send_stamp_plus_the_timeout() -> None:
    logic = new_logic()
    arm(logic, 0.0)
    logic.poll(0.0)
    packet(logic, 0.15)
    logic.poll(0.16)
    logic.on_command(MOVE, 0.17, beat(0.16))  # read 10 ms after it was sent
    assert logic.poll(0.17).send is None  # motion waits for the tick
    assert logic.poll(0.18).send == MOVE
    packet(logic, 0.3)
    logic.poll(0.34)
    assert logic.next_wakeup_s() == pytest.approx(0.36)  # 0.16 + 0.2, not 0.17 + 0.2
    assert logic.poll(0.3599).send in (None, MOVE) and logic.mode is DeadmanMode.ARMED
    assert logic.poll(0.36).send == STOP and logic.mode is DeadmanMode.TRIPPED


@pytest.mark.parametrize(("first", "second", "problem"), [
    (Heartbeat(5, 0.10), Heartbeat(5, 0.11), "sequence went backwards (5 after 5)"),
    (Heartbeat(5, 0.10), Heartbeat(4, 0.11), "sequence went backwards (4 after 5)"),
    (Heartbeat(5, 0.10), Heartbeat(6, 0.09), "heartbeat stamp went backwards"),
    (Heartbeat(5, 0.10), Heartbeat(6, 0.1201), "heartbeat stamped in the future"),
])
def test_stamps_from_the_future_or_going_backwards_trip_it(first: Heartbeat, second: Heartbeat,
                                                            problem: str) -> None:
    logic = new_logic()
    logic.on_arm(0.10, first)
    logic.on_command(MOVE, 0.12, second)
    action = logic.poll(0.12)
    assert action.send == STOP
    assert logic.mode is DeadmanMode.TRIPPED
    assert problem in action.events[-1].reason
    assert logic.heartbeat_seq == 5


def test_an_arm_with_a_bad_stamp_does_not_arm() -> None:
    logic = new_logic()
    logic.on_arm(0.10, Heartbeat(3, 0.5))  # from the future
    assert logic.mode is DeadmanMode.DISARMED and logic.heartbeat_seq == -1


def test_disarm_stops_at_once_needs_no_heartbeat_and_ignores_commands_until_armed() -> None:
    logic = DeadmanLogic(SETTINGS, 0.0)
    inputs = {0.0: INPUTS["arm"], 0.01: lambda lg, t: command(lg, MOVE, t),
              0.1: INPUTS["disarm"],
              # suspended from 0.1 to 3.0, then a stale command from before is read
              3.0: lambda lg, t: lg.on_command(MOVE, t, beat(0.09))}
    sent, _ = _run(logic, 3.5, inputs)
    assert (0.1, STOP) in sent  # at once
    assert all(command == STOP for t, command in sent if t >= 0.1)
    assert logic.mode is DeadmanMode.DISARMED  # never tripped: it held stop without heartbeats
    assert logic.heartbeat_seq >= 0
    arm(logic, 3.6)
    assert logic.mode is DeadmanMode.ARMED and logic.command == STOP


# ---- its own hazard latch ---------------------------------------------------------------------
def test_a_bumper_packet_stops_at_once_not_at_the_next_tick() -> None:
    logic = _setup("armed_moving")
    packet(logic, 0.047, bumper=2)  # read between two ticks (0.04, 0.06)
    action = logic.poll(0.047)
    assert action.send == STOP
    assert [(e.mode, e.reason) for e in action.events] == [
        (DeadmanMode.LATCHED, "bumper pressed (centre)")]


@pytest.mark.parametrize(("bits", "reason"), [
    ({"bumper": 5}, "bumper pressed (left, right)"),
    ({"cliff": 2}, "cliff sensor triggered (centre)"),
    ({"wheel_drop": 2}, "wheel dropped (left)"),
    ({"wheel_drop": 3, "cliff": 1}, "cliff sensor triggered (right); wheel dropped (left, right)"),
    ({"bumper": 8}, "bumper pressed (bits 0x8)"),
])
def test_every_hazard_bit_latches_and_is_named(bits: Bits, reason: str) -> None:
    logic = _setup("armed_moving")
    packet(logic, 0.05, **bits)
    assert logic.poll(0.05).events[-1].reason == reason
    assert logic.mode is DeadmanMode.LATCHED


def test_nothing_moves_after_the_latch_until_the_hazard_clears_and_the_operator_resumes() -> None:
    def base(t: float) -> Bits:  # the bumper is held from 0.5 s to 0.7 s
        return {"bumper": 4} if 0.5 <= t < 0.7 else {}

    inputs = {0.0: INPUTS["arm"], **_every(0.02, 0.01, 2.0, lambda lg, t: command(lg, MOVE, t)),
              0.6: INPUTS["resume"],  # still pressed: refused
              0.8: INPUTS["arm"], 0.85: INPUTS["disarm"], 0.9: INPUTS["arm"],  # not a resume
              1.0: INPUTS["resume"]}
    logic = DeadmanLogic(SETTINGS, 0.0)
    sent, _ = _run(logic, 1.2, inputs, base)
    assert (0.5, STOP) in sent  # at once, with the packet
    assert all(command == MOVE for t, command in sent if 0.02 < t < 0.5)
    assert all(command == STOP for t, command in sent if 0.5 <= t <= 1.0)
    assert [command for t, command in sent if t > 1.01][:2] == [MOVE, MOVE]
    assert logic.mode is DeadmanMode.ARMED


def test_a_refused_resume_says_why_and_holds_the_latch() -> None:
    logic = _setup("latched")
    resume(logic, 0.05)
    assert [(e.mode, e.reason) for e in logic.poll(0.05).events] == [
        (DeadmanMode.LATCHED, "resume refused: bumper pressed (centre)")]
    packet(logic, 0.06)  # released
    resume(logic, 0.07)
    assert [(e.mode, e.reason) for e in logic.poll(0.07).events] == [
        (DeadmanMode.ARMED, "re-armed by the operator (the hazard has cleared)")]
    assert logic.command == STOP  # resuming alone never moves the robot


def test_stale_feedback_latches_a_stop_at_the_feedback_timeout() -> None:
    def base(t: float) -> Bits | None:  # the base's last packet is read at 0.30
        return {} if t <= 0.3 else None

    inputs = {0.0: INPUTS["arm"], **_every(0.02, 0.01, 1.0, lambda lg, t: command(lg, MOVE, t))}
    logic = DeadmanLogic(SETTINGS, 0.0)
    sent, _ = _run(logic, 1.0, inputs, base)
    first_stop = next(t for t, command in sent if t > 0.02 and command == STOP)
    assert first_stop == pytest.approx(0.3 + SETTINGS.feedback_timeout_s)
    assert all(command == STOP for t, command in sent if t >= first_stop)
    assert logic.mode is DeadmanMode.LATCHED
    resume(logic, 1.0)  # still silent: refused
    refusal = logic.poll(1.0).events[0].reason
    assert refusal.startswith("resume refused: no feedback from the base for 0.700 s")


def test_a_packet_replayed_with_its_time_stamp_is_no_fresh_feedback() -> None:
    """An attacker's review: a device repeating one packet (the same time stamp) 10 times a
    second kept the feedback fresh while the robot moved nowhere; a bumper pressed meanwhile
    would not have been seen. Packets of a new stamp keep it fresh; a repeated stamp does not,
    and the latch says so. (The base stamps each packet anew; the u16 counter wraps.)"""
    logic = DeadmanLogic(SETTINGS, 0.0)
    for k in range(30):  # 0.6 s of packets, each with its own stamp (wrapping at 65536)
        t = 0.02 * k
        logic.on_feedback(t, SafetySensors(t, timestamp_ms=(65500 + 20 * k) % 65536))
        if k == 0:
            arm(logic, t)
        command(logic, MOVE, t)
        logic.poll(t)
    assert logic.mode is DeadmanMode.ARMED
    replayed = (65500 + 20 * 29) % 65536
    latched = []
    for k in range(30, 60):  # then the last one, over and over
        t = 0.02 * k
        logic.on_feedback(t, SafetySensors(t, timestamp_ms=replayed))
        command(logic, MOVE, t)
        latched += [e.reason for e in logic.poll(t).events]
    assert logic.mode is DeadmanMode.LATCHED
    assert latched == [f"no feedback from the base for 0.200 s (timeout 0.2 s; its packets "
                       f"repeat the time stamp {replayed} ms: the same packet replayed)"]
    # a repeated packet's hazard bits still count (a latch at once, whatever its stamp)
    bumped = DeadmanLogic(SETTINGS, 0.0)
    bumped.on_feedback(0.0, SafetySensors(0.0, timestamp_ms=7))
    arm(bumped, 0.0)
    bumped.on_feedback(0.01, SafetySensors(0.01, bumper=4, timestamp_ms=7))
    assert bumped.mode is DeadmanMode.LATCHED


def test_packets_without_sensor_data_are_no_feedback_and_the_latch_says_they_came() -> None:
    """An attacker's review: packets whose basic sensor data was cut short came 50 a second,
    and the latch said only 'no feedback from the base'."""
    logic = new_logic()
    arm(logic, 0.0)
    reasons = []
    for k in range(1, 12):
        logic.on_packet_without_sensors()
        command(logic, MOVE, 0.02 * k)
        reasons += [e.reason for e in logic.poll(0.02 * k).events]
    assert logic.mode is DeadmanMode.LATCHED
    assert reasons == ["armed by the control process",
                       "no feedback from the base for 0.200 s (timeout 0.2 s; 10 packets since "
                       "carry no readable basic sensor data)"]


def test_stale_feedback_does_not_latch_a_disarmed_deadman_but_arming_then_latches() -> None:
    logic = new_logic()
    assert logic.poll(0.5).events == () and logic.mode is DeadmanMode.DISARMED
    arm(logic, 0.5)
    events = logic.poll(0.5).events
    assert [(e.mode, e.reason) for e in events] == [
        (DeadmanMode.LATCHED, "no feedback from the base for 0.500 s (timeout 0.2 s)")]


def test_arming_before_any_feedback_latches() -> None:
    logic = DeadmanLogic(SETTINGS, 0.0)
    arm(logic, 0.0)
    assert logic.mode is DeadmanMode.LATCHED
    assert logic.poll(0.0).events[-1].reason == "no feedback from the base yet"


def test_arming_out_of_tripped_with_a_hazard_present_latches_instead() -> None:
    logic = _setup("tripped")
    packet(logic, 0.05, cliff=4)  # tripped: already stopped, the latch comes with the arm
    assert logic.mode is DeadmanMode.TRIPPED
    arm(logic, 0.06)
    assert logic.mode is DeadmanMode.LATCHED
    command(logic, MOVE, 0.07)
    assert logic.poll(0.08).send == STOP


# ---- the envelope -----------------------------------------------------------------------------
ENVELOPE = Envelope(max_linear_m_s=0.5, max_angular_rad_s=2.0, max_linear_accel_m_s2=1.0,
                    max_angular_accel_rad_s2=10.0)
ENVELOPED = DeadmanSettings(heartbeat_timeout_s=0.2, command_period_s=0.02, orphan_stop_s=0.5,
                            feedback_timeout_s=0.2, envelope=ENVELOPE)


def _ticks(logic: DeadmanLogic, start_s: float, count: int) -> list[VelocityCommand]:
    """What goes on the wire at the next `count` ticks (from `start_s`), the base streaming clean
    feedback and the control process's heartbeat a no-op re-arm at each."""
    sent = []
    for _ in range(count):
        t = max(start_s, logic.next_wakeup_s())
        packet(logic, t)
        arm(logic, t)
        action = logic.poll(t)
        assert action.send is not None
        sent.append(action.send)
    return sent


def test_increases_are_ramped_per_command_period() -> None:
    logic = new_logic(ENVELOPED)
    arm(logic, 0.0)
    logic.poll(0.0)
    command(logic, VelocityCommand(0.1, 0.5), 0.01)
    sent = _ticks(logic, 0.02, 7)
    # 1.0 m/s^2 and 10 rad/s^2 over 20 ms: 0.02 m/s and 0.2 rad/s per packet
    assert [(round(c.linear_m_s, 6), round(c.angular_rad_s, 6)) for c in sent] == [
        (0.02, 0.2), (0.04, 0.4), (0.06, 0.5), (0.08, 0.5), (0.1, 0.5), (0.1, 0.5), (0.1, 0.5)]


def test_speeds_beyond_the_envelope_are_scaled_keeping_the_curvature() -> None:
    logic = new_logic(ENVELOPED)
    arm(logic, 0.0)
    command(logic, VelocityCommand(1.0, 1.0), 0.0)  # 2x the linear limit: both halved
    sent = _ticks(logic, 0.0, 40)
    assert sent[-1] == VelocityCommand(0.5, 0.5)
    assert max(c.linear_m_s for c in sent) == 0.5


def test_decreases_and_stops_pass_at_once_and_a_reversal_goes_through_zero() -> None:
    logic = new_logic(ENVELOPED)
    arm(logic, 0.0)
    command(logic, VelocityCommand(0.3, 0.0), 0.0)
    assert _ticks(logic, 0.0, 20)[-1] == VelocityCommand(0.3, 0.0)
    command(logic, VelocityCommand(0.1, 0.0), 0.41)
    assert _ticks(logic, 0.42, 1) == [VelocityCommand(0.1, 0.0)]
    command(logic, VelocityCommand(-0.1, 0.0), 0.43)
    assert [round(c.linear_m_s, 6) for c in _ticks(logic, 0.44, 2)] == [-0.02, -0.04]
    command(logic, STOP, 0.47)
    assert logic.poll(0.47).send == STOP  # at once, not at the next tick
