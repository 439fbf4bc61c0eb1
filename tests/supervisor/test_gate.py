"""The SafetyGate: whatever a controller asks for, only what the gate allows reaches the base.

Expected numbers are written out (at 30 Hz with the default limits: +0.01 m/s and +0.116667 rad/s
per step, caps 0.3 m/s and 1.0 rad/s for driving, 0.7 m/s and pi rad/s for bring-up), and so are
the events the gate halts on by itself: the event table is checked against them, never the other
way round. The random version, with hostile controllers: test_gate_properties.py."""

from __future__ import annotations

import importlib
import math
import sys
from dataclasses import dataclass, field

import pytest

from lanewarden.actuation.base import STOP, BaseFeedback, VelocityCommand
from lanewarden.actuation.sim_base import SimBase
from lanewarden.assembly import build_bring_up_gate
from lanewarden.config import LanewardenConfig
from lanewarden.supervisor import events as event_policy
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, ControlOutput
from lanewarden.supervisor.controllers import FixedCommand
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.events import EVENT_TABLE, Event, EventRule, Response
from lanewarden.supervisor.gate import (
    GATE_HALT_EVENTS,
    PHYSICAL_HAZARDS,
    SafetyGate,
    check_event_table,
)
from lanewarden.supervisor.lecture import LectureController
from lanewarden.supervisor.loop import ControlLoop, StepRecord
from tests.supervisor.rig import DT, RecordingBase, ScriptedCamera, ScriptedDetector

#: The gate's halt reason for a lost base link, written out.
LINK_LOST = "BASE_LINK_LOST: link lost (no feedback, or a command not written)"

CONFIG = SupervisorConfig()
LINEAR_STEP = 0.01  # 0.3 m/s^2 * 1/30 s
ANGULAR_STEP = 3.5 / 30.0
FAST = VelocityCommand(0.7, 3.0)  # beyond both driving caps


@dataclass
class Misbehaving:
    """A controller that does everything wrong: it wants full speed at once from the first step,
    ignores start, bumpers and lost links, and sometimes says HALT while asking to move."""

    wants: VelocityCommand = FAST
    says_halt_at: set[int] = field(default_factory=set)
    raises_at: set[int] = field(default_factory=set)
    steps: int = 0
    seen: list[ControlInputs] = field(default_factory=list)

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        self.seen.append(inputs)
        state = "HALT" if self.steps in self.says_halt_at else "FOLLOW"
        self.steps += 1
        if self.steps - 1 in self.raises_at:
            raise RuntimeError("lost my place\n  in the lane")
        return ControlOutput(command=self.wants, state=state)


@dataclass
class Returns:
    """A controller that returns the same (malformed) thing every step."""

    returned: object

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        return self.returned  # type: ignore[return-value]


def _inputs(now: float, **kw: object) -> ControlInputs:
    fields: dict[str, object] = {"feedback": BaseFeedback(received_at_s=now), **kw}
    return ControlInputs(**fields)  # type: ignore[arg-type]


def _run(gate: SafetyGate, steps: int, start: float = 0.0, **kw: object) -> list[ControlOutput]:
    return [gate.step(_inputs(start + i * DT, **kw), start + i * DT) for i in range(steps)]


# --- the acceptance test: a misbehaving controller in the real loop ---------------------------


