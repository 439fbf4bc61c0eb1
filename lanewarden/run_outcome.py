"""Why a robot run ended, and its exit code: a normal end (0) or a safety stop (3).

A normal end is the operator's stop (Ctrl-C, SIGTERM, SIGQUIT, SIGHUP), `--duration` reached or
the end of a recorded clip. A safety stop is either
- a failure that ends the run by itself (the base link or the dead-man lost, the dead-man
  tripped, a live camera gone), or
- a supervisor HALT that stopped the robot while it was engaged and still held when the run ended
  (LANE_LOST, BUMPER, FRAME_STALE, ...), unless it was the operator's stop, or the clip's own end
  (a stale frame after the last frame of a recorded clip).
HALTs before the robot ever engaged stopped nothing and do not count.

Pure: `RunWatch` is fed the runner's step records; it never reads a clock.
"""

from __future__ import annotations

from dataclasses import dataclass

from lanewarden.errors import EXIT_OK, EXIT_SAFETY_STOP

#: Halt events that are a normal end, not a safety stop.
NORMAL_HALTS = frozenset({"OPERATOR_STOP"})
#: Halt events a recorded clip's end causes by itself once its last frame has been seen.
CLIP_END_HALTS = frozenset({"FRAME_STALE", "CAMERA_ERROR"})


@dataclass(frozen=True)
class RunOutcome:
    """`ended_by`: what ended the run, one line. `safety_stop`: the safety reason, or None for
    a normal end."""

    ended_by: str
    safety_stop: str | None = None

    @property
    def exit_code(self) -> int:
        return EXIT_SAFETY_STOP if self.safety_stop else EXIT_OK


def halt_event(halt_reason: str) -> str:
    """The event name a supervisor halt reason starts with ("LANE_LOST: no usable ...")."""
    return halt_reason.split(":", 1)[0].strip()


class RunWatch:
    """Follows the supervisor's state step by step and remembers the halt that stopped the
    robot (entering HALT from an engaged state), forgetting it when the robot engages again."""

    def __init__(self) -> None:
        self._state = "HALT"  # the supervisor starts halted: that stops nothing
        self._stopped_by: str | None = None
        self._stopped_at_s = 0.0
        self._newest_frame_s: float | None = None

    @property
    def stopped_by(self) -> str | None:
        """The halt reason that stopped the engaged robot and still holds (None: none)."""
        return self._stopped_by

    def observe(self, state: str, halt_reason: str | None, time_s: float,
                frame_time_s: float | None) -> None:
        """One step's record: its supervisor state, halt reason, step time and newest frame's
        capture time."""
        if frame_time_s is not None:
            self._newest_frame_s = max(self._newest_frame_s or frame_time_s, frame_time_s)
        if state == "HALT" and self._state != "HALT":
            self._stopped_by = halt_reason or "HALT"
            self._stopped_at_s = time_s
        elif state != "HALT":
            self._stopped_by = None
        self._state = state

    def outcome(self, ended_by: str, *, fault: str | None = None,
                clip_ended: bool = False) -> RunOutcome:
        """The outcome of a run that `ended_by` this (or by `fault`, a failure that ended it)."""
        if fault is not None:
            return RunOutcome(fault, fault)
        reason = self._stopped_by
        if reason is None or halt_event(reason) in NORMAL_HALTS:
            return RunOutcome(ended_by)
        after_last_frame = (self._newest_frame_s is None
                            or self._stopped_at_s > self._newest_frame_s)
        if clip_ended and halt_event(reason) in CLIP_END_HALTS and after_last_frame:
            return RunOutcome(ended_by)
        return RunOutcome(ended_by, reason)
