"""The fail-safe state machine (transitions): FOLLOW, TURN_LEFT, TURN_RIGHT, DEGRADED, HALT.

One trigger, `tick`, serves every control step. `TRANSITIONS` is the explicit table: for each
source state the rows are tried in order and the first whose named condition holds wins (so HALT
beats DEGRADE beats recovery beats turning). No row matching means "stay" (and a step where no row
of the current state can match does not fire the trigger at all). HALT is the initial state
and is latched: entering it disarms any engage request, and only a NEW start/resume request plus
`engage_confident_frames` confident frames in a row (with no DEGRADE or HALT event) engage again
(or, with `engage_window_frames` M set, that many among the last M judged frames, the newest
confident: k of n). DEGRADED recovers to FOLLOW on `recover_confident_frames` likewise, among
the last `recover_window_frames` (8 by default: k of n; 0: in a row).
A fresh HALT event while halted re-enters HALT (new reason, request disarmed again).

Timers count injected time (`StepFacts.now`) and frames, never wall clock: no transitions `Timeout`
states, no threads. The machine never reads an input itself; `SupervisedController` builds the
`StepFacts`.
"""

from __future__ import annotations

import enum
from collections import deque
from collections.abc import Mapping
from collections.abc import Set as AbstractSet
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from transitions import Machine

from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.events import (
    LANE_LOSS_EVENTS,
    Event,
    Response,
    halt_reason,
    response_of,
    worst_response,
)


class SupervisorState(enum.Enum):
    FOLLOW = "FOLLOW"
    TURN_LEFT = "TURN_LEFT"
    TURN_RIGHT = "TURN_RIGHT"
    DEGRADED = "DEGRADED"
    HALT = "HALT"

    __hash__ = object.__hash__  # singletons: identity hash, in C (Enum's hashes the name in Python)


S = SupervisorState
ENGAGED_STATES: frozenset[SupervisorState] = frozenset(
    {S.FOLLOW, S.TURN_LEFT, S.TURN_RIGHT, S.DEGRADED}
)
NOT_STARTED_REASON = "not engaged yet: waiting for start and a confident lane"

#: DEGRADE events that only say this frame's lane was not confident (the frame itself is counted
#: as unconfident): they do not wipe the confident frames seen before it, which the engage window
#: `engage_window_frames` weighs (in a row, the default, any of them restarts the count anyway).
#: Any other DEGRADE or HALT event (late frames, repeated outliers, hazards) wipes them.
FRAME_JUDGEMENT_EVENTS: frozenset[Event] = frozenset({
    Event.BOTH_EDGES_LOST, Event.LANE_UNTRUSTED, Event.ONE_EDGE_LOST, Event.LANE_LOW_CONFIDENCE})
_BELOW_DEGRADE: frozenset[Event] = frozenset(
    e for e in Event if response_of(e) < Response.DEGRADE)


def forgets_confident_frames(events: AbstractSet[Event]) -> bool:
    """Whether a step with these events wipes the confident frames counted towards engaging and
    recovering: any DEGRADE or HALT event but those that only judge the step's frame
    (FRAME_JUDGEMENT_EVENTS)."""
    worst = worst_response(events)
    return (worst is not None and worst >= Response.DEGRADE
            and not events <= FRAME_JUDGEMENT_EVENTS | _BELOW_DEGRADE)


#: The explicit transition table. Order matters within a source state (first match wins).
TRANSITIONS: tuple[dict[str, Any], ...] = (
    {"trigger": "tick", "source": [S.FOLLOW, S.TURN_LEFT, S.TURN_RIGHT, S.DEGRADED],
     "dest": S.HALT, "conditions": "must_halt"},
    {"trigger": "tick", "source": S.HALT, "dest": S.HALT, "conditions": "must_halt"},
    {"trigger": "tick", "source": S.HALT, "dest": S.FOLLOW, "conditions": "may_engage"},
    {"trigger": "tick", "source": [S.FOLLOW, S.TURN_LEFT, S.TURN_RIGHT], "dest": S.DEGRADED,
     "conditions": "must_degrade"},
    {"trigger": "tick", "source": S.DEGRADED, "dest": S.FOLLOW, "conditions": "may_recover"},
    {"trigger": "tick", "source": [S.FOLLOW, S.TURN_RIGHT], "dest": S.TURN_LEFT,
     "conditions": "bend_left_entered"},
    {"trigger": "tick", "source": [S.FOLLOW, S.TURN_LEFT], "dest": S.TURN_RIGHT,
     "conditions": "bend_right_entered"},
    {"trigger": "tick", "source": S.TURN_LEFT, "dest": S.FOLLOW, "conditions": "bend_left_ended"},
    {"trigger": "tick", "source": S.TURN_RIGHT, "dest": S.FOLLOW, "conditions": "bend_right_ended"},
)  # fmt: skip


