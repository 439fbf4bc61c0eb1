"""Why the controller is in its state, step by step, for reports (video captions, plots).

- HALT: the halt reason's short form (`LANE_LOST`, `BUMPER`, `not engaged yet`, ...).
- DEGRADED: the DEGRADE events of the step that entered DEGRADED (e.g. `LANE_UNTRUSTED`, or
  `LANE_UNTRUSTED + LANE_LOW_CONFIDENCE`), kept while it stays DEGRADED (the steps after entering
  often raise nothing: they are recovering).
- any other state: None.

Pure: reads step records' fields, never the supervisor's internals.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from lanewarden.supervisor.events import EVENT_TABLE, Event, Response

HALT = "HALT"
DEGRADED = "DEGRADED"
_DEGRADE_EVENTS = frozenset(e.value for e in Event if EVENT_TABLE[e].response is Response.DEGRADE)


def short_reason(reason: str | None) -> str | None:
    """'LANE_LOST: no usable lane ...' -> 'LANE_LOST'; the part before the first colon."""
    if not reason:
        return None
    return reason.split(":", 1)[0].strip()


class StateReasons:
    """Feed every step in order; `update` returns that step's reason (see the module docstring)."""

    def __init__(self) -> None:
        self._state: str | None = None
        self._degraded: str | None = None

    def update(self, state: str, events: Iterable[str], halt_reason: str | None) -> str | None:
        entering = state != self._state
        self._state = state
        if state == HALT:
            return short_reason(halt_reason)
        if state != DEGRADED:
            return None
        if entering:
            names = [e for e in events if e in _DEGRADE_EVENTS]
            self._degraded = " + ".join(names) if names else None
        return self._degraded


def state_reasons(states: Sequence[str], events: Sequence[Iterable[str]],
                  halt_reasons: Sequence[str | None]) -> list[str | None]:
    """The reason of every step (see the module docstring)."""
    tracker = StateReasons()
    return [tracker.update(s, e, h) for s, e, h in zip(states, events, halt_reasons, strict=True)]


def state_with_reason(state: str, reason: str | None) -> str:
    """'HALT: LANE_LOST', 'DEGRADED (LANE_UNTRUSTED)', 'FOLLOW'."""
    if reason is None:
        return state
    return f"{state}: {reason}" if state == HALT else f"{state} ({reason})"
