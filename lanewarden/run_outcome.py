"""Why a robot run ended: one function, `end_reason`, decides it, and every place that says so
shows what it decided: the last status line, the summary, stderr, `summary.json`, `replay`'s
metrics.json and report, and the live page (the status dict's `end_reason`).

What ended the runner's loop is a `LoopEnd`: the operator (Ctrl-C, SIGTERM, SIGQUIT, SIGHUP),
`--duration`, the end of a recorded clip, a failure that ends the run by itself (the base link or
the dead-man lost, the dead-man tripped, a live camera gone) or an error. The run's end reason
follows from it and from the supervisor's states (`RunWatch`):

- a failure that ends the run is a safety stop, named by its own line;
- a supervisor HALT that stopped the robot while it was engaged and still held when the loop
  ended (LANE_LOST, BUMPER, FRAME_STALE, ...) is a safety stop, named by its halt reason; not the
  operator's stop (OPERATOR_STOP), which is a normal end;
- the end of a clip is the run's end, not a halt: the CAMERA_ERROR or FRAME_STALE a clip's end
  causes once its last frame has been seen is the clip ending (`state` is then the state before
  it, e.g. FOLLOW), while a safety HALT that held when the clip ended is the reason;
- HALTs before the robot ever engaged stopped nothing and do not count;
- the runner's own closing stop (the step after the loop ended) is never looked at.

Exit code: 0 for a normal end, 3 for a safety stop (the README's table).

Pure: fed step records, never reads a clock; the same code decides for a live run (the runner)
and for a recorded one (`replay` of a run folder, from the recorded steps and the `LoopEnd` in
its summary.json).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from enum import StrEnum
from typing import Any

from lanewarden.errors import EXIT_OK, EXIT_SAFETY_STOP

#: Halt events that are a normal end, not a safety stop.
NORMAL_HALTS = frozenset({"OPERATOR_STOP"})
#: Halt events a recorded clip's end causes by itself once its last frame has been seen.
CLIP_END_HALTS = frozenset({"FRAME_STALE", "CAMERA_ERROR"})


class LoopEndKind(StrEnum):
    """What ended the runner's loop."""

    OPERATOR = "operator"  # Ctrl-C, SIGTERM, SIGQUIT, SIGHUP
    DURATION = "duration"  # --duration reached
    CLIP = "clip"  # a recorded clip or image sequence ran out
    FAILURE = "failure"  # a failure that ends the run by itself: a safety stop
    ERROR = "error"  # an exception ended it (the CLI's one-line error says which)
    CUT_SHORT = "cut short"  # a recording without its summary (the run was killed)


@dataclass(frozen=True)
class LoopEnd:
    """What ended the runner's loop: `kind`, and `text`, one line ("operator stop (SIGINT)",
    "--duration 5 s reached", "end of the clip", "BASE_LINK_LOST: ..."). `steps`: the steps
    before the runner's closing stop (None: all of them count)."""

    kind: LoopEndKind
    text: str
    steps: int | None = None

    def with_steps(self, steps: int) -> LoopEnd:
        return replace(self, steps=steps)

    def as_json(self) -> dict[str, Any]:
        return {"kind": str(self.kind), "text": self.text, "steps": self.steps}

    @classmethod
    def from_json(cls, data: object) -> LoopEnd | None:
        """The `ended_by` of a summary.json; None when absent or not understood."""
        if not isinstance(data, Mapping):
            return None
        try:
            kind = LoopEndKind(str(data.get("kind")))
        except ValueError:
            return None
        text, steps = data.get("text"), data.get("steps")
        if not isinstance(text, str) or not (steps is None or type(steps) is int and steps >= 0):
            return None
        return cls(kind, text, steps)


#: How a replay of a video, images or a tub ends: its last frame.
CLIP_END = LoopEnd(LoopEndKind.CLIP, "end of the clip")
#: How a recorded run without summary.json ends: where its steps stop.
CUT_SHORT = LoopEnd(LoopEndKind.CUT_SHORT,
                    "the recording stops here (it holds no summary: the run was cut short)")


def halt_event(halt_reason: str) -> str:
    """The event name a supervisor halt reason starts with ("LANE_LOST: no usable ...")."""
    return halt_reason.split(":", 1)[0].strip()