def _conditions_by_source() -> dict[SupervisorState, tuple[str, ...]]:
    """For each state, the named conditions of the `TRANSITIONS` rows that leave it, in order."""
    names: dict[SupervisorState, list[str]] = {state: [] for state in SupervisorState}
    for row in TRANSITIONS:
        sources = row["source"] if isinstance(row["source"], list) else [row["source"]]
        for source in sources:
            names[source].append(row["conditions"])
    return {state: tuple(conditions) for state, conditions in names.items()}


#: What `tick` may do from each state: nothing unless one of these conditions holds.
CONDITIONS_BY_SOURCE: Mapping[SupervisorState, tuple[str, ...]] = MappingProxyType(
    _conditions_by_source()
)


def machine_arguments() -> dict[str, Any]:
    """Keyword arguments of the transitions Machine, shared by the supervisor and its diagram."""
    return {
        "states": SupervisorState,
        "transitions": [dict(row) for row in TRANSITIONS],
        "initial": SupervisorState.HALT,
        "auto_transitions": False,
        "queued": True,
    }


@dataclass(frozen=True)
class StepFacts:
    """What the machine needs to know about one step (built by the controller).

    - `frame_confident`: None when no new frame was judged this step, else whether it was confident
      (both edges, confidence >= confidence_confident_min, accepted by the filter's gate).
    - `lane_seen_at_s`: capture time of the newest usable lane (None: never).
    - `slope_sum`: the filtered slope sum (None before the filter has a measurement).
    - `travelled_m`: distance covered since the previous step (for the degraded distance budget).
    """

    now: float
    events: frozenset[Event] = frozenset()
    event_details: Mapping[Event, str] = field(default_factory=lambda: MappingProxyType({}))
    frame_confident: bool | None = None
    lane_seen_at_s: float | None = None
    slope_sum: float | None = None
    travelled_m: float = 0.0
    engage_requested: bool = False


@dataclass(frozen=True)
class Tick:
    """The argument of the `tick` trigger: the facts plus the events the machine itself raised."""

    facts: StepFacts
    events: frozenset[Event]
    #: The most severe response among `events` (None: no events), worked out once for all the
    #: conditions that ask.
    worst: Response | None


class ConfidentFrames:
    """Whether `needed` of the last `window` judged frames were confident, the newest among
    them (k of n). `window` 0 (or `needed`): all `needed` in a row."""

    def __init__(self, needed: int, window: int) -> None:
        self.needed = needed
        self.frames: deque[bool] = deque(maxlen=max(window, needed))
        self.confident = 0

    def add(self, confident: bool) -> None:
        frames = self.frames
        if len(frames) == frames.maxlen:
            self.confident -= frames[0]
        frames.append(confident)
        self.confident += confident

    def clear(self) -> None:
        self.frames.clear()
        self.confident = 0

    @property
    def enough(self) -> bool:
        return self.confident >= self.needed and self.frames[-1]