def test_a_misbehaving_controller_never_reaches_the_base_unfiltered() -> None:
    controller = Misbehaving(says_halt_at={40})
    base = RecordingBase()
    records: list[StepRecord] = []
    loop = ControlLoop(ScriptedCamera(), ScriptedDetector(), SafetyGate(controller, CONFIG), base,
                       record=records.append)  # fmt: skip
    sent = base.sent

    for k in range(10):  # asks to move before anyone pressed start
        loop.step(k * DT)
    assert [c for _, c in sent] == [STOP] * 10

    loop.start(10 * DT)
    for k in range(10, 40):  # skips the ramp: wants 0.7 m/s, 3 rad/s at once
        loop.step(k * DT)
    moving = [c for _, c in sent[10:]]
    assert moving[0].linear_m_s == pytest.approx(LINEAR_STEP)
    assert moving[0].angular_rad_s == pytest.approx(ANGULAR_STEP)
    assert moving[-1] == VelocityCommand(0.3, 1.0)  # the caps, reached by ramping
    for before, after in zip(moving, moving[1:], strict=False):
        assert after.linear_m_s - before.linear_m_s <= LINEAR_STEP + 1e-12
        assert after.angular_rad_s - before.angular_rad_s <= ANGULAR_STEP + 1e-12

    loop.step(40 * DT)  # says HALT but asks to move
    assert sent[-1] == (40 * DT, STOP) and records[-1].state == "HALT"
    loop.step(41 * DT)  # moves again, from zero
    assert sent[-1][1].linear_m_s == pytest.approx(LINEAR_STEP)

    base.bumper = 4  # ignores a pressed bumper
    loop.step(42 * DT)
    assert sent[-1] == (42 * DT, STOP)
    assert records[-1].halt_reason == "BUMPER: bumper pressed (left)"
    base.bumper = 0  # released: the latch holds until resume
    for k in range(43, 60):
        loop.step(k * DT)
    assert all(c == STOP for _, c in sent[-17:])
    assert all(r.state == "HALT" for r in records[-17:])

    loop.resume(60 * DT)
    loop.step(60 * DT)
    assert sent[-1][1].linear_m_s == pytest.approx(LINEAR_STEP)

    base.link_alive_until_s = 61 * DT  # the base falls silent: the controller does not care
    for k in range(61, 75):
        loop.step(k * DT)
    halted = [r for r in records if r.time_s > 61 * DT and r.state == "HALT"]
    assert halted and halted[0].time_s <= 61 * DT + 0.2 + DT + 1e-9
    assert halted[0].halt_reason == (
        f"{LINK_LOST} (no new feedback: the newest arrived 0.20 s ago, over the limit 0.2 s)")
    assert all(c == STOP for t, c in sent if t >= halted[0].time_s)

    # It was told every hazard, and what was really sent; it just ignored them.
    assert Event.BUMPER in controller.seen[42].events
    assert controller.seen[42].previous_command != STOP


def test_nothing_non_zero_leaves_while_halted_on_a_simulated_base() -> None:
    base = SimBase()
    gate = SafetyGate(Misbehaving(), CONFIG)
    loop = ControlLoop(ScriptedCamera(), ScriptedDetector(), gate, base)
    loop.start(0.0)
    for k in range(40):
        loop.step(k * DT)
    assert base.commanded == VelocityCommand(0.3, 1.0)
    base.inject(cliff=2)
    loop.step(40 * DT)
    assert base.commanded == STOP
    base.inject(cliff=0)
    for k in range(41, 70):
        loop.step(k * DT)
        assert base.commanded == STOP


# --- the rules one by one ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("hazard", "reason"),
    [
        ({"events": frozenset({Event.OPERATOR_STOP})}, "OPERATOR_STOP: operator stop"),
        ({"feedback_bits": {"bumper": 2}}, "BUMPER: bumper pressed (centre)"),
        ({"feedback_bits": {"cliff": 5}}, "CLIFF: cliff sensor triggered (left, right)"),
        ({"feedback_bits": {"wheel_drop": 2}}, "WHEEL_DROP: wheel dropped (left)"),
        ({"events": frozenset({Event.BASE_LINK_LOST}),
          "event_details": {Event.BASE_LINK_LOST: "/dev/ttyUSB0: write failed"}},
         f"{LINK_LOST} (/dev/ttyUSB0: write failed)"),
        ({"feedback_age_s": 0.21},
         f"{LINK_LOST} (no new feedback: the newest arrived 0.21 s ago, over the limit 0.2 s)"),
        ({"feedback_bits": {"battery_v": 13.1}},
         "BATTERY_CRITICAL: battery below battery_critical_v: charge it before the base browns "
         "out (13.1 V)"),
    ],
    ids=["operator-stop", "bumper", "cliff", "wheel-drop", "link-lost-by-loop", "link-lost-by-age",
         "battery-critical"],
)
def test_each_physical_hazard_halts_at_once_and_latches_until_resume(
    hazard: dict[str, object], reason: str
) -> None:
    gate = SafetyGate(Misbehaving(), CONFIG)
    gate.step(_inputs(0.0, start_requested=True), 0.0)
    _run(gate, 20, start=DT)
    now = 21 * DT
    bits = hazard.get("feedback_bits", {})
    assert isinstance(bits, dict)
    received = now - float(hazard.get("feedback_age_s", 0.0))  # type: ignore[arg-type]
    kw = {k: v for k, v in hazard.items() if k in ("events", "event_details")}
    out = gate.step(_inputs(now, feedback=BaseFeedback(received_at_s=received, **bits), **kw), now)
    assert (out.state, out.command, out.halt_reason) == ("HALT", STOP, reason)
    later = _run(gate, 10, start=now + DT)  # the hazard is gone; no resume yet
    assert all((o.state, o.command) == ("HALT", STOP) for o in later)
    resumed = gate.step(_inputs(now + 11 * DT, resume_requested=True), now + 11 * DT)
    assert resumed.state == "FOLLOW" and resumed.command.linear_m_s == pytest.approx(LINEAR_STEP)


