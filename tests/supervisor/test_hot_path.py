"""The supervisor's per-step hot path, where it does directly what general tools did before.

The gate builds the controller's inputs and its own output field by field (not with
dataclasses.replace): every field it does not decide must arrive unchanged, including any field
added to ControlInputs or ControlOutput later. The state machine fires `tick` only when a row of
the current state can match: which conditions those are, per state, written out. And the slope
filter's innovation gate, which reads H x and H P H' off the filter's state directly."""

from __future__ import annotations

import dataclasses
from types import MappingProxyType

import pytest

from lanewarden.actuation.base import BaseFeedback, VelocityCommand
from lanewarden.perception.observation import LaneObservation
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, ControlOutput, FrameInfo
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.gate import SafetyGate
from lanewarden.supervisor.slope_filter import SlopeSumFilter
from lanewarden.supervisor.state_machine import CONDITIONS_BY_SOURCE, SupervisorState

CONFIG = SupervisorConfig()
#: What the gate decides itself (the rest of the controller's output passes through).
GATE_DECIDES = {"command", "state", "events", "halt_reason"}
#: What the gate adds to the loop's inputs (the rest reaches the controller unchanged).
GATE_ADDS = {"events", "event_details", "previous_command"}


class Echo:
    """Keeps what it was told; answers with a FOLLOW output whose every field is set."""

    def __init__(self) -> None:
        self.seen: list[ControlInputs] = []

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        self.seen.append(inputs)
        return ControlOutput(command=VelocityCommand(0.0, 0.0), state="FOLLOW", events=(),
                             halt_reason=None, filtered_slope_sum=1.25, slope_sum_variance=0.5,
                             innovation=-0.75, filtered_center_offset=0.0625, lane_trusted=True)


def _inputs() -> ControlInputs:
    observation = LaneObservation(frame_index=7, time_s=0.2, left=None, right=None,
                                  slope_sum=None, confidence=0.0)
    return ControlInputs(
        frame=FrameInfo(7, 0.2, b"print", True),
        observation=observation,
        feedback=BaseFeedback(received_at_s=0.2),
        events=frozenset({Event.LOOP_OVERRUN}),
        event_details=MappingProxyType({Event.LOOP_OVERRUN: "late"}),
        start_requested=True,
        resume_requested=True,
    )


def test_the_controller_is_told_every_input_field_the_gate_does_not_add() -> None:
    echo = Echo()
    sent = _inputs()
    SafetyGate(echo, CONFIG).step(sent, 0.2)
    told = echo.seen[0]
    for f in dataclasses.fields(ControlInputs):
        if f.name not in GATE_ADDS:
            assert getattr(told, f.name) is getattr(sent, f.name), f.name
    assert told.events == frozenset({Event.LOOP_OVERRUN})
    assert dict(told.event_details) == {Event.LOOP_OVERRUN: "late"}


def test_the_output_keeps_every_field_the_gate_does_not_decide() -> None:
    gate = SafetyGate(Echo(), CONFIG)
    for out in (gate.step(_inputs(), 0.2),  # driving: the limiter's command
                gate.step(ControlInputs(feedback=BaseFeedback(bumper=1, received_at_s=0.3)),
                          0.3)):  # a bumper: HALT
        assert (out.filtered_slope_sum, out.slope_sum_variance, out.innovation,
                out.filtered_center_offset, out.lane_trusted) == (1.25, 0.5, -0.75, 0.0625, True)
        kept = {f.name for f in dataclasses.fields(ControlOutput)} - GATE_DECIDES
        assert kept == {"filtered_slope_sum", "slope_sum_variance", "innovation",
                        "filtered_center_offset", "lane_trusted"}
    assert out.state == "HALT" and out.events == (Event.BUMPER,)


def test_which_conditions_can_move_the_machine_from_each_state() -> None:
    S = SupervisorState
    assert dict(CONDITIONS_BY_SOURCE) == {
        S.FOLLOW: ("must_halt", "must_degrade", "bend_left_entered", "bend_right_entered"),
        S.TURN_LEFT: ("must_halt", "must_degrade", "bend_right_entered", "bend_left_ended"),
        S.TURN_RIGHT: ("must_halt", "must_degrade", "bend_left_entered", "bend_right_ended"),
        S.DEGRADED: ("must_halt", "may_recover"),
        S.HALT: ("must_halt", "may_engage"),
    }


def test_the_innovation_gate_weighs_the_prediction_variance_with_the_measurement_noise() -> None:
    """Restarted at 0.0 with confidence 1: P = R = 0.3^2. A second measurement at the same time
    (no predict): S = P + R = 0.18, so 1.5 is 1.5 / sqrt(0.18) = 3.5355 sigma (inside the 4-sigma
    gate; against R alone it would be 5 sigma and rejected)."""
    f = SlopeSumFilter(CONFIG)
    f.step(0.0, 0.0, 1.0)
    estimate = f.step(0.0, 1.5, 1.0)
    assert estimate.innovation == 1.5
    assert estimate.mahalanobis == pytest.approx(3.5355339, abs=1e-6)
    assert estimate.accepted and not estimate.outlier
