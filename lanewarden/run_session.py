"""Everything around one `lanewarden run` that the operator sees: the recording, the live page,
the terminal's status line and keys, the Kobuki's buttons, and the final summary.

The runner builds the loop's parts, lets `RunSession.wrap` put the recording taps around them,
calls `before_step(now)` before each step and hands the loop `after_step` as its record callback.
All of it is kept off the control loop's path: `after_step` only updates counters and swaps
references into queues and latest-only slots; drawing, encoding, disk and terminal writes happen on
their own threads (see recording.py, live_view.py, terminal.py).
"""

from __future__ import annotations

import datetime as dt
import sys
import time
from array import array
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from lanewarden.actuation.base import Base
from lanewarden.assembly import ControlStack, DetectionTap
from lanewarden.config import LanewardenConfig
from lanewarden.live_view import LiveView, ViewFrame, parse_view_address
from lanewarden.operator import (
    ButtonEdges,
    Engageable,
    OperatorPanel,
    RunStats,
    apply_buttons,
    base_link,
    status_of,
    summary_lines,
)
from lanewarden.recording import (
    InputTap,
    RecordingSummary,
    RunRecorder,
    create_run_folder,
    default_run_folder,
)
from lanewarden.run_mcap import PERCEPTION_INPUT
from lanewarden.run_outcome import EndReason, LoopEnd
from lanewarden.scenarios.before_halt import RecentSteps, before_halt, halt_line
from lanewarden.supervisor.loop import Detector, FrameSource, Gate, StepRecord
from lanewarden.terminal import KEY_HELP, KeyReader, StatusPrinter, key_action

DEFAULT_RUNS_ROOT = Path("runs")