@dataclass(frozen=True)
class EndReason:
    """Why a run ended.

    `ended_by`: what ended the loop (`LoopEnd.text`). `safety_stop`: the safety reason (a halt
    reason or a failure's line), None for a normal end. `state`: the supervisor's state when the
    run ended (not counting the clip's own end or the runner's closing stop); `halt_reason`: the
    HALT's reason when `state` is HALT. `engaged`: the robot engaged at some point."""

    ended_by: str
    safety_stop: str | None
    state: str
    halt_reason: str | None = None
    engaged: bool = True
    kind: LoopEndKind = LoopEndKind.OPERATOR

    @property
    def exit_code(self) -> int:
        return EXIT_SAFETY_STOP if self.safety_stop else EXIT_OK

    @property
    def text(self) -> str:
        """The end reason in one line, as every place shows it: "safety stop: LANE_LOST: ..."
        or what ended the run ("end of the clip", "operator stop (SIGINT)")."""
        if self.safety_stop is not None:
            return f"safety stop: {self.safety_stop}"
        return self.ended_by

    @property
    def name(self) -> str:
        """Short: the safety stop's event name, else what ended the run."""
        return halt_event(self.safety_stop) if self.safety_stop is not None else self.ended_by

    @property
    def state_text(self) -> str:
        """'FOLLOW', 'HALT (LANE_LOST: ...)'."""
        if self.state == "HALT" and self.halt_reason:
            return f"HALT ({self.halt_reason})"
        return self.state

    @property
    def stop_line(self) -> str:
        """The summary's first line: what stopped the robot: `halted: REASON` for every safety
        stop (a failure that ended the run from FOLLOW says the state it stopped: `halted:
        DEADMAN_TRIPPED: ... (while FOLLOW)`), else the normal end and the state it stopped."""
        if not self.engaged:
            return "never engaged"
        if self.state == "HALT":
            return f"halted: {self.halt_reason or 'HALT'}"
        if self.safety_stop is not None:  # a failure that ended the run (the dead-man, a link)
            return f"halted: {self.safety_stop} (while {self.state})"
        return f"stopped by the end of the run ({self.ended_by}) while {self.state}"

    def as_json(self) -> dict[str, Any]:
        return {"text": self.text, "name": self.name, "safety_stop": self.safety_stop,
                "ended_by": self.ended_by, "state": self.state, "halt_reason": self.halt_reason,
                "engaged": self.engaged}


class RunWatch:
    """Follows the supervisor's state step by step: the halt that stopped the engaged robot (and
    still holds), the state it stopped from, and whether that halt came after the newest frame
    (what a clip's end looks like)."""

    def __init__(self) -> None:
        self.state = "HALT"  # the supervisor starts halted: that stops nothing
        self.halt_reason: str | None = None
        self.engaged = False
        self._stopped_by: str | None = None
        self._stopped_from = "HALT"
        self._stopped_at_s = 0.0
        self._newest_frame_s: float | None = None

    @property
    def stopped_by(self) -> str | None:
        """The halt reason that stopped the engaged robot and still holds (None: none)."""
        return self._stopped_by

    @property
    def stopped_from(self) -> str:
        """The engaged state that halt stopped."""
        return self._stopped_from

    @property
    def stopped_after_last_frame(self) -> bool:
        """That halt came after the newest frame's capture (as a clip's end does)."""
        return self._newest_frame_s is None or self._stopped_at_s > self._newest_frame_s

    def observe(self, state: str, halt_reason: str | None, time_s: float,
                frame_time_s: float | None) -> None:
        """One step's record: its supervisor state, halt reason, step time and newest frame's
        capture time."""
        if frame_time_s is not None:
            self._newest_frame_s = max(self._newest_frame_s or frame_time_s, frame_time_s)
        if state == "HALT" and self.state != "HALT":
            self._stopped_by = halt_reason or "HALT"
            self._stopped_from = self.state
            self._stopped_at_s = time_s
        elif state != "HALT":
            self._stopped_by = None
            self.engaged = True
        self.state, self.halt_reason = state, halt_reason

    def observe_all(self, steps: Iterable[tuple[str, str | None, float, float | None]]) -> None:
        for step in steps:
            self.observe(*step)


def end_reason(watch: RunWatch, end: LoopEnd) -> EndReason:
    """The one decision of why a run ended (see the module docstring)."""

    def ended(safety_stop: str | None, state: str, halt_reason: str | None) -> EndReason:
        return EndReason(end.text, safety_stop, state, halt_reason, watch.engaged, end.kind)

    halt = watch.halt_reason if watch.state == "HALT" else None
    if end.kind is LoopEndKind.FAILURE:
        return ended(end.text, watch.state, halt)
    reason = watch.stopped_by
    if reason is None:  # engaged when the loop ended, or never engaged
        return ended(None, watch.state, halt)
    event = halt_event(reason)
    if (end.kind is LoopEndKind.CLIP and event in CLIP_END_HALTS
            and watch.stopped_after_last_frame):
        return ended(None, watch.stopped_from, None)  # the clip's end, not a halt
    if event in NORMAL_HALTS:
        return ended(None, "HALT", reason)
    return ended(reason, "HALT", reason)


def end_reason_of(steps: Iterable[tuple[str, str | None, float, float | None]],
                  end: LoopEnd) -> EndReason:
    """`end_reason` for recorded steps (state, halt reason, step time, frame time): the first
    `end.steps` of them (the runner's closing stop after them is not looked at)."""
    watch = RunWatch()
    for index, step in enumerate(steps):
        if end.steps is not None and index >= end.steps:
            break
        watch.observe(*step)
    return end_reason(watch, end)


def recorded_loop_end(summary: Mapping[str, Any] | None) -> LoopEnd:
    """What ended a recorded run: its summary.json's `ended_by`, else (no summary: the run was
    killed) where the recording stops; the same where a summary does not say (written before
    `ended_by` was, or damaged: replay then says the recording is incomplete), in other words."""
    found = LoopEnd.from_json((summary or {}).get("ended_by"))
    if found is not None:
        return found
    return CUT_SHORT if not summary else UNSAID_END


#: How a recorded run whose summary does not say what ended it ends: where its steps stop.
UNSAID_END = LoopEnd(LoopEndKind.CUT_SHORT,
                     "the recording stops here (its summary does not say what ended the run)")
