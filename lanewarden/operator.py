"""The operator's side of a run: requests (start, stop, resume), the Kobuki's buttons, the live
status and the final summary.

- `OperatorPanel`: the one place the keyboard, the Kobuki's buttons and the live page send their
  requests. They go through the supervisor's own requests: Stop calls `ControlLoop.operator_stop`
  at once from the caller's thread (a zero command immediately, HALT at the next step); Start and
  Resume only arm (`ControlLoop.start` / `resume`, delivered by the control thread before its next
  step), so the supervisor still needs its confident frames before anything moves. Every request
  is announced the same way, when it is made (`notify`: the terminal's "stop requested (page)").
  It also says what the live page's buttons may offer: `started` and `armed`.
- `ButtonEdges`: B0 = start/resume, B1 = stop, on the press (edge), not while held.
- `RunStats`: duration, distance from odometry, states visited, frames seen/skipped/late, loop
  times, frame rate; fed one step at a time.
- `status_of`: one step's live status (a JSON-ready dict) for the terminal and the live page.

Pure except `OperatorPanel` (a lock and a clock callable it is given). Never sleeps.
"""

from __future__ import annotations

import math
import threading
from array import array
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol

from lanewarden.actuation.base import BaseFeedback
from lanewarden.perception.observation import LaneObservation
from lanewarden.supervisor.events import LANE_LOSS_EVENTS, Event, Response, response_of
from lanewarden.supervisor.loop import StepRecord
from lanewarden.wording import counted

#: Kobuki button bits (BaseFeedback.buttons): B0 starts or resumes, B1 stops.
BUTTON_B0 = 0x01
BUTTON_B1 = 0x02
#: New frames the frame rate is measured over.
FPS_WINDOW_FRAMES = 30
#: Steps the live loop time (mean, max) is measured over.
LOOP_WINDOW_STEPS = 30


class Engageable(Protocol):
    def start(self, now: float) -> None: ...
    def resume(self, now: float) -> None: ...
    def operator_stop(self, now: float) -> None: ...


@dataclass(frozen=True)
class OperatorRequest:
    kind: str  # "start", "resume" or "stop"
    source: str  # "key", "button", "page", ...
    time_s: float


def halting_events(events: Iterable[str]) -> set[Event]:
    """The events of a step that halt (and so disarm any engage request made before them)."""
    found = set()
    for name in events:
        try:
            event = Event(name)
        except ValueError:
            continue
        if response_of(event) is Response.HALT:
            found.add(event)
    return found


class OperatorPanel:
    """Thread-safe entry point for operator requests (see the module docstring).

    `notify(request)` is called for every request as it is made (from the requesting thread).
    `auto_resume_after_lane_loss`: the supervisor's setting (a LANE_LOST halt re-arms itself)."""

    def __init__(self, loop: Engageable, clock: Callable[[], float], *,
                 notify: Callable[[OperatorRequest], None] | None = None,
                 auto_resume_after_lane_loss: bool = False) -> None:
        self._loop = loop
        self._clock = clock
        self._notify = notify
        self._auto_resume = auto_resume_after_lane_loss
        self._lock = threading.Lock()
        self._pending: list[OperatorRequest] = []
        self.history: deque[OperatorRequest] = deque(maxlen=20)
        self._started = False
        self._armed = False

    def start(self, source: str) -> None:
        self._queue("start", source)

    def resume(self, source: str) -> None:
        self._queue("resume", source)

    def engage(self, source: str) -> None:
        """Start before the first start, resume after it (the Kobuki's B0)."""
        with self._lock:
            started = self._started or any(r.kind == "start" for r in self._pending)
        self._queue("resume" if started else "start", source)

    def stop(self, source: str) -> None:
        now = self._clock()
        self._loop.operator_stop(now)
        request = OperatorRequest("stop", source, now)
        with self._lock:
            self.history.append(request)
        if self._notify is not None:
            self._notify(request)

    def _queue(self, kind: str, source: str) -> None:
        request = OperatorRequest(kind, source, self._clock())
        with self._lock:
            self._pending.append(request)
        if self._notify is not None:
            self._notify(request)

    @property
    def started(self) -> bool:
        """A start request has been made (delivered or about to be)."""
        with self._lock:
            return self._started or any(r.kind == "start" for r in self._pending)

    @property
    def armed(self) -> bool:
        """A start or resume waits to engage the robot: made since it last halted and not
        undone by a new halt (the supervisor's latch rule), or not delivered yet."""
        with self._lock:
            return self._armed or bool(self._pending)

    def observe(self, state: str, events: Iterable[str]) -> None:
        """After each step (the control thread): engaged, or a halting event in this step
        (which disarms as the supervisor does; a lane-loss halt re-arms itself when
        `auto_resume_after_lane_loss`), ends what `armed` said."""
        if state != "HALT":
            self._armed = False
            return
        halting = halting_events(events)
        if halting:
            self._armed = self._auto_resume and halting <= LANE_LOSS_EVENTS

    def deliver(self, now: float) -> list[OperatorRequest]:
        """Hand queued Start/Resume requests to the loop (the control thread, before a step)."""
        with self._lock:
            pending, self._pending = self._pending, []
            for request in pending:
                self.history.append(request)
                self._started = self._started or request.kind == "start"
            self._armed = self._armed or bool(pending)
        for request in pending:
            if request.kind == "start":
                self._loop.start(now)
            else:
                self._loop.resume(now)
        return pending