def test_a_low_battery_only_warns_and_never_releases_a_latch() -> None:
    gate = SafetyGate(Misbehaving(), CONFIG)
    gate.step(_inputs(0.0, start_requested=True), 0.0)
    _run(gate, 20, start=DT)
    now = 21 * DT
    low = BaseFeedback(received_at_s=now, battery_v=13.9)  # below 14.0, above 13.2
    out = gate.step(_inputs(now, feedback=low), now)
    assert out.state == "FOLLOW" and Event.BATTERY_LOW in out.events and not out.command.is_stop
    bumped = gate.step(_inputs(now + DT, feedback=BaseFeedback(received_at_s=now + DT, bumper=1)),
                       now + DT)
    assert bumped.command == STOP
    # a warning alone in a later step must not count as "no hazard" and unlatch the HALT
    later = gate.step(_inputs(now + 2 * DT, feedback=BaseFeedback(received_at_s=now + 2 * DT,
                                                                  battery_v=13.9)), now + 2 * DT)
    assert (later.state, later.command) == ("HALT", STOP)


def test_a_resume_in_the_same_step_as_a_hazard_does_not_release() -> None:
    gate = SafetyGate(Misbehaving(), CONFIG)
    gate.step(_inputs(0.0, start_requested=True), 0.0)
    out = gate.step(_inputs(DT, feedback=BaseFeedback(received_at_s=DT, bumper=1),
                            resume_requested=True), DT)  # fmt: skip
    assert out.command == STOP
    assert all(o.command == STOP for o in _run(gate, 5, start=2 * DT))


def test_a_stop_is_never_delayed_and_slowing_down_is_immediate() -> None:
    controller = Misbehaving(wants=VelocityCommand(0.3, 0.5))
    gate = SafetyGate(controller, CONFIG)
    gate.step(_inputs(0.0, start_requested=True), 0.0)
    assert _run(gate, 40, start=DT)[-1].command == VelocityCommand(0.3, 0.5)
    controller.wants = VelocityCommand(0.05, -0.2)  # slower, and turning the other way
    out = gate.step(_inputs(41 * DT), 41 * DT)
    assert out.command.linear_m_s == 0.05  # at once
    assert out.command.angular_rad_s == pytest.approx(-ANGULAR_STEP)  # through zero, then ramped
    controller.wants = STOP
    assert gate.step(_inputs(42 * DT), 42 * DT).command == STOP


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_a_non_finite_command_or_clock_gives_zero(bad: float) -> None:
    controller = Misbehaving(wants=VelocityCommand(bad, 0.0))
    gate = SafetyGate(controller, CONFIG)
    gate.step(_inputs(0.0, start_requested=True), 0.0)
    assert gate.step(_inputs(DT), DT).command == STOP
    controller.wants = VelocityCommand(0.2, 0.0)
    assert gate.step(_inputs(2 * DT), 2 * DT).command.linear_m_s == pytest.approx(LINEAR_STEP)
    out = gate.step(_inputs(3 * DT), bad)
    assert (out.state, out.command) == ("HALT", STOP)
    assert out.halt_reason == "CLOCK_INVALID: step time went backwards or is not finite"
    back = gate.step(_inputs(DT), DT)  # before the previous valid step
    assert back.command == STOP


def test_the_lecture_controller_gets_its_physical_stops_from_the_gate() -> None:
    lecture = LectureController(CONFIG)
    bumped = _inputs(0.0, feedback=BaseFeedback(received_at_s=0.0, bumper=1))
    assert lecture.step(bumped, 0.0).state == "FOLLOW"  # alone, it would drive on
    gate = SafetyGate(LectureController(CONFIG), CONFIG)
    gate.step(_inputs(0.0, start_requested=True), 0.0)
    assert gate.step(_inputs(DT), DT).command.linear_m_s == pytest.approx(LINEAR_STEP)
    out = gate.step(_inputs(2 * DT, feedback=BaseFeedback(received_at_s=2 * DT, bumper=1)), 2 * DT)
    assert (out.state, out.command, out.halt_reason) == (
        "HALT", STOP, "BUMPER: bumper pressed (right)")