class SupervisorStateMachine:
    """The transitions model. `state` is set by transitions' Machine."""

    state: SupervisorState

    def __init__(self, config: SupervisorConfig) -> None:
        self._config = config
        self.halt_reason: str | None = NOT_STARTED_REASON
        self.engage_armed = False
        # k of the last n judged frames confident, the newest among them: to engage, to recover.
        self.engage_frames = ConfidentFrames(config.engage_confident_frames,
                                             config.engage_window_frames)
        self.recover_frames = ConfidentFrames(config.recover_confident_frames,
                                              config.recover_window_frames)
        self.degraded_since_s: float | None = None
        self.degraded_travelled_m = 0.0
        self._machine = Machine(model=self, **machine_arguments())
        self._conditions = {
            state: tuple(getattr(self, name) for name in names)
            for state, names in CONDITIONS_BY_SOURCE.items()
        }

    @property
    def engaged(self) -> bool:
        return self.state in ENGAGED_STATES

    def step(self, facts: StepFacts) -> Tick:
        """Run one control step; returns the tick (facts + all events, including LANE_LOST and
        DEGRADED_BUDGET_EXHAUSTED raised here)."""
        cfg = self._config
        raised: set[Event] = set()
        if self.engaged and (
            facts.lane_seen_at_s is None or facts.now - facts.lane_seen_at_s > cfg.lane_lost_halt_s
        ):
            raised.add(Event.LANE_LOST)
        if self.state is S.DEGRADED and self.degraded_since_s is not None:
            self.degraded_travelled_m += abs(facts.travelled_m)
            if (
                facts.now - self.degraded_since_s > cfg.degraded_budget_s
                or self.degraded_travelled_m > cfg.degraded_budget_m
            ):
                raised.add(Event.DEGRADED_BUDGET_EXHAUSTED)
        if facts.engage_requested and self.state is S.HALT:
            self.engage_armed = True
        events = facts.events | raised if raised else facts.events
        tick = Tick(facts, events, worst_response(events))
        if forgets_confident_frames(events):
            self._forget_confident_frames()
        elif facts.frame_confident is not None:
            self.engage_frames.add(facts.frame_confident)
            self.recover_frames.add(facts.frame_confident)
        if self._may_fire(tick):
            self._machine.events["tick"].trigger(self, tick)
        return tick

    def _forget_confident_frames(self) -> None:
        self.engage_frames.clear()
        self.recover_frames.clear()

    def _may_fire(self, tick: Tick) -> bool:
        """Whether some row leaving the current state has its condition met. When none has,
        transitions' `tick` would do nothing (no transition, no callback): it is not fired."""
        for condition in self._conditions[self.state]:
            if condition(tick):
                return True
        return False

    # --- named conditions (called by transitions with the Tick) ---
    def must_halt(self, tick: Tick) -> bool:
        """Some event this step has the HALT response."""
        return tick.worst is Response.HALT

    def must_degrade(self, tick: Tick) -> bool:
        """The worst event this step has the DEGRADE response."""
        return tick.worst is Response.DEGRADE

    def may_engage(self, tick: Tick) -> bool:
        """A start/resume made since the last halt, `engage_confident_frames` confident frames
        in a row (or among the last `engage_window_frames`, the newest confident), nothing worse
        than WARN this step, and a filtered slope sum."""
        return (
            self.engage_armed
            and self.engage_frames.enough
            and (tick.worst is None or tick.worst < Response.DEGRADE)
            and tick.facts.slope_sum is not None
        )

    def may_recover(self, tick: Tick) -> bool:
        """`recover_confident_frames` confident frames among the last `recover_window_frames`
        (8 by default; 0: in a row), the newest confident, and nothing worse than WARN."""
        return self.recover_frames.enough and (
            tick.worst is None or tick.worst < Response.DEGRADE
        )

    def bend_left_entered(self, tick: Tick) -> bool:
        """Filtered slope sum >= turn_enter_slope_sum."""
        s = tick.facts.slope_sum
        return s is not None and s >= self._config.turn_enter_slope_sum

    def bend_right_entered(self, tick: Tick) -> bool:
        """Filtered slope sum <= -turn_enter_slope_sum."""
        s = tick.facts.slope_sum
        return s is not None and s <= -self._config.turn_enter_slope_sum

    def bend_left_ended(self, tick: Tick) -> bool:
        """Filtered slope sum < turn_exit_slope_sum."""
        s = tick.facts.slope_sum
        return s is None or s < self._config.turn_exit_slope_sum

    def bend_right_ended(self, tick: Tick) -> bool:
        """Filtered slope sum > -turn_exit_slope_sum."""
        s = tick.facts.slope_sum
        return s is None or s > -self._config.turn_exit_slope_sum

    # --- state callbacks (transitions binds on_enter_<STATE> / on_exit_<STATE> by name) ---
    def on_enter_HALT(self, tick: Tick) -> None:
        halting = {e for e in tick.events if response_of(e) is Response.HALT}
        self.halt_reason = halt_reason(tick.events, tick.facts.event_details)
        # Latch: a request made before this halt does not count.
        self.engage_armed = self._config.auto_resume_after_lane_loss and halting <= LANE_LOSS_EVENTS
        self._forget_confident_frames()
        self.degraded_since_s = None
        self.degraded_travelled_m = 0.0

    def on_exit_HALT(self, tick: Tick) -> None:
        self.halt_reason = None
        self.engage_armed = False

    def on_enter_DEGRADED(self, tick: Tick) -> None:
        self.degraded_since_s = tick.facts.now
        self.degraded_travelled_m = 0.0
        self._forget_confident_frames()

    def on_exit_DEGRADED(self, tick: Tick) -> None:
        self.degraded_since_s = None
        self.degraded_travelled_m = 0.0
