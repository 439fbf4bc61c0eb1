"""The base's safety sensors as events, and the age of its feedback. Pure.

Battery: below `battery_critical_v` a HALT event (BATTERY_CRITICAL), below `battery_low_v` a
WARN (BATTERY_LOW).
Bumper, cliff and wheel drop: any bit set is a HALT event (see `supervisor.events.EVENT_TABLE`),
with the sides named as detail (bit layout: `actuation.base.BaseFeedback`); so is the base's own
safety latch (`BaseFeedback.stop_latched`: DEADMAN_LATCHED, the dead-man's reason as detail).
The feedback's age (now - the time it was received; before any feedback, since the first step)
is what the SafetyGate turns into BASE_LINK_LOST and the watchdog into BASE_FEEDBACK_LATE.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from lanewarden.actuation.base import BaseFeedback
from lanewarden.actuation.kobuki_feedback import (
    BUMPER_SIDES,
    CLIFF_SIDES,
    WHEEL_DROP_SIDES,
    side_names,
)
from lanewarden.supervisor.events import Event

_SIDES: Mapping[Event, tuple[tuple[int, str], ...]] = MappingProxyType({
    Event.BUMPER: BUMPER_SIDES, Event.CLIFF: CLIFF_SIDES, Event.WHEEL_DROP: WHEEL_DROP_SIDES,
})  # fmt: skip


def base_hazard_events(feedback: BaseFeedback | None) -> dict[Event, str]:
    """BUMPER / CLIFF / WHEEL_DROP for every bit field with a bit set, each with the sides set
    ("left, centre"), and DEADMAN_LATCHED with the dead-man's reason while the base's own safety
    monitor holds a stop; empty for no feedback (missing feedback is a matter of its age)."""
    if feedback is None or not (feedback.bumper or feedback.cliff or feedback.wheel_drop
                                or feedback.stop_latched):
        return {}
    bits = {Event.BUMPER: feedback.bumper, Event.CLIFF: feedback.cliff,
            Event.WHEEL_DROP: feedback.wheel_drop}  # fmt: skip
    found = {
        event: ", ".join(side_names(value, _SIDES[event])) or f"bits {value:#x}"
        for event, value in bits.items()
        if value
    }
    if feedback.stop_latched:
        found[Event.DEADMAN_LATCHED] = feedback.stop_latched
    return found


def battery_events(feedback: BaseFeedback | None, low_v: float,
                   critical_v: float) -> dict[Event, str]:
    """BATTERY_CRITICAL below `critical_v`, else BATTERY_LOW below `low_v`, with the voltage as
    detail; empty when the base reports no battery."""
    volts = None if feedback is None else feedback.battery_v
    if volts is None or volts >= low_v:
        return {}
    detail = f"{volts:.1f} V"
    return {Event.BATTERY_CRITICAL if volts < critical_v else Event.BATTERY_LOW: detail}


def feedback_age_s(feedback: BaseFeedback | None, first_step_s: float, now: float) -> float:
    """Seconds since the newest feedback was received (since `first_step_s` before any)."""
    received = None if feedback is None else feedback.received_at_s
    return now - (first_step_s if received is None else received)


def stale_feedback_detail(feedback: BaseFeedback | None, age_s: float, limit_s: float) -> str:
    """What BASE_LINK_LOST measured when the feedback grew too old, one line (as FRAME_STALE's
    `Watchdog.stale_detail`): how old the newest feedback is, or that none came at all."""
    if feedback is None or feedback.received_at_s is None:
        return f"no feedback at all in {age_s:.2f} s"
    return f"no new feedback: the newest arrived {age_s:.2f} s ago, over the limit {limit_s:g} s"
