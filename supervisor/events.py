"""Faults as data: every event the supervisor can raise, and ONE table of how it responds.

`Event` names what happened; `EVENT_TABLE` maps each event to a `Response` (WARN: record it and
carry on; DEGRADE: slow down with bounded steering; HALT: zero command now, latched) and the reason
text a log or an operator reads. The state machine only ever asks `response_of(event)`; adding an
event means adding a row here (a test fails otherwise) and a test that provokes it.

The declaration order of `Event` is the priority order used to pick a halt reason when several HALT
events arrive in the same step. Pure data: nothing here reads a clock or an input.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType


class Response(enum.IntEnum):
    """What the supervisor does about an event; a larger value is more severe."""

    WARN = 1
    DEGRADE = 2
    HALT = 3


class Event(enum.Enum):
    """Everything the supervisor reacts to. Values are the names written into run.jsonl."""

    # HALT, most telling first (the first present becomes the halt reason).
    OPERATOR_STOP = "OPERATOR_STOP"
    DEADMAN_LATCHED = "DEADMAN_LATCHED"
    BUMPER = "BUMPER"
    CLIFF = "CLIFF"
    WHEEL_DROP = "WHEEL_DROP"
    BASE_LINK_LOST = "BASE_LINK_LOST"
    BATTERY_CRITICAL = "BATTERY_CRITICAL"
    CAMERA_ERROR = "CAMERA_ERROR"
    PERCEPTION_ERROR = "PERCEPTION_ERROR"
    CONTROLLER_ERROR = "CONTROLLER_ERROR"
    MALFORMED_OBSERVATION = "MALFORMED_OBSERVATION"
    FRAME_INVALID = "FRAME_INVALID"
    CLOCK_INVALID = "CLOCK_INVALID"
    FRAME_STALE = "FRAME_STALE"
    FRAME_FROZEN = "FRAME_FROZEN"
    LANE_DEPARTURE = "LANE_DEPARTURE"
    LANE_LOST = "LANE_LOST"
    DEGRADED_BUDGET_EXHAUSTED = "DEGRADED_BUDGET_EXHAUSTED"
    # DEGRADE
    FRAME_LATE = "FRAME_LATE"
    BASE_FEEDBACK_LATE = "BASE_FEEDBACK_LATE"
    BOTH_EDGES_LOST = "BOTH_EDGES_LOST"
    LANE_UNTRUSTED = "LANE_UNTRUSTED"
    ONE_EDGE_LOST = "ONE_EDGE_LOST"
    LANE_LOW_CONFIDENCE = "LANE_LOW_CONFIDENCE"
    REPEATED_OUTLIERS = "REPEATED_OUTLIERS"
    # WARN
    INNOVATION_OUTLIER = "INNOVATION_OUTLIER"
    LOOP_OVERRUN = "LOOP_OVERRUN"
    BATTERY_LOW = "BATTERY_LOW"

    # Members are singletons compared by identity: hash them by identity too, in C. (Enum's own
    # __hash__ hashes the name in Python code, and events go through sets and dicts many times a
    # step; Python randomises string hashes per process anyway, so no order depended on it.)
    __hash__ = object.__hash__


@dataclass(frozen=True)
class EventRule:
    response: Response
    reason: str


_H, _D, _W = Response.HALT, Response.DEGRADE, Response.WARN

#: The one table: event -> (response, human-readable reason).
EVENT_TABLE: Mapping[Event, EventRule] = MappingProxyType(
    {
        Event.OPERATOR_STOP: EventRule(_H, "operator stop"),
        Event.DEADMAN_LATCHED: EventRule(
            _H, "the dead-man latched a stop on its own, held until a resume"
        ),
        Event.BUMPER: EventRule(_H, "bumper pressed"),
        Event.CLIFF: EventRule(_H, "cliff sensor triggered"),
        Event.WHEEL_DROP: EventRule(_H, "wheel dropped"),
        Event.BASE_LINK_LOST: EventRule(_H, "link lost (no feedback, or a command not written)"),
        Event.BATTERY_CRITICAL: EventRule(
            _H, "battery below battery_critical_v: charge it before the base browns out"
        ),
        Event.CAMERA_ERROR: EventRule(_H, "the frame source raised an error"),
        Event.PERCEPTION_ERROR: EventRule(_H, "perception raised an error"),
        Event.CONTROLLER_ERROR: EventRule(
            _H, "the controller raised an error or returned a malformed output"
        ),
        Event.MALFORMED_OBSERVATION: EventRule(
            _H, "perception returned a malformed observation (non-finite or out of range)"
        ),
        Event.FRAME_INVALID: EventRule(
            _H, "frame timestamp or index is invalid (from the future, backwards or not finite)"
        ),
        Event.CLOCK_INVALID: EventRule(_H, "step time went backwards or is not finite"),
        Event.FRAME_STALE: EventRule(_H, "newest camera frame older than frame_stale_s"),
        Event.FRAME_FROZEN: EventRule(_H, "camera frames identical while moving (frozen camera)"),
        Event.LANE_DEPARTURE: EventRule(
            _H, "a lane edge inside the robot's footprint for lane_departure_frames frames "
            "(leaving the lane)"
        ),
        Event.LANE_LOST: EventRule(_H, "no usable lane for longer than lane_lost_halt_s"),
        Event.DEGRADED_BUDGET_EXHAUSTED: EventRule(
            _H, "degraded for longer than its time or distance budget"
        ),
        Event.FRAME_LATE: EventRule(_D, "newest camera frame is late"),
        Event.BASE_FEEDBACK_LATE: EventRule(_D, "base feedback is late"),
        Event.BOTH_EDGES_LOST: EventRule(_D, "neither lane edge found in this frame"),
        Event.LANE_UNTRUSTED: EventRule(_D, "lane confidence below the usable minimum"),
        Event.ONE_EDGE_LOST: EventRule(_D, "only one lane edge found in this frame"),
        Event.LANE_LOW_CONFIDENCE: EventRule(
            _D, "lane confidence low for low_confidence_degrade_frames frames"
        ),
        Event.REPEATED_OUTLIERS: EventRule(
            _D, "slope-sum outliers repeated within outliers_window_frames"
        ),
        Event.INNOVATION_OUTLIER: EventRule(_W, "slope-sum measurement rejected by the gate"),
        Event.LOOP_OVERRUN: EventRule(_W, "control step came later than loop_overrun_s"),
        Event.BATTERY_LOW: EventRule(_W, "battery below battery_low_v: charge it soon"),
    }
)

#: Events that mean "the lane is gone" (the only halt cause `auto_resume_after_lane_loss` forgives).
LANE_LOSS_EVENTS: frozenset[Event] = frozenset({Event.LANE_LOST})


#: Each event's response, read from `EVENT_TABLE` once (asked for many times a step).
_RESPONSES: Mapping[Event, Response] = {e: rule.response for e, rule in EVENT_TABLE.items()}
#: Each event's place in the priority (declaration) order of `Event`.
_PRIORITY: Mapping[Event, int] = {e: i for i, e in enumerate(Event)}


def response_of(event: Event) -> Response:
    return _RESPONSES[event]


def worst_response(events: Iterable[Event]) -> Response | None:
    """The most severe response among `events` (None for no events)."""
    return max(map(_RESPONSES.__getitem__, events), default=None)


def ordered(events: Iterable[Event]) -> tuple[Event, ...]:
    """Events in table (priority) order, without duplicates."""
    return tuple(sorted(set(events), key=_PRIORITY.__getitem__))


def event_reason(event: Event, details: Mapping[Event, str] | None = None) -> str:
    """`NAME: reason` of one event, with its detail in brackets if it has one."""
    detail = None if details is None else details.get(event)
    reason = f"{event.value}: {EVENT_TABLE[event].reason}"
    return f"{reason} ({detail})" if detail else reason


def halt_reason(events: Iterable[Event], details: Mapping[Event, str] | None = None) -> str | None:
    """Reason text of the highest-priority HALT event (with its detail, if any), or None."""
    for event in ordered(events):
        if response_of(event) is Response.HALT:
            return event_reason(event, details)
    return None
