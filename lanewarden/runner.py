"""The robot runner: camera -> perception -> supervisor -> Kobuki, on the monotonic clock.

The only place in Lanewarden that reads the wall (monotonic) clock for control and the only loop
that sleeps. Everything it drives is the same stack (lanewarden/assembly.py: detector, controller,
SafetyGate, `ControlLoop`) the simulator steps on a fake clock.
Order of start-up is chosen so nothing moves until every check passed: config, calibration, camera
(and its image size against the calibration), then the base, then an explicit start. On any exit
(end of duration or clip, Ctrl-C, SIGTERM, SIGQUIT, SIGHUP, an error) the loop is told to stop,
the base is closed (which sends stop and leaves the dead-man holding it), and the log is flushed.
Ctrl-Z (SIGTSTP) stops the robot first (the dead-man holds the stop), then suspends the process;
after SIGCONT the supervisor stays latched in HALT (OPERATOR_STOP) until an explicit start or
resume. The run also ends by itself on a failure it cannot recover from: the base link or the
dead-man lost, the dead-man tripped, a live camera gone. `RunSummary.outcome` says which
(`run_outcome`: a normal end, exit 0, or a safety stop, exit 3).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

from lanewarden.actuation.deadman_logic import DeadmanMode
from lanewarden.actuation.kobuki_base import KobukiBase
from lanewarden.assembly import build_stack
from lanewarden.camera_source import CameraFrameSource, open_camera, replay_rate_fps
from lanewarden.config import LanewardenConfig
from lanewarden.perception.calibration import load_calibration, require_usable_calibration
from lanewarden.run_outcome import RunOutcome, RunWatch
from lanewarden.stop_signals import signal_requests, suspend
from lanewarden.supervisor.clock import MonotonicClock
from lanewarden.supervisor.controllers import controller_factory
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.loop import StepRecord
from lanewarden.supervisor.recorder import JsonlRecorder

FIRST_FRAME_TIMEOUT_S = 3.0


@dataclass(frozen=True)
class RunSummary:
    """`final_state`/`halt_reason`: the supervisor's state and halt reason just before the
    runner's own closing stop. `outcome`: why the run ended and its exit code."""

    steps: int
    duration_s: float
    final_state: str
    halt_reason: str | None
    log_path: Path
    outcome: RunOutcome = RunOutcome("not run")


def _ending_fault(base: KobukiBase, frames: CameraFrameSource, camera: str,
                  recorded: bool) -> str | None:
    """A failure that ends the run by itself (one line, its kind first), or None."""
    lost = base.link_lost
    if lost is not None:
        return f"BASE_LINK_LOST: {lost}"
    if base.deadman_mode is DeadmanMode.TRIPPED:
        return f"DEADMAN_TRIPPED: the dead-man stopped the base ({base.deadman_reason})"
    if frames.error is not None and not recorded:
        return f"CAMERA_LOST: --camera {camera}: {frames.error}"
    return None


def run_robot(
    config: LanewardenConfig,
    *,
    camera: str,
    port: str | None,
    calibration_path: str | None,
    controller_name: str,
    log_path: Path,
    duration_s: float | None,
) -> RunSummary:
    clock = MonotonicClock()
    controller_factory(controller_name)  # an unknown name fails here, before the camera opens
    calibration = load_calibration(calibration_path) if calibration_path else None

    max_pixels = config.perception.max_image_pixels
    capture = open_camera(camera, max_pixels)
    period = config.supervisor.camera_period_s
    replay_fps = replay_rate_fps(camera, capture, 1.0 / period)
    frames = CameraFrameSource(capture, clock.now, replay_fps, max_pixels=max_pixels)
    try:
        deadline = clock.now() + FIRST_FRAME_TIMEOUT_S
        first = frames.read(clock.now())
        while first is None and clock.now() < deadline and frames.error is None:
            time.sleep(0.02)
            first = frames.read(clock.now())
        if first is None:
            raise SupervisorError(
                f"--camera {camera}: no frame within {FIRST_FRAME_TIMEOUT_S:.0f} s "
                f"({frames.error or 'the camera opened but delivered nothing'})"
            )
        height, width = first.image.shape[:2]
        if calibration is not None:
            require_usable_calibration(calibration, (width, height), config.calibration,
                                       f"--calibration {calibration_path}")
        stack = build_stack(config, controller=controller_name, calibration=calibration)

        last: StepRecord | None = None
        steps = 0
        watch = RunWatch()
        fault: str | None = None
        clip_ended = False
        ended_by = "an error"
        with (
            KobukiBase.open(port, clock=clock.now, config=config.actuation) as base,
            JsonlRecorder(log_path) as recorder,
            signal_requests() as requests,
        ):
            warning = base.priority_warning()
            if warning is not None:
                print(f"lanewarden: warning: {warning}", file=sys.stderr, flush=True)
            loop = stack.connect(frames, base, recorder)
            started = clock.now()
            loop.start(started)
            next_tick = started
            rearm_after_suspend = False
            try:
                while True:
                    if requests.stop is not None:
                        ended_by = f"operator stop ({requests.stop.name})"
                        break
                    now = clock.now()
                    if requests.suspend:
                        requests.suspend = False
                        loop.operator_stop(now)  # stop first; HALT latches at the next step
                        base.hold_stopped(now)  # the dead-man holds stop while we are stopped
                        suspend()
                        rearm_after_suspend = True
                        continue
                    if duration_s is not None and now - started >= duration_s:
                        ended_by = f"--duration {duration_s:g} s reached"
                        break
                    last = loop.step(now)
                    steps += 1
                    watch.observe(last.state, last.halt_reason, last.time_s, last.frame_time_s)
                    fault = _ending_fault(base, frames, camera, replay_fps is not None)
                    if fault is not None:
                        break
                    if rearm_after_suspend and last.state == "HALT":
                        base.rearm(now)  # still latched: only an explicit start/resume moves
                        rearm_after_suspend = False
                    if frames.error is not None:  # a recorded clip ran out
                        ended_by, clip_ended = "end of the clip", True
                        break
                    next_tick += period
                    delay = next_tick - clock.now()
                    if delay > 0:
                        time.sleep(delay)
                    else:
                        next_tick = clock.now()  # overrun: the watchdog sees it; don't burst
            finally:
                final_state = last.state if last else "HALT"
                final_reason = last.halt_reason if last else None
                now = clock.now()
                loop.operator_stop(now)
                loop.step(now)
        return RunSummary(
            steps=steps,
            duration_s=clock.now() - started,
            final_state=final_state,
            halt_reason=final_reason,
            log_path=log_path,
            outcome=watch.outcome(ended_by, fault=fault, clip_ended=clip_ended),
        )
    finally:
        frames.close()