def test_bring_up_gate_ramps_to_the_base_limits_and_halts_on_hazards() -> None:
    gate = build_bring_up_gate(LanewardenConfig(), VelocityCommand(0.7, -math.pi))
    outs = [gate.step(_inputs(i * DT, start_requested=i == 0), i * DT) for i in range(100)]
    assert outs[0].command == STOP  # dt = 0 at the first step
    assert outs[1].command.linear_m_s == pytest.approx(LINEAR_STEP)
    assert outs[-1].command == VelocityCommand(0.7, -math.pi)
    assert outs[-1].state == "BRING_UP"
    hit = gate.step(_inputs(3.4, feedback=BaseFeedback(received_at_s=3.4, wheel_drop=1)), 3.4)
    assert (hit.command, hit.halt_reason) == (STOP, "WHEEL_DROP: wheel dropped (right)")


def test_a_base_that_never_answered_halts_saying_so() -> None:
    gate = SafetyGate(Misbehaving(), CONFIG)
    silent = BaseFeedback(received_at_s=None)
    gate.step(_inputs(0.0, start_requested=True, feedback=silent), 0.0)
    # steps 1/30 .. 7/30 s: over the 0.2 s limit at the seventh, 0.233 s
    outputs = _run(gate, 7, start=DT, feedback=silent)
    assert not any("BASE_LINK_LOST" in (o.halt_reason or "") for o in outputs[:6])
    assert outputs[6].halt_reason == f"{LINK_LOST} (no feedback at all in 0.23 s)"


# --- one truth: the events the gate halts on are its own -------------------------------------

#: Written out: the gate latches these, whatever the controller and whatever the event table says.
HAZARDS = {
    "operator-stop": ({"events": frozenset({Event.OPERATOR_STOP})}, "OPERATOR_STOP: operator stop"),
    "bumper": ({"feedback_bits": {"bumper": 4}}, "BUMPER: bumper pressed (left)"),
    "cliff": ({"feedback_bits": {"cliff": 1}}, "CLIFF: cliff sensor triggered (right)"),
    "wheel-drop": ({"feedback_bits": {"wheel_drop": 3}}, "WHEEL_DROP: wheel dropped (left, right)"),
    "link-lost": ({"feedback_age_s": 0.5},
                  f"{LINK_LOST} (no new feedback: the newest arrived 0.50 s ago, over the limit "
                  "0.2 s)"),
    "battery-critical": ({"feedback_bits": {"battery_v": 12.0}},
                         "BATTERY_CRITICAL: battery below battery_critical_v: charge it before the "
                         "base browns out (12.0 V)"),
}  # fmt: skip


def _hazard_inputs(now: float, hazard: dict[str, object], **kw: object) -> ControlInputs:
    bits = hazard.get("feedback_bits", {})
    assert isinstance(bits, dict)
    received = now - float(hazard.get("feedback_age_s", 0.0))  # type: ignore[arg-type]
    extra = {k: v for k, v in hazard.items() if k in ("events", "event_details")}
    return _inputs(now, feedback=BaseFeedback(received_at_s=received, **bits), **extra, **kw)


def test_the_gate_halts_by_itself_on_a_fixed_set_of_events() -> None:
    assert sorted(e.value for e in PHYSICAL_HAZARDS) == [
        "BASE_LINK_LOST", "BATTERY_CRITICAL", "BUMPER", "CLIFF", "DEADMAN_LATCHED",
        "OPERATOR_STOP", "WHEEL_DROP"]
    assert sorted(e.value for e in GATE_HALT_EVENTS) == [
        "BASE_LINK_LOST", "BATTERY_CRITICAL", "BUMPER", "CLIFF", "CLOCK_INVALID",
        "CONTROLLER_ERROR", "DEADMAN_LATCHED", "OPERATOR_STOP", "WHEEL_DROP"]


