"""The base's safety sensors as events: bumper, cliff and wheel drop (Kobuki bit fields).

Any bit set is a HALT event (see `supervisor.events.EVENT_TABLE`). Missing feedback is not a hazard
here; the watchdog turns its age into BASE_LINK_LOST. Pure.
"""

from __future__ import annotations

from lanewarden.actuation.base import BaseFeedback
from lanewarden.supervisor.events import Event


def base_hazard_events(feedback: BaseFeedback | None) -> frozenset[Event]:
    if feedback is None:
        return frozenset()
    events: set[Event] = set()
    if feedback.bumper:
        events.add(Event.BUMPER)
    if feedback.cliff:
        events.add(Event.CLIFF)
    if feedback.wheel_drop:
        events.add(Event.WHEEL_DROP)
    return frozenset(events)
