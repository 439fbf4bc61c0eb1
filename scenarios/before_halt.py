"""What perception gave the supervisor just before a run halted: the summary a false halt is read
from (docs/campaigns.md, "Known gaps", was written by hand from such windows).

Over the last `window_s` seconds of steps up to and including the halting one, counted per new
frame judged (a step whose record carries an observation):

- `frames`: frames judged; `confident`, `usable` (usable but not confident) and `unusable`, as
  the supervisor graded them: `supervisor.lane_evidence.frame_grade`, except that a frame whose
  step raised LANE_UNTRUSTED is unusable whatever its confidence (the supervisor's verdict on a
  lane placed from one tape that jumped where the robot could not have moved it);
- `jumped`: of the unusable frames, those lanes placed from one tape that jumped (LANE_UNTRUSTED
  on a frame `frame_grade` alone would call usable);
- `weakest`: among the unusable frames, how often each confidence component was the weakest one
  (a component at 1 never counts; ties: the first in the observation's order), most frequent
  first, at most three;
- `longest_confident_run`: the most confident frames in a row as the supervisor counts them
  towards recovering (DEGRADED recovers on `recover_confident_frames`, 5 by default, of the
  last `recover_window_frames`, 8): a
  confident frame whose slope sum the filter rejected (INNOVATION_OUTLIER) does not count, and a
  step whose events wipe the count (`state_machine.forgets_confident_frames`: REPEATED_OUTLIERS,
  say) ends a run as an unconfident frame does;
- `at_slope_cap`: confident frames with an edge's slope at the cap (`edges.max_abs_slope`): an
  edge reported upright in the image, whose slope the lecture's rule cannot read (the slope sum
  then jumps, and the filter rejects it);
- `outliers`: steps with INNOVATION_OUTLIER (the slope filter rejected the measurement);
- `no_frame`: steps without a judged frame (no new frame, or perception failed on it).

Pure function of the step records and the thresholds.
"""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Sequence
from typing import Any

from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.lane_evidence import frame_grade
from lanewarden.supervisor.loop import StepRecord
from lanewarden.supervisor.state_machine import forgets_confident_frames
from lanewarden.wording import counted

#: The window summarised, seconds before the halt: the supervisor's DEGRADED time budget when it
#: was written (3 s since the twenty-eighth campaign; left at 2 s so that reports stay comparable
#: with the earlier campaigns').
WINDOW_S = 2.0
#: Weakest components listed, most frequent first.
WEAKEST_LISTED = 3
#: An edge's slope this close to the cap counts as at it (slopes are capped exactly; rounding in
#: a recording leaves them a hair off).
_AT_CAP = 1e-6


def before_halt(records: Sequence[StepRecord], halt_index: int, config: SupervisorConfig,
                max_abs_slope: float, window_s: float = WINDOW_S) -> dict[str, Any]:
    """The summary (module docstring) of the steps in (records[halt_index].time_s - window_s,
    records[halt_index].time_s]."""
    end = records[halt_index].time_s
    window = [r for r in records[:halt_index + 1] if r.time_s > end - window_s]
    grades = {"confident": 0, "usable": 0, "unusable": 0}
    weakest: Counter[str] = Counter()
    run = longest = at_cap = outliers = no_frame = jumped = 0
    for record in window:
        events = frozenset(Event(name) for name in record.events)
        outlier = Event.INNOVATION_OUTLIER in events
        outliers += outlier
        wiped = forgets_confident_frames(events)
        if wiped:
            run = 0
        obs = record.observation
        if obs is None:
            no_frame += 1
            continue
        usable, confident = frame_grade(obs, config)
        if usable and Event.LANE_UNTRUSTED in events:  # a placed lane that jumped: unusable
            jumped += 1
            grades["unusable"] += 1
            run = 0
            continue
        grade = "confident" if confident else "usable" if usable else "unusable"
        grades[grade] += 1
        run = run + 1 if confident and not outlier and not wiped else 0
        longest = max(longest, run)
        if confident and any(edge is not None and abs(edge.slope) >= max_abs_slope - _AT_CAP
                             for edge in (obs.left, obs.right)):
            at_cap += 1
        if grade == "unusable":
            below = [(value, name) for name, value in obs.components.items() if value < 1.0]
            if below:
                weakest[min(below, key=lambda item: item[0])[1]] += 1
    return {
        "window_s": window_s,
        "frames": sum(grades.values()),
        **grades,
        "jumped": jumped,
        "weakest": dict(weakest.most_common(WEAKEST_LISTED)),
        "longest_confident_run": longest,
        "at_slope_cap": at_cap,
        "outliers": outliers,
        "no_frame": no_frame,
    }


def halt_line(summary: object) -> str | None:
    """The terminal's line under a halt (`sim`, `replay`, `run`'s summary): '  before the halt:
    last 2 s: ...'; None without a summary (a run that never halted after engaging)."""
    return f"  before the halt: {describe(summary)}" if isinstance(summary, dict) else None


def describe(summary: dict[str, Any]) -> str:
    """One line for a report: 'last 2 s: 61 frames, 40 confident (at most 4 in a row), 5 usable but
    not confident, 16 unusable (lane_width 9, parallel 4); 5 at the slope cap; 13 outliers'."""
    weakest = summary.get("weakest") or {}
    unusable = f"{summary['unusable']} unusable"
    reasons = [f"{name} {count}" for name, count in weakest.items()]
    if summary.get("jumped"):
        reasons.append(f"placed lane jumped {summary['jumped']}")
    if reasons:
        unusable += " (" + ", ".join(reasons) + ")"
    parts = [f"last {summary['window_s']:g} s: {counted(summary['frames'], 'frame')}, "
             f"{summary['confident']} confident (at most {summary['longest_confident_run']} in "
             f"a row), {summary['usable']} usable but not confident, {unusable}"]
    if summary.get("at_slope_cap"):
        parts.append(f"{summary['at_slope_cap']} at the slope cap")
    if summary.get("outliers"):
        parts.append(counted(summary["outliers"], "outlier"))
    if summary.get("no_frame"):
        parts.append(counted(summary["no_frame"], "step") + " without a frame")
    return "; ".join(parts)


class RecentSteps:
    """The step records of the last `window_s` seconds (by their step times), and a copy of them
    at each halt after engaging (a step in HALT after one that was not), with the number of the
    step it came at: what `before_halt` summarises for a run that keeps no list of its records
    (the robot runner). Only the last two halts are kept (a run's own halt, then the runner's
    closing stop)."""

    def __init__(self, window_s: float = WINDOW_S) -> None:
        self.window_s = window_s
        self._recent: deque[StepRecord] = deque()
        self._steps = 0
        self._state = "HALT"  # the supervisor starts halted: that is no halt
        self._halts: list[tuple[int, list[StepRecord]]] = []

    def observe(self, record: StepRecord) -> None:
        self._recent.append(record)
        while self._recent[0].time_s <= record.time_s - self.window_s:
            self._recent.popleft()
        if record.state == "HALT" and self._state != "HALT":
            self._halts = [*self._halts[-1:], (self._steps, list(self._recent))]
        self._state = record.state
        self._steps += 1

    def before_halt(self, steps: int | None) -> list[StepRecord] | None:
        """The records of the window before the latest halt that came within the first `steps`
        steps (None: any step), the halting one last; None without such a halt."""
        for index, window in reversed(self._halts):
            if steps is None or index < steps:
                return window
        return None
