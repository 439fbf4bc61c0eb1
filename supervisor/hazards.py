"""The base's safety sensors as events, and the age of its feedback. Pure.

Battery: below `battery_critical_v` a HALT event (BATTERY_CRITICAL), below `battery_low_v` a
WARN (BATTERY_LOW).
Bumper, cliff and wheel drop: any bit set is a HALT event (see `supervisor.events.EVENT_TABLE`),
with the sides named as detail (bit layout: `actuation.base.BaseFeedback`). The feedback's age
(now - the time it was received; before any feedback, since the first step) is what the
SafetyGate turns into BASE_LINK_LOST and the watchdog into BASE_FEEDBACK_LATE.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from lanewarden.actuation.base import BaseFeedback
from lanewarden.supervisor.events import Event

_SIDES: Mapping[Event, tuple[tuple[int, str], ...]] = MappingProxyType({
    Event.BUMPER: ((4, "left"), (2, "centre"), (1, "right")),
    Event.CLIFF: ((4, "left"), (2, "centre"), (1, "right")),
    Event.WHEEL_DROP: ((2, "left"), (1, "right")),
})  # fmt: skip


def base_hazard_events(feedback: BaseFeedback | None) -> dict[Event, str]:
    """BUMPER / CLIFF / WHEEL_DROP for every bit field with a bit set, each with the sides set
    ("left, centre"); empty for no feedback (missing feedback is a matter of its age)."""
    if feedback is None or not (feedback.bumper or feedback.cliff or feedback.wheel_drop):
        return {}
    bits = {Event.BUMPER: feedback.bumper, Event.CLIFF: feedback.cliff,
            Event.WHEEL_DROP: feedback.wheel_drop}  # fmt: skip
    return {
        event: ", ".join(name for bit, name in _SIDES[event] if value & bit) or f"bits {value:#x}"
        for event, value in bits.items()
        if value
    }


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