def test_the_event_table_is_checked_against_the_gate() -> None:
    check_event_table(EVENT_TABLE)  # the real table agrees (it is also checked at import)
    demoted = {**EVENT_TABLE, Event.BUMPER: EventRule(Response.WARN, "bumper pressed"),
               Event.CONTROLLER_ERROR: EventRule(Response.DEGRADE, "controller trouble")}
    with pytest.raises(SupervisorError) as err:
        check_event_table(demoted)
    assert str(err.value) == (
        "supervisor/events.py: EVENT_TABLE must give HALT to every event the SafetyGate halts "
        "on; it does not for BUMPER, CONTROLLER_ERROR")
    without_cliff = {e: rule for e, rule in EVENT_TABLE.items() if e is not Event.CLIFF}
    with pytest.raises(SupervisorError, match=r"it does not for CLIFF$"):
        check_event_table(without_cliff)


def test_the_gate_refuses_to_load_beside_a_table_that_demotes_its_events(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    demoted = {**EVENT_TABLE, Event.WHEEL_DROP: EventRule(Response.DEGRADE, "wheel dropped")}
    monkeypatch.setattr(event_policy, "EVENT_TABLE", demoted)
    monkeypatch.delitem(sys.modules, "lanewarden.supervisor.gate")  # put back afterwards
    with pytest.raises(SupervisorError, match=r"it does not for WHEEL_DROP$"):
        importlib.import_module("lanewarden.supervisor.gate")


@pytest.mark.parametrize("name", list(HAZARDS))
def test_physical_hazards_latch_whatever_the_event_table_says(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The issue's bring-up case: with BUMPER demoted in the table, a bumper press before start
    cleared the not-started latch and `base drive` ramped off. The gate must not ask the table."""
    for event in PHYSICAL_HAZARDS:  # what the state machine and the records would now read
        monkeypatch.setitem(event_policy._RESPONSES, event, Response.WARN)
    hazard, reason = HAZARDS[name]
    gate = SafetyGate(FixedCommand(VelocityCommand(0.05, 0.0)), CONFIG)
    out = gate.step(_hazard_inputs(0.0, hazard), 0.0)
    assert (out.state, out.command, out.halt_reason) == ("HALT", STOP, reason)
    later = _run(gate, 5, start=DT)  # the hazard is gone: still not started
    assert all((o.state, o.command) == ("HALT", STOP) for o in later)
    out = gate.step(_inputs(6 * DT, start_requested=True), 6 * DT)
    assert (out.state, out.command.linear_m_s) == ("BRING_UP", pytest.approx(LINEAR_STEP))
    out = gate.step(_hazard_inputs(7 * DT, hazard), 7 * DT)
    assert (out.state, out.command, out.halt_reason) == ("HALT", STOP, reason)
    assert all(o.command == STOP for o in _run(gate, 5, start=8 * DT))  # latched until resume
    out = gate.step(_inputs(13 * DT, resume_requested=True), 13 * DT)
    assert out.command.linear_m_s == pytest.approx(LINEAR_STEP)


def test_only_a_start_ends_the_first_latch() -> None:
    controller = Misbehaving()
    gate = SafetyGate(controller, CONFIG)
    not_started = "not engaged yet: waiting for start and a confident lane"
    out = gate.step(_inputs(0.0, resume_requested=True), 0.0)  # a resume before any start
    assert (out.state, out.command, out.halt_reason) == ("HALT", STOP, not_started)
    assert not controller.seen[-1].resume_requested  # the controller is not told of it
    assert gate.step(_inputs(DT), DT).command == STOP
    gate.step(_hazard_inputs(2 * DT, HAZARDS["bumper"][0]), 2 * DT)  # a hazard's latch on top
    out = gate.step(_inputs(3 * DT, resume_requested=True), 3 * DT)  # resume: still not started
    assert (out.state, out.command, out.halt_reason) == (
        "HALT", STOP, "BUMPER: bumper pressed (left)")
    out = gate.step(_hazard_inputs(4 * DT, HAZARDS["cliff"][0], start_requested=True), 4 * DT)
    assert out.command == STOP and not controller.seen[-1].start_requested  # not with a hazard
    assert gate.step(_inputs(5 * DT), 5 * DT).command == STOP
    out = gate.step(_inputs(6 * DT, start_requested=True), math.nan)  # nor at an unusable time
    assert out.command == STOP and not controller.seen[-1].start_requested
    assert gate.step(_inputs(7 * DT), 7 * DT).command == STOP
    out = gate.step(_inputs(8 * DT, start_requested=True, resume_requested=True), 8 * DT)
    assert (controller.seen[-1].start_requested, controller.seen[-1].resume_requested) == (
        True, True)
    assert (out.state, out.command.linear_m_s) == ("FOLLOW", pytest.approx(LINEAR_STEP))
    gate.step(_hazard_inputs(9 * DT, HAZARDS["wheel-drop"][0]), 9 * DT)
    out = gate.step(_inputs(10 * DT, resume_requested=True), 10 * DT)  # started: resume counts
    assert (out.state, out.command.linear_m_s) == ("FOLLOW", pytest.approx(LINEAR_STEP))


def test_a_controller_that_raises_halts_with_its_own_reason_until_resume() -> None:
    controller = Misbehaving(raises_at={20})
    base = RecordingBase()
    records: list[StepRecord] = []
    loop = ControlLoop(ScriptedCamera(), ScriptedDetector(), SafetyGate(controller, CONFIG), base,
                       record=records.append)  # fmt: skip
    loop.start(0.0)
    for k in range(20):
        loop.step(k * DT)
    assert not base.sent[-1][1].is_stop
    loop.step(20 * DT)  # raises inside: no traceback out of the loop
    reason = ("CONTROLLER_ERROR: the controller raised an error or returned a malformed output "
              "(Misbehaving raised RuntimeError: lost my place in the lane)")
    assert base.sent[-1] == (20 * DT, STOP)
    assert (records[-1].state, records[-1].halt_reason) == ("HALT", reason)
    assert "CONTROLLER_ERROR" in records[-1].events
    for k in range(21, 30):  # it works again, but nobody has looked at it: latched
        loop.step(k * DT)
        assert (base.sent[-1][1], records[-1].halt_reason) == (STOP, reason)
    loop.resume(30 * DT)
    loop.step(30 * DT)
    assert base.sent[-1][1].linear_m_s == pytest.approx(LINEAR_STEP)  # from zero again


@pytest.mark.parametrize(
    ("returned", "detail"),
    [
        (None, "returned NoneType, expected a ControlOutput"),
        (VelocityCommand(0.2, 0.0), "returned VelocityCommand, expected a ControlOutput"),
        (ControlOutput(command=VelocityCommand("fast", 0.0), state="FOLLOW"),  # type: ignore[arg-type]
         "returned the command VelocityCommand(linear_m_s='fast', angular_rad_s=0.0), expected "
         "a VelocityCommand of numbers"),
        (ControlOutput(command=(0.2, 0.0), state="FOLLOW"),  # type: ignore[arg-type]
         "returned the command (0.2, 0.0), expected a VelocityCommand of numbers"),
        (ControlOutput(command=FAST, state=None),  # type: ignore[arg-type]
         "returned the state None, expected a name"),
        (ControlOutput(command=FAST, state="FOLLOW", events=("BUMPER",)),  # type: ignore[arg-type]
         "returned the events ('BUMPER',), expected a tuple of Event"),
        (ControlOutput(command=FAST, state="FOLLOW", halt_reason=3),  # type: ignore[arg-type]
         "returned the halt reason 3, expected text"),
        (ControlOutput(command=FAST, state="FOLLOW", filtered_slope_sum="7"),  # type: ignore[arg-type]
         "returned filtered_slope_sum '7', expected a number"),
        (ControlOutput(command=FAST, state="FOLLOW", lane_trusted="yes"),  # type: ignore[arg-type]
         "returned lane_trusted 'yes', expected true or false"),
    ],
    ids=["none", "a-command", "string-speed", "tuple-command", "no-state", "string-events",
         "number-reason", "string-slope-sum", "string-trust"],
)
def test_a_malformed_controller_output_is_a_controller_error(returned: object,
                                                             detail: str) -> None:
    gate = SafetyGate(Returns(returned), CONFIG)
    out = gate.step(_inputs(0.0, start_requested=True), 0.0)
    assert (out.state, out.command, out.events) == ("HALT", STOP, (Event.CONTROLLER_ERROR,))
    assert out.halt_reason == ("CONTROLLER_ERROR: the controller raised an error or returned a "
                               f"malformed output (Returns {detail})")
    assert gate.latched_reason == out.halt_reason


def test_a_controller_error_names_a_hazard_of_the_same_step_first() -> None:
    gate = SafetyGate(Misbehaving(raises_at={1}), CONFIG)
    gate.step(_inputs(0.0, start_requested=True), 0.0)
    out = gate.step(_hazard_inputs(DT, HAZARDS["cliff"][0]), DT)
    assert (out.command, out.halt_reason) == (STOP, "CLIFF: cliff sensor triggered (right)")
    assert out.events == (Event.CLIFF, Event.CONTROLLER_ERROR)
