"""The SafetyGate: the one place between every controller and the base.

Every command that reaches a base leaves through `SafetyGate.step`. A controller (the supervised
one, the lecture's baseline, `base drive`'s fixed command) only says what it would like to send;
the gate decides what is sent, by the same rules for all of them:

- Physical hazards latch HALT: operator stop, bumper, cliff, wheel drop, the base's own
  safety latch (the Kobuki's dead-man stopped it: DEADMAN_LATCHED), a critically low battery
  (below `battery_critical_v`; below `battery_low_v` only a BATTERY_LOW warning) and a
  lost base link (raised by the loop when the base fails, or base feedback older than
  `base_link_timeout_s`). The gate finds them itself (`PHYSICAL_HAZARDS`) and latches them
  whatever the controller does and whatever the event table says: the table is checked against
  the gate at import (`check_event_table`), never trusted to agree.
  The latch holds, hazard gone or not, until a start or resume request in a later step without
  a hazard and with a valid step time. Nothing moves before the first start, and only a start
  ends that first latch (a resume before any start is refused). The controller is told only the
  requests the gate granted.
- A controller that raises, or returns something that is not a well-formed `ControlOutput`, is
  CONTROLLER_ERROR: HALT in the same step, latched like a hazard, the exception named in one
  line in the reason; never a traceback through the loop.
- HALT is an exact zero: while the gate is latched, whenever the controller itself says HALT, and
  for a step whose time is not finite or goes backwards (CLOCK_INVALID), the command is STOP in
  the same step, and the ramp starts again from zero.
- Otherwise the controller's command goes through the limiter (supervisor/limiter.py): speeds
  capped, increases ramped, decreases (a stop included) passed at once, non-finite -> stop.

The controller is told what the gate found (the hazard events join the step's events, and
`previous_command` is what the gate sent last), so a supervised state machine records the same
facts and halt reasons; but the gate never relies on the controller acting on them.

Pure: time is the `now` passed in; nothing here reads a clock, a camera or a port. Must never
let an exception from a controller out, and never decide a halt from `EVENT_TABLE`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from numbers import Real
from types import MappingProxyType

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, Controller, ControlOutput
from lanewarden.supervisor.errors import SupervisorError, exception_line
from lanewarden.supervisor.events import (
    EVENT_TABLE,
    Event,
    EventRule,
    Response,
    event_reason,
    halt_reason,
    ordered,
)
from lanewarden.supervisor.hazards import (
    base_hazard_events,
    battery_events,
    feedback_age_s,
    stale_feedback_detail,
)
from lanewarden.supervisor.limiter import CommandLimiter, CommandLimits
from lanewarden.supervisor.state_machine import NOT_STARTED_REASON

#: The hazards that latch HALT at the gate, whatever the controller (priority order of `Event`).
PHYSICAL_HAZARDS: frozenset[Event] = frozenset({
    Event.OPERATOR_STOP, Event.DEADMAN_LATCHED, Event.BUMPER, Event.CLIFF, Event.WHEEL_DROP,
    Event.BASE_LINK_LOST, Event.BATTERY_CRITICAL,
})  # fmt: skip
#: Every event the gate halts on by itself: the physical hazards, a step time it cannot use and
#: a controller that fails. `EVENT_TABLE` must say HALT for each (checked at import).
GATE_HALT_EVENTS: frozenset[Event] = PHYSICAL_HAZARDS | {Event.CLOCK_INVALID,
                                                         Event.CONTROLLER_ERROR}

#: The state name of a halted step, in outputs and records.
HALT = "HALT"
CONTROLLER_HALT_REASON = "the controller asked for HALT"
#: What a controller that failed is taken to have said (nothing but a stop).
_FAILED = ControlOutput()


def check_event_table(table: Mapping[Event, EventRule]) -> None:
    """SupervisorError (one line) unless `table` gives HALT to every event the gate halts on: the
    state machine and the records read the table, the gate does not, and they must agree."""
    wrong = [e.value for e in Event if e in GATE_HALT_EVENTS
             and (e not in table or table[e].response is not Response.HALT)]
    if wrong:
        raise SupervisorError(
            "supervisor/events.py: EVENT_TABLE must give HALT to every event the SafetyGate "
            f"halts on; it does not for {', '.join(wrong)}"
        )


check_event_table(EVENT_TABLE)


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
        #: How long a lane the supervisor trusted stays the one perception's `consistency` is
        #: measured against (`ControlLoop`): the supervisor halts LANE_LOST after this long
        #: without a usable lane, so past it there is no trusted lane left to agree with.
        self.lane_memory_s = config.lane_lost_halt_s
        self._link_timeout_s = config.base_link_timeout_s
        self._battery_v = (config.battery_low_v, config.battery_critical_v)
        self._limiter = CommandLimiter(limits or CommandLimits.for_driving(config))
        self._latched: str | None = NOT_STARTED_REASON
        self._started = False
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
        hazards = [e for e in ordered(found) if e in PHYSICAL_HAZARDS] if found else []
        latched_now: str | None = None
        granted = False
        if hazards:
            self._latched = latched_now = event_reason(hazards[0], details)
        elif clock_ok and (inputs.start_requested or (inputs.resume_requested and self._started)):
            self._latched = None
            self._started = granted = True
        told = _told(inputs, found, details, self._limiter.last, granted)
        try:
            wanted = self.controller.step(told, now)
            problem = _malformed(wanted)
        except Exception as exc:  # a controller's bug halts the robot; it never crashes the loop
            problem = f"raised {exception_line(exc)}"
        failure = None if problem is None else f"{type(self.controller).__name__} {problem}"
        events = {*told.events}
        if failure is not None:
            wanted = _FAILED
            events.add(Event.CONTROLLER_ERROR)
            details = {**details, Event.CONTROLLER_ERROR: failure}  # the controller keeps its own
            self._latched = latched_now = event_reason(
                ordered([*hazards, Event.CONTROLLER_ERROR])[0], details)
        else:
            events.update(wanted.events)
        dt = 0.0
        if not clock_ok:
            events.add(Event.CLOCK_INVALID)
        elif self._last_now is not None:
            dt = now - self._last_now
        if clock_ok:
            self._last_now = now
        if self._latched is not None or wanted.state == HALT or not clock_ok:
            self._limiter.stop()
            said = wanted.halt_reason if wanted.state == HALT else None
            return _sent(wanted, STOP, HALT, ordered(events),
                         latched_now or said or self._latched or halt_reason(events)
                         or CONTROLLER_HALT_REASON)
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
            found.setdefault(Event.BASE_LINK_LOST,
                             stale_feedback_detail(inputs.feedback, age, self._link_timeout_s))
        return found


def _malformed(output: object) -> str | None:
    """What is wrong with a controller's output (None: a well-formed ControlOutput). Values out
    of range are the limiter's business; wrong types would crash the gate or the recorder."""
    if not isinstance(output, ControlOutput):
        return f"returned {type(output).__name__}, expected a ControlOutput"
    command = output.command
    if not (isinstance(command, VelocityCommand) and isinstance(command.linear_m_s, Real)
            and isinstance(command.angular_rad_s, Real)):
        return f"returned the command {_short(command)}, expected a VelocityCommand of numbers"
    if not isinstance(output.state, str):
        return f"returned the state {_short(output.state)}, expected a name"
    if not (isinstance(output.events, tuple) and all(type(e) is Event for e in output.events)):
        return f"returned the events {_short(output.events)}, expected a tuple of Event"
    if output.halt_reason is not None and not isinstance(output.halt_reason, str):
        return f"returned the halt reason {_short(output.halt_reason)}, expected text"
    for name in ("filtered_slope_sum", "slope_sum_variance", "innovation",
                 "filtered_center_offset"):
        value = getattr(output, name)
        if value is not None and not isinstance(value, Real):
            return f"returned {name} {_short(value)}, expected a number"
    if output.lane_trusted not in (None, True, False):
        return f"returned lane_trusted {_short(output.lane_trusted)}, expected true or false"
    return None


def _short(value: object) -> str:
    text = " ".join(repr(value).split())
    return text if len(text) <= 60 else text[:57] + "..."


# The two helpers below copy every field by name (cheaper than dataclasses.replace, which the gate
# would call twice a step): a field added to ControlInputs or ControlOutput must be added here.


def _told(inputs: ControlInputs, found: dict[Event, str], details: dict[Event, str],
          previous_command: VelocityCommand, granted: bool) -> ControlInputs:
    """`inputs` as the controller sees them: plus the gate's findings and its last command, and
    the start/resume requests only if the gate granted them."""
    return ControlInputs(
        frame=inputs.frame,
        observation=inputs.observation,
        feedback=inputs.feedback,
        events=inputs.events | found.keys(),
        event_details=MappingProxyType(details),
        start_requested=granted and inputs.start_requested,
        resume_requested=granted and inputs.resume_requested,
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
