"""The supervised controller: filter, watchdog, state machine and commands, step by step.

`SupervisedController.step(inputs, now)` is the pure core the SafetyGate calls once per camera
tick: (its own state, inputs, now) -> (wanted command, state, events). It gathers the step's events
(the loop's and the gate's, which include the physical hazards; the watchdog's; the lane evidence;
the filter's gate), runs the state machine and asks the state for its command. HALT asks for an
exact zero in the same step. Limiting, and enforcing the hazards whatever this controller says,
is the gate's job (supervisor/gate.py).

About frames that are not new: a frame source returns its newest frame until the next one is
captured. A step without a new frame has no new measurement, so the filter and the lane evidence do
not move; the state's command is recomputed from the latest estimate, which by construction is at
most `frame_late_s` old (older: FRAME_LATE -> DEGRADED; older than `frame_stale_s`: FRAME_STALE ->
HALT and zero). No input ever leads to replaying a previous command.

Never reads a clock, a camera or a port.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lanewarden.perception.observation import LaneObservation
from lanewarden.supervisor.center_offset import CenterOffsetFilter, lane_steers
from lanewarden.supervisor.commands import command_for
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, ControlOutput, FrameInfo
from lanewarden.supervisor.events import Event, ordered
from lanewarden.supervisor.lane_evidence import LaneEvidence, observation_problem
from lanewarden.supervisor.slope_filter import (
    SlopeEstimate,
    SlopeSumFilter,
    slope_sum_chord_variance,
)
from lanewarden.supervisor.state_machine import StepFacts, SupervisorState, SupervisorStateMachine
from lanewarden.supervisor.watchdog import Watchdog


@dataclass(frozen=True)
class FrameVerdict:
    """What the supervisor made of this step's new frame (all None: no new frame judged).
    `trusted`: a usable lane; `confident`: counts towards engage/recover (None for a malformed
    observation); `innovation`: the filter's, for the record."""

    trusted: bool | None = None
    confident: bool | None = None
    innovation: float | None = None


NO_FRAME_JUDGED = FrameVerdict()


class SupervisedController:
    """The product's controller. One instance per run (it keeps the run's history)."""

    def __init__(self, config: SupervisorConfig) -> None:
        self.config = config
        self._watchdog = Watchdog(config)
        self._slope = SlopeSumFilter(config)
        self._center = CenterOffsetFilter(config)
        self._lane = LaneEvidence(config)
        self._machine = SupervisorStateMachine(config)
        self._last_now: float | None = None
        self._lane_seen_at_s: float | None = None
        self._estimate = SlopeEstimate(None, None, None)

    @property
    def state(self) -> SupervisorState:
        return self._machine.state

    @property
    def halt_reason(self) -> str | None:
        return self._machine.halt_reason

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        cfg = self.config
        events: set[Event] = set(inputs.events)
        details = dict(inputs.event_details)

        dt = 0.0
        if not math.isfinite(now) or (self._last_now is not None and now < self._last_now):
            events.add(Event.CLOCK_INVALID)
            details.setdefault(Event.CLOCK_INVALID, f"now={now!r}, previous={self._last_now!r}")
            now = self._last_now if self._last_now is not None else 0.0
        elif self._last_now is not None:
            dt = now - self._last_now
        self._last_now = now

        previous = inputs.previous_command
        events |= self._watchdog.check(now, inputs.frame, inputs.feedback, not previous.is_stop)
        if Event.FRAME_STALE in events:
            details.setdefault(Event.FRAME_STALE, self._watchdog.stale_detail(now, inputs.frame))
        frame = NO_FRAME_JUDGED
        if inputs.observation is not None and Event.FRAME_INVALID not in events:
            frame = self._judge(inputs.observation, inputs.frame, events, details)

        tick = self._machine.step(
            StepFacts(
                now=now,
                events=frozenset(events),
                event_details=details,
                frame_confident=frame.confident,
                lane_seen_at_s=self._lane_seen_at_s,
                slope_sum=self._estimate.slope_sum,
                travelled_m=abs(previous.linear_m_s) * dt,
                engage_requested=inputs.start_requested or inputs.resume_requested,
            )
        )
        state = self._machine.state
        return ControlOutput(
            command=command_for(state, self._estimate.slope_sum, self._center.value, cfg),
            state=state.value,
            events=ordered(tick.events),
            halt_reason=self._machine.halt_reason,
            filtered_slope_sum=self._estimate.slope_sum,
            slope_sum_variance=self._estimate.variance,
            innovation=frame.innovation,
            filtered_center_offset=self._center.value,
            lane_trusted=frame.trusted,
        )

    def _judge(self, obs: LaneObservation, frame: FrameInfo | None, events: set[Event],
               details: dict[Event, str]) -> FrameVerdict:
        """Assess a new frame's observation, feed the filters; adds its events to `events`."""
        problem = observation_problem(obs, frame)
        if problem is not None:
            events.add(Event.MALFORMED_OBSERVATION)
            details.setdefault(Event.MALFORMED_OBSERVATION, problem)
            return FrameVerdict(trusted=False, confident=None)
        lane = self._lane.assess(obs)
        events |= lane.events
        if Event.LANE_DEPARTURE in lane.events and lane.departure:
            details.setdefault(Event.LANE_DEPARTURE, lane.departure)
        self._estimate = self._slope.step(obs.time_s, lane.slope_sum, obs.confidence,
                                          slope_sum_chord_variance(obs, self.config))
        events |= self._estimate.events
        if lane.slope_sum is not None:
            if lane_steers(obs, self.config.center_max_edge_angle_deg):
                self._center.step(obs.time_s, obs.lane_offset_m, obs.lane_heading_rad)
            else:
                self._center.relax(obs.time_s)
        if lane.usable:
            self._lane_seen_at_s = obs.time_s
        return FrameVerdict(
            trusted=lane.usable,
            # an image identical to the previous one is no new evidence (a frozen camera): it
            # never counts towards engaging or recovering, however confident its lane
            confident=(lane.confident and self._estimate.accepted
                       and not self._watchdog.image_repeated),
            innovation=self._estimate.innovation,
        )
