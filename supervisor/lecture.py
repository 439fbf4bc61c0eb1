"""The lecture's controller, kept as a baseline to show in numbers what the supervisor fixes.

Raw slope sum, no filter, no confidence: > +threshold turn left, < -threshold turn right, otherwise
straight (the lecture's +-6, `turn_enter_slope_sum`). When it sees no slope sum it keeps its last
decision, so it never halts on lane loss (that is the point of the baseline: it follows tile seams
and wanders off). Lane, camera and timing faults it ignores.

It never halts by itself: like every controller it runs behind the SafetyGate
(supervisor/gate.py), which holds it still until start, halts it (latched until resume) on an
operator stop and on the physical hazards the lecture never had to think about (bumper, cliff,
wheel drop, a lost base link), and ramps its commands with the same limiter as the supervised
controller's, so both drive the same robot. Its decisions are named FOLLOW (straight), TURN_LEFT
and TURN_RIGHT in the records.
"""

from __future__ import annotations

import math

from lanewarden.actuation.base import VelocityCommand
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, ControlOutput
from lanewarden.supervisor.events import ordered
from lanewarden.supervisor.state_machine import SupervisorState


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


class LectureController:
    def __init__(self, config: SupervisorConfig) -> None:
        self.config = config
        self._decision = SupervisorState.FOLLOW

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        obs = inputs.observation
        raw = None if obs is None else obs.slope_sum
        self._decision = lecture_decision(raw, self._decision, self.config.turn_enter_slope_sum)
        return ControlOutput(
            command=self._thrust(self._decision),
            state=self._decision.value,
            events=ordered(inputs.events),
            filtered_slope_sum=raw,
        )

    def _thrust(self, decision: SupervisorState) -> VelocityCommand:
        cfg = self.config
        if decision is SupervisorState.TURN_LEFT:
            return VelocityCommand(cfg.turn_speed_m_s, cfg.lecture_turn_angular_rad_s)
        if decision is SupervisorState.TURN_RIGHT:
            return VelocityCommand(cfg.turn_speed_m_s, -cfg.lecture_turn_angular_rad_s)
        return VelocityCommand(cfg.follow_speed_m_s, 0.0)
