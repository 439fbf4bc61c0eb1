"""The lecture's controller, kept as a baseline to show in numbers what the supervisor fixes.

Raw slope sum, no filter, no confidence: > +threshold turn left, < -threshold turn right, otherwise
straight (the lecture's +-6). When it sees no slope sum it keeps its last decision, so it never
halts on lane loss (that is the point of the baseline: it follows tile seams and wanders off). It
does obey the operator: nothing moves before start, and an operator stop halts it until resume.
Because it may drive a real robot (`lanewarden run --controller lecture`), it also halts, latched
until resume, on the physical hazards the lecture never had to think about: bumper, cliff, wheel
drop and a lost base link (`PHYSICAL_HAZARDS`). Lane, camera and timing faults it ignores.
Commands go through the same limiter as the supervised controller so both drive the same robot.
Its decisions are named FOLLOW (straight), TURN_LEFT and TURN_RIGHT in the records.
"""

from __future__ import annotations

import math

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, ControlOutput
from lanewarden.supervisor.events import EVENT_TABLE, Event, ordered
from lanewarden.supervisor.hazards import base_hazard_events
from lanewarden.supervisor.limiter import CommandLimiter
from lanewarden.supervisor.state_machine import NOT_STARTED_REASON, SupervisorState


def lecture_decision(
    slope_sum: float | None, previous: SupervisorState, threshold: float
) -> SupervisorState:
    """The lecture's rule; no slope sum keeps the previous decision."""
    if slope_sum is None or not math.isfinite(slope_sum):
        return previous
    if slope_sum > threshold:
        return SupervisorState.TURN_LEFT
    if slope_sum < -threshold:
        return SupervisorState.TURN_RIGHT
    return SupervisorState.FOLLOW


#: Faults that halt even the lecture's baseline, in priority order.
PHYSICAL_HAZARDS: tuple[Event, ...] = (
    Event.OPERATOR_STOP,
    Event.BUMPER,
    Event.CLIFF,
    Event.WHEEL_DROP,
    Event.BASE_LINK_LOST,
)


class LectureController:
    def __init__(self, config: SupervisorConfig) -> None:
        self.config = config
        self._limiter = CommandLimiter(config)
        self._decision = SupervisorState.FOLLOW
        self._halt_reason: str | None = NOT_STARTED_REASON
        self._last_now: float | None = None

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        cfg = self.config
        dt = 0.0 if self._last_now is None else max(0.0, now - self._last_now)
        self._last_now = now
        events = frozenset(inputs.events) | base_hazard_events(inputs.feedback)
        hazard = next((e for e in PHYSICAL_HAZARDS if e in events), None)
        if hazard is not None:
            self._halt_reason = f"{hazard.value}: {EVENT_TABLE[hazard].reason}"
        elif inputs.start_requested or inputs.resume_requested:
            self._halt_reason = None
        obs = inputs.observation
        self._decision = lecture_decision(
            None if obs is None else obs.slope_sum, self._decision, cfg.lecture_slope_sum_threshold
        )
        if self._halt_reason is not None:
            self._limiter.stop()
            state, command = SupervisorState.HALT, STOP
        else:
            state = self._decision
            command = self._limiter.limit(self._thrust(state), min(dt, cfg.loop_overrun_s))
        return ControlOutput(
            command=command,
            state=state.value,
            events=ordered(events),
            halt_reason=self._halt_reason,
            filtered_slope_sum=None if obs is None else obs.slope_sum,
        )

    def _thrust(self, decision: SupervisorState) -> VelocityCommand:
        cfg = self.config
        if decision is SupervisorState.TURN_LEFT:
            return VelocityCommand(cfg.turn_speed_m_s, cfg.lecture_turn_angular_rad_s)
        if decision is SupervisorState.TURN_RIGHT:
            return VelocityCommand(cfg.turn_speed_m_s, -cfg.lecture_turn_angular_rad_s)
        return VelocityCommand(cfg.follow_speed_m_s, 0.0)
