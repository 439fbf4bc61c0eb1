"""Faults as data: the policy (every event's response and reason) is written out here as a literal
and the table must equal it; every event is then provoked from real inputs (observations,
feedback, frames, time, operator requests) and must get the written-out response.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import pytest

from lanewarden.actuation.base import STOP, BaseFeedback, VelocityCommand
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, Controller, ControlOutput
from lanewarden.supervisor.controller import SupervisedController
from lanewarden.supervisor.events import EVENT_TABLE, Event, Response, halt_reason, ordered
from lanewarden.supervisor.gate import SafetyGate
from lanewarden.supervisor.loop import ControlLoop, StepRecord
from tests.supervisor.rig import (
    DT,
    RecordingBase,
    Rig,
    ScriptedCamera,
    ScriptedDetector,
    observation,
)

#: The policy, written out (priority order). Changing a response in supervisor/events.py must
#: change this table too: never read the expected answers from the table under test.
EXPECTED_POLICY: dict[str, tuple[str, str]] = {
    "OPERATOR_STOP": ("HALT", "operator stop"),
    "DEADMAN_LATCHED": ("HALT", "the dead-man latched a stop on its own, held until a resume"),
    "BUMPER": ("HALT", "bumper pressed"),
    "CLIFF": ("HALT", "cliff sensor triggered"),
    "WHEEL_DROP": ("HALT", "wheel dropped"),
    "BASE_LINK_LOST": ("HALT", "link lost (no feedback, or a command not written)"),
    "BATTERY_CRITICAL": (
        "HALT", "battery below battery_critical_v: charge it before the base browns out"),
    "CAMERA_ERROR": ("HALT", "the frame source raised an error"),
    "PERCEPTION_ERROR": ("HALT", "perception raised an error"),
    "CONTROLLER_ERROR": ("HALT", "the controller raised an error or returned a malformed output"),
    "MALFORMED_OBSERVATION": (
        "HALT", "perception returned a malformed observation (non-finite or out of range)"),
    "FRAME_INVALID": (
        "HALT", "frame timestamp or index is invalid (from the future, backwards or not finite)"),
    "CLOCK_INVALID": ("HALT", "step time went backwards or is not finite"),
    "FRAME_STALE": ("HALT", "newest camera frame older than frame_stale_s"),
    "FRAME_FROZEN": ("HALT", "camera frames identical while moving (frozen camera)"),
    "LANE_DEPARTURE": ("HALT", "a lane edge inside the robot's footprint for "
                               "lane_departure_frames frames (leaving the lane)"),
    "LANE_LOST": ("HALT", "no usable lane for longer than lane_lost_halt_s"),
    "DEGRADED_BUDGET_EXHAUSTED": ("HALT", "degraded for longer than its time or distance budget"),
    "FRAME_LATE": ("DEGRADE", "newest camera frame is late"),
    "BASE_FEEDBACK_LATE": ("DEGRADE", "base feedback is late"),
    "BOTH_EDGES_LOST": ("DEGRADE", "neither lane edge found in this frame"),
    "LANE_UNTRUSTED": ("DEGRADE", "lane confidence below the usable minimum"),
    "ONE_EDGE_LOST": ("DEGRADE", "only one lane edge found in this frame"),
    "LANE_LOW_CONFIDENCE": (
        "DEGRADE", "lane confidence low for low_confidence_degrade_frames frames"),
    "REPEATED_OUTLIERS": ("DEGRADE", "slope-sum outliers repeated within outliers_window_frames"),
    "INNOVATION_OUTLIER": ("WARN", "slope-sum measurement rejected by the gate"),
    "LOOP_OVERRUN": ("WARN", "control step came later than loop_overrun_s"),
    "BATTERY_LOW": ("WARN", "battery below battery_low_v: charge it soon"),
}  # fmt: skip


#: A provoker that has not seen its event after this many steps (10 s) gives up (no test hangs).
MAX_STEPS = 300


def test_the_event_table_is_exactly_the_written_policy_in_priority_order() -> None:
    table = {event.value: (rule.response.name, rule.reason) for event, rule in EVENT_TABLE.items()}
    assert table == EXPECTED_POLICY
    assert [event.value for event in Event] == list(EXPECTED_POLICY)


@dataclass(frozen=True)
class Provoked:
    before: str
    after: str
    events: frozenset[str]
    command: VelocityCommand
    halt_reason: str | None


def _from(before: str, out: ControlOutput | StepRecord) -> Provoked:
    names = frozenset(e if isinstance(e, str) else e.value for e in out.events)
    return Provoked(before, out.state, names, out.command, out.halt_reason)


def _engaged(config: SupervisorConfig | None = None) -> Rig:
    rig = Rig(config)
    rig.engage()
    rig.run(15)  # let the limiter ramp up: the robot is moving
    assert rig.state == "FOLLOW" and not rig.outputs[-1].command.is_stop
    return rig


def _loop_engaged(
    camera: ScriptedCamera | None = None,
    detector: ScriptedDetector | None = None,
    base: RecordingBase | None = None,
    controller: Controller | None = None,
) -> tuple[ControlLoop, RecordingBase, list[StepRecord], float]:
    base = base or RecordingBase()
    records: list[StepRecord] = []
    loop = ControlLoop(
        camera or ScriptedCamera(),
        detector or ScriptedDetector(),
        SafetyGate(controller or SupervisedController(SupervisorConfig()), SupervisorConfig()),
        base,
        record=records.append,
    )
    loop.start(0.0)
    now = 0.0
    for i in range(30):
        now = i * DT
        loop.step(now)
    assert records[-1].state == "FOLLOW"
    return loop, base, records, now


# --- one provoker per event ---------------------------------------------------------------


def _operator_stop() -> Provoked:
    loop, base, records, now = _loop_engaged()
    loop.operator_stop(now + 0.01)
    assert base.sent[-1] == (now + 0.01, STOP), "operator stop must reach the base at once"
    return _from("FOLLOW", loop.step(now + DT))


def _feedback_bits(**bits: int) -> Callable[[], Provoked]:
    def provoke() -> Provoked:
        rig = _engaged()
        now = rig.clock.now() + DT
        return _from("FOLLOW", rig.step(feedback=BaseFeedback(received_at_s=now, **bits)))

    return provoke


def _deadman_latched() -> Provoked:
    # the base's own safety monitor holds a stop the gate has not seen the cause of (a bumper
    # pulse while the control process was frozen): the feedback says so, the bits are clear
    rig = _engaged()
    now = rig.clock.now() + DT
    out = rig.step(feedback=BaseFeedback(received_at_s=now, stop_latched="bumper pressed (left)"))
    assert out.halt_reason == ("DEADMAN_LATCHED: the dead-man latched a stop on its own, held "
                               "until a resume (bumper pressed (left))")
    return _from("FOLLOW", out)


def _battery(volts: float) -> Callable[[], Provoked]:
    def provoke() -> Provoked:
        rig = _engaged()
        now = rig.clock.now() + DT
        return _from("FOLLOW", rig.step(feedback=BaseFeedback(received_at_s=now,
                                                              battery_v=volts)))

    return provoke


def _base_link_lost() -> Provoked:
    rig = _engaged()
    silent_since = rig.clock.now()
    out = rig.step(feedback=BaseFeedback(received_at_s=silent_since))
    while out.state != "HALT" and len(rig.outputs) < MAX_STEPS:
        out = rig.step(feedback=BaseFeedback(received_at_s=silent_since))
    assert rig.clock.now() - silent_since <= rig.config.base_link_timeout_s + DT + 1e-9
    return _from("DEGRADED", out)  # feedback late first (DEGRADE), then lost (HALT)


def _camera_error() -> Provoked:
    loop, _, _, now = _loop_engaged(camera=ScriptedCamera(fail_at_s=1.0 - 1e-6))
    return _from("FOLLOW", loop.step(1.0))


def _perception_error() -> Provoked:
    def script(i: int, t: float):  # type: ignore[no-untyped-def]
        if i >= 30:
            raise ValueError("cv2.error: (-215) unexpected image layout")
        return observation(i, t)

    loop, _, _, now = _loop_engaged(detector=ScriptedDetector(script))
    record = loop.step(30 * DT)
    assert record.halt_reason is not None and "cv2.error" in record.halt_reason
    return _from("FOLLOW", record)


class _BugFrom:
    """The supervised controller with a bug that strikes from `from_s` on. A controller's bug has
    no real part to inject it into (camera, link, floor): this is the one fault that has to be
    injected into the controller itself, and only ever around the real one."""

    def __init__(self, from_s: float) -> None:
        self.inner = SupervisedController(SupervisorConfig())
        self.from_s = from_s

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        if now >= self.from_s:
            raise ZeroDivisionError("float division by zero")
        return self.inner.step(inputs, now)


def _controller_error() -> Provoked:
    loop, base, _, now = _loop_engaged(controller=_BugFrom(30 * DT))
    record = loop.step(30 * DT)  # no traceback: a HALT, and a stop on the wire
    assert base.sent[-1] == (30 * DT, STOP)
    assert record.halt_reason == (
        "CONTROLLER_ERROR: the controller raised an error or returned a malformed output "
        "(_BugFrom raised ZeroDivisionError: float division by zero)")
    return _from("FOLLOW", record)


def _malformed() -> Provoked:
    rig = _engaged()
    return _from("FOLLOW", rig.step(slope_sum=math.nan))


def _frame_invalid() -> Provoked:
    rig = _engaged()
    return _from("FOLLOW", rig.step(latency_s=-0.5))  # a frame captured in the future


def _clock_invalid() -> Provoked:
    rig = _engaged()
    now = rig.clock.now()
    # A time source that jumps back: the step is dated before the previous one.
    inputs = ControlInputs(frame=rig.frame, feedback=BaseFeedback(received_at_s=now))
    return _from("FOLLOW", rig.gate.step(inputs, now - 0.5))


def _frame_stale() -> Provoked:
    rig = _engaged()
    out = rig.step(new_frame=False)
    while out.state != "HALT" and len(rig.outputs) < MAX_STEPS:
        out = rig.step(new_frame=False)
    return _from("DEGRADED", out)  # late first, then stale


def _frame_frozen() -> Provoked:
    rig = _engaged()
    out = rig.step(fingerprint=b"same")
    while out.state != "HALT" and len(rig.outputs) < MAX_STEPS:
        out = rig.step(fingerprint=b"same")
    return _from("FOLLOW", out)


def _lane_lost() -> Provoked:
    rig = _engaged()
    seen_last = rig.clock.now()  # the last usable lane
    out = rig.step(left=False, right=False, confidence=0.0)
    while out.state != "HALT" and len(rig.outputs) < MAX_STEPS:
        out = rig.step(left=False, right=False, confidence=0.0)
    # after more than lane_lost_halt_s (0.2 s) without a usable lane, at the first frame past it
    assert 0.2 < rig.clock.now() - seen_last <= 0.2 + DT + 1e-9
    return _from("DEGRADED", out)


def _lane_departure() -> Provoked:
    rig = _engaged()
    for _ in range(rig.config.lane_departure_frames - 1):
        assert rig.step(left_edge_m=0.12).state == "FOLLOW"
    return _from("FOLLOW", rig.step(left_edge_m=0.12))


def _budget_exhausted() -> Provoked:
    rig = _engaged()
    out = rig.step(right=False, confidence=0.5)
    while out.state != "HALT" and len(rig.outputs) < MAX_STEPS:
        out = rig.step(right=False, confidence=0.5)
    return _from("DEGRADED", out)


def _frame_late() -> Provoked:
    rig = _engaged()
    out = rig.step(new_frame=False)  # the camera skips a few frames: the newest one ages
    while "FRAME_LATE" not in {e.value for e in out.events} and len(rig.outputs) < MAX_STEPS:
        assert out.state == "FOLLOW"
        out = rig.step(new_frame=False)
    return _from("FOLLOW", out)


def _feedback_late() -> Provoked:
    rig = _engaged()
    now = rig.clock.now() + DT
    return _from("FOLLOW", rig.step(feedback=BaseFeedback(received_at_s=now - 0.15)))


def _both_edges_lost() -> Provoked:
    return _from("FOLLOW", _engaged().step(left=False, right=False, confidence=0.0))


def _lane_untrusted() -> Provoked:
    return _from("FOLLOW", _engaged().step(confidence=0.1))


def _one_edge_lost() -> Provoked:
    return _from("FOLLOW", _engaged().step(left=False, confidence=0.5))


def _low_confidence() -> Provoked:
    rig = _engaged()
    k = rig.config.low_confidence_degrade_frames
    for _ in range(k - 1):
        assert rig.step(confidence=0.3).state == "FOLLOW"
    return _from("FOLLOW", rig.step(confidence=0.3))


def _repeated_outliers() -> Provoked:
    rig = _engaged()
    for value in (15.0, -15.0):
        assert rig.step(slope_sum=value).state == "FOLLOW"
    return _from("FOLLOW", rig.step(slope_sum=15.0))


def _innovation_outlier() -> Provoked:
    return _from("FOLLOW", _engaged().step(slope_sum=25.0))


def _loop_overrun() -> Provoked:
    # The step comes late, but brings a fresh frame and fresh feedback: only the overrun remains.
    return _from("FOLLOW", _engaged().step(advance_s=0.15))


PROVOKERS: dict[Event, Callable[[], Provoked]] = {
    Event.OPERATOR_STOP: _operator_stop,
    Event.BUMPER: _feedback_bits(bumper=2),
    Event.CLIFF: _feedback_bits(cliff=4),
    Event.WHEEL_DROP: _feedback_bits(wheel_drop=1),
    Event.DEADMAN_LATCHED: _deadman_latched,
    Event.BASE_LINK_LOST: _base_link_lost,
    Event.BATTERY_CRITICAL: _battery(13.1),  # the Kobuki driver's dangerous level is 13.2 V
    Event.CAMERA_ERROR: _camera_error,
    Event.PERCEPTION_ERROR: _perception_error,
    Event.CONTROLLER_ERROR: _controller_error,
    Event.MALFORMED_OBSERVATION: _malformed,
    Event.FRAME_INVALID: _frame_invalid,
    Event.CLOCK_INVALID: _clock_invalid,
    Event.FRAME_STALE: _frame_stale,
    Event.FRAME_FROZEN: _frame_frozen,
    Event.LANE_DEPARTURE: _lane_departure,
    Event.LANE_LOST: _lane_lost,
    Event.DEGRADED_BUDGET_EXHAUSTED: _budget_exhausted,
    Event.FRAME_LATE: _frame_late,
    Event.BASE_FEEDBACK_LATE: _feedback_late,
    Event.BOTH_EDGES_LOST: _both_edges_lost,
    Event.LANE_UNTRUSTED: _lane_untrusted,
    Event.ONE_EDGE_LOST: _one_edge_lost,
    Event.LANE_LOW_CONFIDENCE: _low_confidence,
    Event.REPEATED_OUTLIERS: _repeated_outliers,
    Event.INNOVATION_OUTLIER: _innovation_outlier,
    Event.BATTERY_LOW: _battery(13.9),  # below the low level 14.0 V, above the dangerous one
    Event.LOOP_OVERRUN: _loop_overrun,
}


def test_every_event_has_exactly_one_row_with_a_one_line_reason() -> None:
    assert set(EVENT_TABLE) == set(Event)
    for event, rule in EVENT_TABLE.items():
        assert isinstance(rule.response, Response), event
        assert rule.reason.strip() and "\n" not in rule.reason, event


def test_every_row_has_a_provoking_test() -> None:
    assert set(PROVOKERS) == set(Event)


@pytest.mark.parametrize("event", list(Event), ids=lambda e: e.value)
def test_event_is_provoked_from_real_inputs_and_gets_its_response(event: Event) -> None:
    result = PROVOKERS[event]()
    assert event.value in result.events, result
    response = EXPECTED_POLICY[event.value][0]
    if response == "HALT":
        assert result.after == "HALT"
        assert result.command == STOP
        # halted by this event (or one before it in priority, in the same step), not by a later
        # fault its provoker went on to cause
        assert result.halt_reason is not None, result
        named = result.halt_reason.split(":", 1)[0]
        order = list(EXPECTED_POLICY)
        assert named in result.events and EXPECTED_POLICY[named][0] == "HALT", result
        assert order.index(named) <= order.index(event.value), result
    elif response == "DEGRADE":
        assert result.after == "DEGRADED"
        config = SupervisorConfig()
        assert 0.0 < result.command.linear_m_s <= config.follow_speed_m_s
        assert abs(result.command.angular_rad_s) <= config.degraded_max_angular_rad_s
    else:
        assert result.after == result.before
        assert not result.command.is_stop


def test_halt_reason_picks_the_highest_priority_halt_event_with_detail() -> None:
    events = {Event.FRAME_LATE, Event.LANE_LOST, Event.BUMPER}
    reason = halt_reason(events, {Event.BUMPER: "centre"})
    assert reason == "BUMPER: bumper pressed (centre)"
    assert halt_reason({Event.FRAME_LATE, Event.LOOP_OVERRUN}) is None
    assert ordered(events) == (Event.BUMPER, Event.LANE_LOST, Event.FRAME_LATE)
