"""The SafetyGate: the one place between every controller and the base.

Every command that reaches a base leaves through `SafetyGate.step`. A controller (the supervised
one, the lecture's baseline, `base drive`'s fixed command) only says what it would like to send;
the gate decides what is sent, by the same rules for all of them:

- Physical hazards latch HALT: operator stop, bumper, cliff, wheel drop, the base's own
  safety latch (the Kobuki's dead-man stopped it: DEADMAN_LATCHED), a critically low battery
  (below `battery_critical_v`; below `battery_low_v` only a BATTERY_LOW warning) and a
  lost base link (raised by the loop when the base fails, or base feedback older than
  `base_link_timeout_s`).
  The latch holds, hazard gone or not, until a start or resume request in a later step without
  a hazard. Nothing moves before the first start either.
- HALT is an exact zero: while the gate is latched, whenever the controller itself says HALT, and
  for a step whose time is not finite or goes backwards (CLOCK_INVALID), the command is STOP in
  the same step, and the ramp starts again from zero.
- Otherwise the controller's command goes through the limiter (supervisor/limiter.py): speeds
  capped, increases ramped, decreases (a stop included) passed at once, non-finite -> stop.

The controller is told what the gate found (the hazard events join the step's events, and
`previous_command` is what the gate sent last), so a supervised state machine records the same
facts and halt reasons; but the gate never relies on the controller acting on them.

Pure: time is the `now` passed in; nothing here reads a clock, a camera or a port.
"""

from __future__ import annotations

import math
from types import MappingProxyType

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, Controller, ControlOutput
from lanewarden.supervisor.events import Event, halt_reason, ordered
from lanewarden.supervisor.hazards import base_hazard_events, battery_events, feedback_age_s
from lanewarden.supervisor.limiter import CommandLimiter, CommandLimits
from lanewarden.supervisor.state_machine import NOT_STARTED_REASON

#: The hazards that latch HALT at the gate, whatever the controller (priority order of `Event`).
PHYSICAL_HAZARDS: frozenset[Event] = frozenset({
    Event.OPERATOR_STOP, Event.DEADMAN_LATCHED, Event.BUMPER, Event.CLIFF, Event.WHEEL_DROP,
    Event.BASE_LINK_LOST, Event.BATTERY_CRITICAL,
})  # fmt: skip

#: The state name of a halted step, in outputs and records.
HALT = "HALT"
CONTROLLER_HALT_REASON = "the controller asked for HALT"


class SafetyGate:
    """Wraps one controller for one run. `step` has the controller's signature, so the control
    loop drives the gate exactly as it would a controller, and sends only what it returns."""

    def __init__(
        self,
        controller: Controller,
        config: SupervisorConfig,
        limits: CommandLimits | None = None,
    ) -> None:
        self.controller = controller
        self._link_timeout_s = config.base_link_timeout_s
        self._battery_v = (config.battery_low_v, config.battery_critical_v)
        self._limiter = CommandLimiter(limits or CommandLimits.for_driving(config))
        self._latched: str | None = NOT_STARTED_REASON
        self._first_now: float | None = None
        self._last_now: float | None = None

    @property
    def latched_reason(self) -> str | None:
        """Why the gate holds HALT (None: it lets the controller drive, within the limits)."""
        return self._latched

    @property
    def last_command(self) -> VelocityCommand:
        """The command the gate let out last."""
        return self._limiter.last

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        clock_ok = math.isfinite(now) and (self._last_now is None or now >= self._last_now)
        at = now if clock_ok else self._last_now
        found = {} if at is None else self._hazards(inputs, at)
        details = {**inputs.event_details, **found}
        hazards = {e: d for e, d in found.items() if e in PHYSICAL_HAZARDS}  # the rest: warnings
        if hazards:
            self._latched = halt_reason(hazards, details)
        elif inputs.start_requested or inputs.resume_requested:
            self._latched = None
        wanted = self.controller.step(_told(inputs, found, details, self._limiter.last), now)
        events = {*wanted.events, *found}
        dt = 0.0
        if not clock_ok:
            events.add(Event.CLOCK_INVALID)
        elif self._last_now is not None:
            dt = now - self._last_now
        if clock_ok:
            self._last_now = now
        halt = self._latched is not None or wanted.state == HALT or not clock_ok
        if halt:
            self._limiter.stop()
            reason = wanted.halt_reason if wanted.state == HALT else None
            return _sent(wanted, STOP, HALT, ordered(events),
                         reason or self._latched or halt_reason(events) or CONTROLLER_HALT_REASON)
        return _sent(wanted, self._limiter.limit(wanted.command, dt), wanted.state,
                     ordered(events), wanted.halt_reason)

    def _hazards(self, inputs: ControlInputs, now: float) -> dict[Event, str]:
        """This step's physical hazards and the base's warnings (BATTERY_LOW), each with its
        detail ('' for none). `now` is valid."""
        if self._first_now is None:
            self._first_now = now
        found = {e: inputs.event_details.get(e, "") for e in inputs.events if e in PHYSICAL_HAZARDS}
        found.update(base_hazard_events(inputs.feedback))
        found.update(battery_events(inputs.feedback, *self._battery_v))
        age = feedback_age_s(inputs.feedback, self._first_now, now)
        if not math.isfinite(age) or age > self._link_timeout_s:
            found.setdefault(Event.BASE_LINK_LOST, "")
        return found


# The two helpers below copy every field by name (cheaper than dataclasses.replace, which the gate
# would call twice a step): a field added to ControlInputs or ControlOutput must be added here.


def _told(inputs: ControlInputs, found: dict[Event, str], details: dict[Event, str],
          previous_command: VelocityCommand) -> ControlInputs:
    """`inputs` as the controller sees them: plus the gate's findings and its last command."""
    return ControlInputs(
        frame=inputs.frame,
        observation=inputs.observation,
        feedback=inputs.feedback,
        events=inputs.events | found.keys(),
        event_details=MappingProxyType(details),
        start_requested=inputs.start_requested,
        resume_requested=inputs.resume_requested,
        previous_command=previous_command,
    )


def _sent(wanted: ControlOutput, command: VelocityCommand, state: str,
          events: tuple[Event, ...], reason: str | None) -> ControlOutput:
    """The controller's output with what the gate decides: command, state, events, halt reason."""
    return ControlOutput(
        command=command,
        state=state,
        events=events,
        halt_reason=reason,
        filtered_slope_sum=wanted.filtered_slope_sum,
        slope_sum_variance=wanted.slope_sum_variance,
        innovation=wanted.innovation,
        filtered_center_offset=wanted.filtered_center_offset,
        lane_trusted=wanted.lane_trusted,
    )