class ButtonEdges:
    """Which buttons went down since the last reading (a held button counts once)."""

    def __init__(self) -> None:
        self._previous = 0

    def pressed(self, buttons: int) -> int:
        down = buttons & ~self._previous
        self._previous = buttons
        return down


def apply_buttons(edges: ButtonEdges, feedback: BaseFeedback | None, panel: OperatorPanel) -> None:
    """B1 (stop) wins when both go down together."""
    if feedback is None:
        return
    down = edges.pressed(feedback.buttons)
    if down & BUTTON_B1:
        panel.stop("button B1")
    elif down & BUTTON_B0:
        panel.engage("button B0")


@dataclass
class RunStats:
    """What the final summary and the live status report, accumulated step by step."""

    steps: int = 0
    first_time_s: float | None = None
    last_time_s: float | None = None
    states_visited: list[str] = field(default_factory=list)
    halt_reason: str | None = None
    halt_cause: str | None = None
    state: str = "HALT"
    distance_m: float = 0.0
    frames_seen: int = 0
    frames_skipped: int = 0
    steps_frame_late: int = 0
    loop_overruns: int = 0
    loop_time_s_max: float = 0.0
    loop_time_s_sum: float = 0.0
    last_observation: LaneObservation | None = None
    _last_index: int | None = None
    _last_pose: tuple[float, float] | None = None
    _frame_times: deque[float] = field(default_factory=lambda: deque(maxlen=FPS_WINDOW_FRAMES))
    _loop_times: deque[float] = field(default_factory=lambda: deque(maxlen=LOOP_WINDOW_STEPS))
    loop_times_s: array[float] = field(default_factory=lambda: array("d"))

    def add(self, record: StepRecord, feedback: BaseFeedback | None,
            loop_time_s: float = 0.0) -> None:
        self.steps += 1
        if self.first_time_s is None:
            self.first_time_s = record.time_s
        self.last_time_s = record.time_s
        if record.state == "HALT" and self.state != "HALT":
            self.halt_cause = record.halt_reason  # why it stopped (later steps may add reasons)
        self.state = record.state
        if record.state not in self.states_visited:
            self.states_visited.append(record.state)
        self.halt_reason = record.halt_reason
        index = record.frame_index
        if index is not None and index != self._last_index:
            self.frames_seen += 1
            if self._last_index is not None and index > self._last_index + 1:
                self.frames_skipped += index - self._last_index - 1
            self._last_index = index
            if record.frame_time_s is not None:
                self._frame_times.append(record.frame_time_s)
        self.steps_frame_late += "FRAME_LATE" in record.events
        self.loop_overruns += "LOOP_OVERRUN" in record.events
        self.loop_time_s_max = max(self.loop_time_s_max, loop_time_s)
        self.loop_time_s_sum += loop_time_s
        self._loop_times.append(loop_time_s)
        self.loop_times_s.append(loop_time_s)
        if record.observation is not None:
            self.last_observation = record.observation
        if feedback is not None:
            pose = (feedback.odometry.x_m, feedback.odometry.y_m)
            if self._last_pose is not None:
                self.distance_m += math.dist(pose, self._last_pose)
            self._last_pose = pose

    @property
    def duration_s(self) -> float:
        if self.first_time_s is None or self.last_time_s is None:
            return 0.0
        return self.last_time_s - self.first_time_s

    @property
    def fps(self) -> float | None:
        """Frames per second over the last FPS_WINDOW_FRAMES new frames (capture times)."""
        times = self._frame_times
        if len(times) < 2 or times[-1] <= times[0]:
            return None
        return (len(times) - 1) / (times[-1] - times[0])

    @property
    def loop_time_s_mean(self) -> float:
        return self.loop_time_s_sum / self.steps if self.steps else 0.0

    def loop_time_percentile_s(self, q: float) -> float:
        """The q-th percentile (0-100) of every step's time so far (nearest rank)."""
        if not self.loop_times_s:
            return 0.0
        ordered = sorted(self.loop_times_s)
        return ordered[min(len(ordered) - 1, max(0, math.ceil(q / 100.0 * len(ordered)) - 1))]

    @property
    def recent_loop_time_s(self) -> tuple[float, float]:
        """(mean, max) step time over the last LOOP_WINDOW_STEPS steps."""
        times = self._loop_times
        return (sum(times) / len(times), max(times)) if times else (0.0, 0.0)


