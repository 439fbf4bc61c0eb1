"""Property: over random sequences of observations, feedback, faults, timing and operator requests,
no non-zero command ever leaves the supervised stack while HALT is latched, and HALT is left only
after a request made after the last fault plus N confident frames.

This is the supervised controller behind its gate: the controller zeroes its own command in HALT,
so this test alone would pass with the gate's latch removed. The gate's own rules are checked
with hostile controllers, which halt for nothing, in test_gate_properties.py."""

from __future__ import annotations

from dataclasses import dataclass

from hypothesis import event, given, settings
from hypothesis import strategies as st

from lanewarden.actuation.base import STOP, BaseFeedback
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.events import EVENT_TABLE, Event, Response
from tests.supervisor.rig import DT, Rig, observation

CONFIG = SupervisorConfig()
#: Both edges at high confidence. The filter's gate may only delay engagement, never hasten it, so
#: a wild (but repeated, hence consistent) slope sum counts too.
CONFIDENT_KINDS = {"good", "bend_left", "bend_right", "wild"}


@dataclass(frozen=True)
class StepSpec:
    advance_s: float
    new_frame: bool
    kind: str
    feedback: str
    events: frozenset[Event]
    start: bool
    resume: bool


step_specs = st.builds(
    StepSpec,
    advance_s=st.sampled_from([DT, DT, DT, DT, 2 * DT, 0.12, 0.3]),
    new_frame=st.sampled_from([True, True, True, True, False]),
    kind=st.sampled_from(
        ["good"] * 6
        + ["bend_left", "bend_right", "one_edge", "none", "low", "untrusted", "wild", "malformed"]
    ),
    feedback=st.sampled_from(["ok"] * 8 + ["bumper", "old", "missing"]),
    events=st.one_of(
        st.just(frozenset()),
        st.just(frozenset()),
        st.just(frozenset()),
        st.frozensets(st.sampled_from(list(Event)), max_size=2),
    ),
    start=st.sampled_from([False] * 5 + [True]),
    resume=st.sampled_from([False] * 5 + [True]),
)


def _observation_kwargs(kind: str) -> dict[str, object]:
    return {
        "good": {},
        "bend_left": {"slope_sum": 7.5},
        "bend_right": {"slope_sum": -7.5},
        "one_edge": {"right": False, "confidence": 0.5},
        "none": {"left": False, "right": False, "confidence": 0.0},
        "low": {"confidence": 0.3},
        "untrusted": {"confidence": 0.1},
        "wild": {"slope_sum": 40.0, "confidence": 0.9},
    }.get(kind, {})


def _run(rig: Rig, spec: StepSpec):  # type: ignore[no-untyped-def]
    now = rig.clock.now() + (0.0 if rig.first else spec.advance_s)
    feedback = {
        "ok": BaseFeedback(received_at_s=now),
        "bumper": BaseFeedback(received_at_s=now, bumper=1),
        "old": BaseFeedback(received_at_s=now - 0.5),
        "missing": None,
    }[spec.feedback]
    common = {
        "advance_s": spec.advance_s,
        "new_frame": spec.new_frame,
        "feedback": feedback,
        "events": spec.events,
        "start": spec.start,
        "resume": spec.resume,
    }
    if spec.kind == "malformed" and spec.new_frame:
        bad = observation(rig.index + 1, now, confidence=1.7)
        return rig.step(obs=bad, **common)  # type: ignore[arg-type]
    return rig.step(**_observation_kwargs(spec.kind), **common)  # type: ignore[arg-type]


#: Runs of repeated steps, so that long stretches of good (or bad) frames are common.
step_runs = st.lists(st.tuples(step_specs, st.integers(1, 15)), min_size=1, max_size=12)


@settings(derandomize=True, max_examples=200, deadline=None)
@given(step_runs)
def test_no_motion_while_halt_is_latched(runs: list[tuple[StepSpec, int]]) -> None:
    specs = [spec for spec, repeat in runs for _ in range(repeat)]
    rig = Rig(CONFIG)
    last_halt_event = -1  # index of the latest step whose events latch HALT (initial: before 0)
    last_request = None
    confident_run = 0  # new frames in a row of a confident kind
    previous_state = "HALT"
    for i, spec in enumerate(specs):
        out = _run(rig, spec)
        if spec.new_frame:
            confident_run = confident_run + 1 if spec.kind in CONFIDENT_KINDS else 0
        if spec.start or spec.resume:
            last_request = i
        if any(EVENT_TABLE[e].response is Response.HALT for e in out.events):
            last_halt_event = i

        if out.state == "HALT":
            assert out.command == STOP, (i, out)
        if previous_state == "HALT" and out.state != "HALT":  # engaged at step i
            event("engaged")  # hypothesis statistics: the property is not vacuous
            assert last_request is not None and last_request > last_halt_event, (i, out)
            assert confident_run >= CONFIG.engage_confident_frames, (i, confident_run)
            assert all(EVENT_TABLE[e].response is Response.WARN for e in out.events), out
        if out.command != STOP:
            assert out.state != "HALT"
        previous_state = out.state
