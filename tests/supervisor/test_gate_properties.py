"""Property: the SafetyGate, driven directly with hostile controllers, sends exactly what a small
model of its rules written out here allows, whatever the controller does.

The controllers move while halted, move before start, ignore every hazard, say HALT while asking
to move, raise, return garbage (None, strings, events that are not events) and ask for NaN,
infinite or absurd speeds. The inputs are random runs of hazards (bumper, cliff, wheel drop,
critical battery, stale or missing feedback, operator stop, a lost link), warnings, start and
resume requests and step times that go backwards or are not finite.

Unlike tests/supervisor/test_properties.py (the supervised controller zeroes its own command in
HALT, so there a gate that never latched would still pass), nothing here halts by itself but the
gate: removing any one of its rules fails this test. The model's numbers are the default config's,
written out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from hypothesis import event, given, settings
from hypothesis import strategies as st

from lanewarden.actuation.base import STOP, BaseFeedback, VelocityCommand
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, ControlOutput
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.gate import SafetyGate

DT = 1.0 / 30.0
MAX_LINEAR = 0.3  # limiter_max_linear_m_s
MAX_ANGULAR = 1.0  # limiter_max_angular_rad_s
LINEAR_ACCEL = 0.3  # max_linear_accel_m_s2
ANGULAR_ACCEL = 3.5  # max_angular_accel_rad_s2
MAX_CREDITED_STEP_S = 0.1  # loop_overrun_s: a late step buys no bigger jump
LINK_TIMEOUT_S = 0.2  # base_link_timeout_s
BATTERY_CRITICAL_V = 13.2
#: The gate's physical hazards in priority order (the first one present names the halt).
HAZARD_PRIORITY = ("OPERATOR_STOP", "BUMPER", "CLIFF", "WHEEL_DROP", "BASE_LINK_LOST",
                   "BATTERY_CRITICAL")
EPS = 1e-9

#: What a hostile controller asks for when it drives (or says HALT while driving).
WISHES = (
    VelocityCommand(0.2, 0.5), VelocityCommand(-0.25, -0.8), VelocityCommand(0.05, 0.0),
    VelocityCommand(0.0, -0.3), VelocityCommand(1e9, -1e9), VelocityCommand(-7.0, 40.0),
    VelocityCommand(math.nan, 0.0), VelocityCommand(0.1, math.inf), VelocityCommand(-math.inf, 0.0),
    STOP,
)
#: Ways to fail: raise, or return something that is not a well-formed ControlOutput.
FAILURES = ("raises", "returns_none", "string_command", "string_events", "state_not_text")


@dataclass(frozen=True)
class Act:
    """One step of a hostile controller: 'drive' or 'says_halt' with `wish`, or a failure."""

    kind: str
    wish: VelocityCommand = STOP


@dataclass
class Hostile:
    """Plays its script, one act per step; ignores everything it is told (but keeps it)."""

    script: list[Act]
    seen: list[ControlInputs] = field(default_factory=list)

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        self.seen.append(inputs)
        act = self.script[len(self.seen) - 1]
        if act.kind == "raises":
            raise ZeroDivisionError("float division by zero")
        if act.kind == "returns_none":
            return None  # type: ignore[return-value]
        if act.kind == "string_command":
            return ControlOutput(command=VelocityCommand("fast", 0.0))  # type: ignore[arg-type]
        if act.kind == "string_events":
            return ControlOutput(command=act.wish, state="FOLLOW",
                                 events=("BUMPER",))  # type: ignore[arg-type]
        if act.kind == "state_not_text":
            return ControlOutput(command=act.wish, state=None)  # type: ignore[arg-type]
        if act.kind == "says_halt":
            return ControlOutput(command=act.wish, state="HALT", halt_reason="I feel like stopping")
        return ControlOutput(command=act.wish, state="FOLLOW")


@dataclass(frozen=True)
class Step:
    clock: str  # "ok" (advance_s later), "nan", "backwards" (0.5 s before the last good time)
    advance_s: float
    feedback: str
    loop_events: frozenset[Event]
    start: bool
    resume: bool
    act: Act


acts = st.builds(Act, st.sampled_from(["drive"] * 30 + ["says_halt"] * 3 + list(FAILURES)),
                st.sampled_from(WISHES))
steps = st.builds(
    Step,
    clock=st.sampled_from(["ok"] * 18 + ["nan", "backwards"]),
    advance_s=st.sampled_from([DT, DT, DT, 0.01, 0.15, 0.3]),
    feedback=st.sampled_from(["ok"] * 30 + ["bumper", "cliff", "wheel_drop", "battery_critical",
                                            "battery_low", "late", "old", "missing"]),
    loop_events=st.one_of(
        *[st.just(frozenset())] * 6,
        st.frozensets(st.sampled_from([Event.OPERATOR_STOP, Event.BASE_LINK_LOST,
                                       Event.CAMERA_ERROR, Event.LANE_LOST,
                                       Event.LOOP_OVERRUN]), max_size=2),
    ),
    start=st.sampled_from([False] * 4 + [True]),
    resume=st.sampled_from([False] * 4 + [True]),
    act=acts,
)
#: Runs of repeated steps, so that long stretches of driving (or of one fault) are common.
runs = st.lists(st.tuples(steps, st.integers(1, 12)), min_size=1, max_size=10)


def _feedback(kind: str, now: float) -> BaseFeedback | None:
    return {
        "ok": BaseFeedback(received_at_s=now, battery_v=16.0),
        "bumper": BaseFeedback(received_at_s=now, bumper=4),
        "cliff": BaseFeedback(received_at_s=now, cliff=3),
        "wheel_drop": BaseFeedback(received_at_s=now, wheel_drop=2),
        "battery_critical": BaseFeedback(received_at_s=now, battery_v=13.0),
        "battery_low": BaseFeedback(received_at_s=now, battery_v=13.9),
        "late": BaseFeedback(received_at_s=now - 0.15),  # late, not lost
        "old": BaseFeedback(received_at_s=now - 0.5),
        "missing": None,
    }[kind]


@dataclass
class Model:
    """The gate's rules, restated: latch, first start, requests, and when a step must be zero."""

    latched: bool = True  # not started yet
    started: bool = False
    first_s: float | None = None
    last_s: float | None = None

    def hazards(self, step: Step, feedback: BaseFeedback | None, at: float) -> list[str]:
        if self.first_s is None:
            self.first_s = at
        found = {e.value for e in step.loop_events} & set(HAZARD_PRIORITY)
        if feedback is not None:
            bits = {"BUMPER": feedback.bumper, "CLIFF": feedback.cliff,
                    "WHEEL_DROP": feedback.wheel_drop}
            found |= {name for name, value in bits.items() if value}
            if feedback.battery_v is not None and feedback.battery_v < BATTERY_CRITICAL_V:
                found.add("BATTERY_CRITICAL")
        received = self.first_s if feedback is None or feedback.received_at_s is None \
            else feedback.received_at_s
        if at - received > LINK_TIMEOUT_S:
            found.add("BASE_LINK_LOST")
        return [name for name in HAZARD_PRIORITY if name in found]