def _summary_ms(values: array[float]) -> dict[str, float]:
    ordered = sorted(values) or [0.0]
    return {"mean": round(sum(ordered) / len(ordered) * 1000, 3),
            "p50": round(ordered[len(ordered) // 2] * 1000, 3),
            "p95": round(ordered[min(len(ordered) - 1, int(len(ordered) * 0.95))] * 1000, 3)}


@dataclass(frozen=True)
class SessionOptions:
    base_kind: str = "kobuki"
    record: Path | None = None  # None: runs/<UTC time>/
    record_image: str = PERCEPTION_INPUT  # which frames: lanewarden.run_mcap.IMAGE_KINDS
    view: str | None = None  # [HOST:]PORT
    keys: bool = True
    meta: dict[str, Any] = field(default_factory=dict)
    calibration_path: Path | None = None


class RunSession:
    """One run's operator side. Open before the base (bad --record/--view fail first), close
    last."""

    def __init__(self, options: SessionOptions, config: LanewardenConfig,
                 clock: Callable[[], float], out: TextIO | None = None) -> None:
        self.options = options
        self.config = config
        self._clock = clock
        self._out = out if out is not None else sys.stdout
        self.tap = InputTap()
        self.stats = RunStats()
        #: the steps before each halt, for the summary's "before the halt" line
        self.recent = RecentSteps()
        self._buttons = ButtonEdges()
        self._detections: DetectionTap | None = None
        self._stack: ControlStack | None = None
        self.panel: OperatorPanel | None = None
        self._step_started_s: float | None = None
        self._step_cpu_started_s = 0.0
        self._loop_time_s = 0.0
        #: CPU time of the control thread per step (not slowed by other processes: what the
        #: live-view benchmark compares).
        self.step_cpu_s: array[float] = array("d")
        self.view: LiveView | None = None
        self.printer = StatusPrinter(self._out)
        try:
            if options.view is not None:  # a bad or busy --view fails before anything is written
                host, port = parse_view_address(options.view)
                sup = config.supervisor
                self.view = LiveView(host, port, self, log=self.printer.message, plot={
                    "turn_enter_slope_sum": sup.turn_enter_slope_sum,
                    "turn_exit_slope_sum": sup.turn_exit_slope_sum})
        except BaseException:
            self.printer.close()
            raise
        try:
            folder = options.record or default_run_folder(DEFAULT_RUNS_ROOT,
                                                          dt.datetime.now(dt.UTC))
            self.folder = create_run_folder(folder)
            started = dt.datetime.now(dt.UTC)
            self.recorder = RunRecorder(self.folder, image_kind=options.record_image,
                                        epoch_offset_s=started.timestamp() - clock())
            self.recorder.write_header(
                {**options.meta, "base": options.base_kind,
                 "started_utc": started.isoformat(timespec="seconds"), "argv": sys.argv},
                config.model_dump(mode="json"), options.calibration_path, clock())
        except BaseException:
            if self.view is not None:
                self.view.close()
            self.printer.close()
            if hasattr(self, "recorder"):
                self.recorder.close({"end_reason": "could not start", "exit_code": None})
            raise
        self.keys = KeyReader(self._on_key)
        self.recording: RecordingSummary | None = None
        #: the newest status; at the end, the last one published (with `end_reason`)
        self._status: dict[str, Any] = {"state": "HALT", "end_reason": None}
        self.final_status: dict[str, Any] = {}
        self._recording_said = (False, False)  # (a problem said, dropped frames said)

    # ---- building the loop --------------------------------------------------------------------
    def wrap(self, frames: FrameSource, stack: ControlStack,
             base: Base) -> tuple[FrameSource, Detector, Gate, Base]:
        """The loop's parts (the stack's detector and safety gate, built with `debug_tap=True`
        for the live page's overlay) with the recording taps around them (same behaviour)."""
        self._stack = stack
        self._detections = stack.tap
        self.recorder.prepare_with(stack.detector)  # it records what this detector consumes
        # The gate's tap hands every step to the gate and returns its output unchanged.
        gate = self.tap.gate(stack.gate)
        return (self.tap.frames(frames), stack.tap or stack.detector, gate, self.tap.base(base))

    def attach(self, loop: Engageable) -> OperatorPanel:
        """Connect the operator's inputs (keys, buttons, page) to the loop's requests."""
        self.panel = OperatorPanel(
            loop, self._clock,
            notify=lambda request: self.printer.message(
                f"{request.kind} requested ({request.source})"),
            auto_resume_after_lane_loss=self.config.supervisor.auto_resume_after_lane_loss)
        if self.view is not None:
            self.printer.message(f"live view: {self.view.url}")
            if self.view.token is not None:
                self.printer.message(
                    f"live view: not bound to loopback: the page needs the token {self.view.token}"
                    " (in the address above; anyone with it can start the robot)")
        if self.options.keys:
            self.keys.__enter__()
            if self.keys.active:
                self.printer.message(KEY_HELP)
        return self.panel

    # ---- each step ----------------------------------------------------------------------------
    def before_step(self, now: float) -> None:
        self._step_started_s = now
        self._step_cpu_started_s = time.thread_time()
        if self.panel is not None:
            self.panel.deliver(now)  # each request was announced when it was made

    def after_step(self, record: StepRecord) -> None:
        """The loop's record callback (runs inside the step: cheap work only)."""
        now = self._clock()
        self.step_cpu_s.append(time.thread_time() - self._step_cpu_started_s)
        started = self._step_started_s if self._step_started_s is not None else record.time_s
        self._loop_time_s = max(0.0, now - started)
        step_input, new_frame = self.tap.take(record.time_s)
        feedback = self.tap.latest_feedback
        self.stats.add(record, feedback, self._loop_time_s)
        self.recent.observe(record)
        self.recorder.record(record, step_input, new_frame)
        self._say_recording_trouble()
        if self.panel is not None:
            self.panel.observe(record.state, record.events)
            apply_buttons(self._buttons, feedback, self.panel)
        sup = self.config.supervisor
        status = status_of(
            record, self.stats, feedback,
            link=base_link(feedback, record.time_s, sup.base_feedback_late_s,
                           sup.base_link_timeout_s),
            extra={"base": self.options.base_kind, "would_send": self.options.base_kind == "none",
                   "recording": str(self.folder), "end_reason": None,
                   "recording_frames_dropped": len(self.recorder.summary.frames_dropped),
                   "recording_stopped": self.recorder.summary.problem,
                   "started": self.panel is not None and self.panel.started,
                   "armed": self.panel is not None and self.panel.armed})
        self._status = status
        self.printer.publish(status)
        if self.view is not None:
            frame = None
            if new_frame is not None:
                tap = self._detections.last if self._detections is not None else None
                detection = tap if tap is not None and tap[0] == new_frame.index else None
                frame = ViewFrame(
                    image=new_frame.image,
                    observation=None if detection is None else detection[1],
                    debug=None if detection is None else detection[2],
                    decision="none" if detection is None or self._stack is None
                    else self._stack.decide(detection[1]),
                    state=record.state, reason=record.halt_reason)
            self.view.publish(status, frame)

    def _say_recording_trouble(self) -> None:
        """Once each: the recording stopped (the run goes on), or it dropped frames."""
        problem_said, drops_said = self._recording_said
        summary = self.recorder.summary
        if not problem_said and summary.problem is not None:
            self.printer.warning(f"warning: the recording stopped: {summary.problem}; the run "
                                 "goes on unrecorded")
            problem_said = True
        if not drops_said and summary.frames_dropped:
            self.printer.message("warning: the recording is not keeping up and drops frames "
                                 "(counted in the summary): this run cannot be replayed exactly")
            drops_said = True
        self._recording_said = (problem_said, drops_said)

    # ---- the live page's requests (before attach there is no loop: they do nothing) ---------
    def start(self, source: str) -> None:
        if self.panel is not None:
            self.panel.start(source)

    def resume(self, source: str) -> None:
        if self.panel is not None:
            self.panel.resume(source)

    def stop(self, source: str) -> None:
        if self.panel is not None:
            self.panel.stop(source)

    def _on_key(self, key: str) -> None:
        action = key_action(key)
        if action is None or self.panel is None:
            return
        if action == "stop":
            self.panel.stop("key")
        elif action == "start":
            self.panel.start("key")
        else:
            self.panel.resume("key")

    def suspending(self) -> None:
        """Before the process suspends itself (Ctrl-Z): the terminal as the shell expects it."""
        self.keys.pause()

    def resumed(self) -> None:
        """After SIGCONT: keys in cbreak mode again."""
        self.keys.resume()

    # ---- the end ------------------------------------------------------------------------------
    def close(self, end: EndReason, loop_end: LoopEnd, exit_code: int | None) -> list[str]:
        """Publish the last status (with the end reason) to the terminal and the live page, stop
        the keys, the page and the status line, finish the recording (summary.json: the end
        reason and what ended the loop, so a replay decides the same); the summary lines."""
        # the run's end, not its closing stop: the last step published is that stop's, and
        # the page had shown OPERATOR_STOP as the reason of a run whose duration was reached
        # (an instructor's review); the robot is stopped now, whatever state it ended in
        self.final_status = {**self._status, "state": "HALT",
                             "halt_reason": end.halt_reason or f"the run ended: {end.text}",
                             "events": [], "end_reason": end.text, "exit_code": exit_code}
        self.printer.publish(self.final_status)
        if self.view is not None:
            self.view.publish(self.final_status, None)
        self.keys.__exit__(None, None, None)
        view_dropped = None
        if self.view is not None:
            view_dropped = self.view.frames_dropped
            self.view.close()
        self.printer.close()
        self.recording = self.recorder.close({
            "end_reason": end.text, "end": end.as_json(), "ended_by": loop_end.as_json(),
            "exit_code": exit_code,
            "duration_s": round(self.stats.duration_s, 3),
            "final_state": end.state,
            "halt_reason": end.halt_reason,
            "states_visited": self.stats.states_visited,
            "distance_m": round(self.stats.distance_m, 4),
            "loop_time_ms": {
                "mean": round(self.stats.loop_time_s_mean * 1000, 3),
                "p50": round(self.stats.loop_time_percentile_s(50) * 1000, 3),
                "p95": round(self.stats.loop_time_percentile_s(95) * 1000, 3),
                "max": round(self.stats.loop_time_s_max * 1000, 3)},
            "loop_cpu_ms": _summary_ms(self.step_cpu_s),
            "frames_seen": self.stats.frames_seen,
            "frames_skipped": self.stats.frames_skipped,
            "view_frames_dropped": view_dropped})
        lines = summary_lines(self.stats, stopped=end.stop_line, recording=str(self.folder),
                              frames_dropped_recording=len(self.recording.frames_dropped),
                              view_dropped=view_dropped)
        window = self.recent.before_halt(loop_end.steps) if end.safety_stop else None
        # the run's own halt (not the runner's closing stop after the loop's end)
        if window and (line := halt_line(before_halt(
                window, len(window) - 1, self.config.supervisor,
                self.config.perception.edges.max_abs_slope))):
            lines.insert(1, line)
        if self.recording.problem is not None:
            lines.append(f"  the recording stopped early: {self.recording.problem}")
        lines += [f"  not written: {error}" for error in self.recording.write_errors
                  if error.startswith("summary.json")]
        return lines