def _round(value: float | None, digits: int) -> float | None:
    return None if value is None else round(value, digits)


def base_link(feedback: BaseFeedback | None, now: float, late_s: float, lost_s: float) -> str:
    """"ok", "late" or "lost", by the age of the newest feedback (the watchdog's limits)."""
    if feedback is None or feedback.received_at_s is None:
        return "lost"
    age = now - feedback.received_at_s
    return "ok" if age <= late_s else "late" if age <= lost_s else "lost"


def status_of(record: StepRecord, stats: RunStats, feedback: BaseFeedback | None, *,
              link: str, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """The live status after one step (JSON-ready). Perception's numbers are those of the newest
    observation (most steps have no new frame); the loop time is over the last steps."""
    obs = stats.last_observation
    loop_mean, loop_max = stats.recent_loop_time_s
    return {
        "time_s": round(stats.duration_s, 3),
        "step": stats.steps,
        "state": record.state,
        "halt_reason": record.halt_reason,
        "events": list(record.events),
        "frame_index": record.frame_index,
        "confidence": None if obs is None else round(obs.confidence, 3),
        "components": {} if obs is None else {k: round(v, 3) for k, v in obs.components.items()},
        "slope_sum": None if obs is None else _round(obs.slope_sum, 3),
        "filtered_slope_sum": _round(record.filtered_slope_sum, 3),
        "command": {"linear_m_s": round(record.command.linear_m_s, 3),
                    "angular_rad_s": round(record.command.angular_rad_s, 3)},
        "fps": _round(stats.fps, 1),
        "loop_ms": round(loop_mean * 1000.0, 1),
        "loop_ms_max": round(loop_max * 1000.0, 1),
        "base_link": link,
        "battery_v": None if feedback is None else _round(feedback.battery_v, 1),
        "distance_m": round(stats.distance_m, 3),
        "frames_skipped": stats.frames_skipped,
        "frames_late": stats.steps_frame_late,
        **(extra or {}),
    }


def summary_lines(stats: RunStats, *, stopped: str | None = None,
                  recording: str | None = None, frames_dropped_recording: int = 0,
                  view_dropped: int | None = None) -> list[str]:
    """The operator's summary printed when a run ends (before the runner's one line saying why it
    ended). `stopped`: what stopped the robot, from the run's end reason
    (`run_outcome.EndReason.stop_line`; default: the reason it entered its last HALT with, else
    the last step's)."""
    reason = stats.halt_cause or (stats.halt_reason if stats.state == "HALT" else None)
    first = stopped or (f"halted: {reason}" if reason else "never halted")
    lines = [
        f"  {first}",
        f"  distance (odometry) {stats.distance_m:.2f} m; states visited: "
        f"{', '.join(stats.states_visited) or 'none'}",
        f"  frames: {stats.frames_seen} seen, {stats.frames_skipped} skipped by the loop, "
        f"{stats.steps_frame_late} steps with a late frame; loop time mean "
        f"{stats.loop_time_s_mean * 1000:.1f} ms, max {stats.loop_time_s_max * 1000:.1f} ms",
    ]
    if recording is not None:
        dropped = (f", {counted(frames_dropped_recording, 'frame')} dropped (replay cannot be "
                   "exact)" if frames_dropped_recording else "")
        lines.append(f"  recorded in {recording}{dropped}")
    if view_dropped:
        lines.append(f"  live view: {view_dropped} view frames dropped (the loop never waits)")
    return lines