def _limit_bound(previous: float, wanted: float, cap: float, accel: float, dt: float) -> float:
    """The largest magnitude the limiter may send on one axis (towards `wanted`)."""
    kept = abs(previous) if previous * wanted > 0.0 else 0.0
    return min(cap, abs(wanted), kept + accel * min(dt, MAX_CREDITED_STEP_S))


@settings(derandomize=True, max_examples=300, deadline=None)
@given(runs)
def test_a_hostile_controller_gets_only_what_the_gate_allows(
    plan: list[tuple[Step, int]],
) -> None:
    script = [s for s, repeat in plan for _ in range(repeat)]
    controller = Hostile([s.act for s in script])
    gate = SafetyGate(controller, SupervisorConfig())
    model = Model()
    t = 0.0
    sent = STOP
    for i, step in enumerate(script):
        if i > 0 and step.clock == "ok":
            t += step.advance_s
        now = {"ok": t, "nan": math.nan, "backwards": t - 0.5}[step.clock]
        feedback = _feedback(step.feedback, t)
        out = gate.step(ControlInputs(feedback=feedback, events=step.loop_events,
                                      start_requested=step.start, resume_requested=step.resume),
                        now)
        told = controller.seen[-1]

        clock_ok = math.isfinite(now) and (model.last_s is None or now >= model.last_s)
        at = now if clock_ok else model.last_s
        hazards = [] if at is None else model.hazards(step, feedback, at)
        granted = False
        if hazards:
            model.latched = True
        elif clock_ok and (step.start or (step.resume and model.started)):
            model.latched, model.started, granted = False, True, True
        failed = step.act.kind in FAILURES
        if failed:
            model.latched = True
        dt = 0.0 if not clock_ok or model.last_s is None else now - model.last_s
        if clock_ok:
            model.last_s = now

        # What the controller was told: the gate's findings, what was really sent, and only the
        # requests the gate granted.
        assert {e.value for e in told.events} >= set(hazards), (i, told.events)
        assert told.previous_command == sent, i
        assert (told.start_requested, told.resume_requested) == (
            granted and step.start, granted and step.resume), (i, step, model)
        names = [e.value for e in out.events]
        assert ("CONTROLLER_ERROR" in names) == failed, (i, names)
        assert ("CLOCK_INVALID" in names) == (not clock_ok), (i, names)

        if model.latched or step.act.kind == "says_halt" or not clock_ok:
            event("halted")
            assert (out.state, out.command) == ("HALT", STOP), (i, step, out)
            assert out.halt_reason, (i, out)
            first = [*hazards, "CONTROLLER_ERROR"][0] if failed else (hazards or [None])[0]
            if first is not None:
                assert out.halt_reason.startswith(f"{first}: "), (i, first, out.halt_reason)
        else:
            event("driving")
            wish = step.act.wish
            assert out.state == "FOLLOW", (i, out)
            if not (math.isfinite(wish.linear_m_s) and math.isfinite(wish.angular_rad_s)):
                assert out.command == STOP, (i, wish, out.command)  # malformed -> stop
            else:
                for got, was, want, cap, accel in (
                    (out.command.linear_m_s, sent.linear_m_s, wish.linear_m_s, MAX_LINEAR,
                     LINEAR_ACCEL),
                    (out.command.angular_rad_s, sent.angular_rad_s, wish.angular_rad_s,
                     MAX_ANGULAR, ANGULAR_ACCEL),
                ):
                    assert got * want >= 0.0, (i, got, want)  # never the other way
                    bound = _limit_bound(was, want, cap, accel, dt)
                    assert abs(got) <= bound + EPS, (i, got, bound, was, want, dt)
                    if abs(want) <= abs(was) and was * want > 0.0 and abs(want) <= cap:
                        assert got == want, (i, got, want)  # slowing down: at once
                    if want != 0.0 and dt > 0.0:
                        assert got != 0.0, (i, got, want, dt)  # it does drive when allowed
        sent = out.command
