"""The robot runner: camera -> perception -> supervisor -> base, on the monotonic clock.

Its `Ticker` (lanewarden/ticker.py, shared with `base drive`) is where control code reads the
monotonic clock, and the only loop that sleeps between steps. Everything it drives is the same
stack (lanewarden/assembly.py: detector, controller, SafetyGate, `ControlLoop`) the simulator
steps on a fake clock.
Order of start-up is chosen so nothing moves until every check passed: config, calibration, camera
(and its image size against the calibration), the recording folder and the live view's port, then
the base (`--base kobuki|sim|none`), then an explicit start. On any exit (end of duration or clip,
Ctrl-C, SIGTERM, SIGQUIT, SIGHUP, an error) the loop is told to stop, a last step sends the stop,
the base is closed (which sends stop and leaves the dead-man holding it), and the recording is
finished (lanewarden/run_session.py: recording, live page, status line, keys, buttons).
Ctrl-Z (SIGTSTP) stops the robot first (the dead-man holds the stop), then suspends the process;
after SIGCONT the supervisor stays latched in HALT (OPERATOR_STOP) until an explicit start or
resume. The operator's start and resume also release the dead-man's own hazard latch (bumper,
cliff, wheel drop, stale feedback: the gate's DEADMAN_LATCHED) once the hazard has cleared; that
latch halts the run like a bumper does, it does not end it. The run also ends by itself on a
failure it cannot recover from: the base link or the dead-man lost, the dead-man tripped, a live
camera gone. `RunSummary.end` says why it ended (`run_outcome.end_reason`, the one place that
decides: a normal end, exit 0, or a safety stop, exit 3).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from lanewarden.actuation.base import Base
from lanewarden.actuation.deadman_logic import DeadmanMode
from lanewarden.actuation.errors import ActuationError
from lanewarden.actuation.kobuki_base import KobukiBase
from lanewarden.assembly import build_stack
from lanewarden.bases import open_base
from lanewarden.camera_source import (
    CameraFrameSource,
    CameraLost,
    open_camera,
    replay_rate_fps,
    require_camera_view,
)
from lanewarden.config import LanewardenConfig, narrow_lane_warning
from lanewarden.errors import UsageError
from lanewarden.perception.calibration import (
    CameraCalibration,
    load_calibration,
    require_usable_calibration,
)
from lanewarden.perception.detector import too_small
from lanewarden.perception.ground import default_pose
from lanewarden.recording import RUN_MCAP
from lanewarden.run_mcap import PERCEPTION_INPUT
from lanewarden.run_outcome import EndReason, LoopEnd, LoopEndKind, RunWatch, end_reason
from lanewarden.run_session import RunSession, SessionOptions
from lanewarden.scenarios.camera_clip import clip_calibration_hint
from lanewarden.stop_signals import signal_requests, suspend
from lanewarden.supervisor.controllers import controller_factory
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.loop import ControlLoop, StepRecord
from lanewarden.ticker import Ticker

FIRST_FRAME_TIMEOUT_S = 3.0


@dataclass(frozen=True)
class RunSummary:
    """`end`: why the run ended and its exit code (`run_outcome.end_reason`). `lines`: the
    operator's summary (what stopped the robot, distance, states visited, frames, recording).
    `final_status`: the last status published to the terminal and the live page (with the end
    reason as `end_reason`)."""

    steps: int
    duration_s: float
    log_path: Path
    end: EndReason
    lines: tuple[str, ...] = ()
    final_status: dict[str, object] = field(default_factory=dict)


def _first_frame(frames: CameraFrameSource, clock: Ticker, camera: str) -> np.ndarray:
    """The camera's first frame, once it arrived. A camera that delivered frames and failed
    before the run began still delivered: its loss is the loop's to report, as a safety stop
    (CAMERA_LOST) with the base open, like a loss a second later."""
    deadline = clock.now() + FIRST_FRAME_TIMEOUT_S
    problem = "the camera opened but delivered nothing"
    while clock.now() < deadline:
        try:
            first = frames.read(clock.now())
        except CameraLost as exc:
            delivered = frames.latest
            if delivered is not None:
                return delivered.image
            problem = str(exc)
            break
        if first is not None:
            return first.image
        time.sleep(0.02)
    raise SupervisorError(f"--camera {camera}: no frame within {FIRST_FRAME_TIMEOUT_S:.0f} s "
                          f"({problem})")


class OperatorEngage:
    """The operator's start and resume as the panel delivers them (on the control thread, before
    a step): first the base's own safety latch is released where it has one (the Kobuki's
    dead-man: `KobukiBase.resume`, called from nowhere else, so that latch only ever clears on an
    operator's explicit request; it waits, bounded, for the dead-man's answer, so the step after
    it sees the latch gone), then the loop is asked. Stop goes straight to the loop."""

    def __init__(self, loop: ControlLoop, base: Base) -> None:
        self._loop = loop
        self._base = base

    def start(self, now: float) -> None:
        self._release_base_latch(now)
        self._loop.start(now)

    def resume(self, now: float) -> None:
        self._release_base_latch(now)
        self._loop.resume(now)

    def operator_stop(self, now: float) -> None:
        self._loop.operator_stop(now)

    def _release_base_latch(self, now: float) -> None:
        if isinstance(self._base, KobukiBase):
            try:
                self._base.resume(now)
            except ActuationError:
                pass  # a lost link: the loop's next step reports it (BASE_LINK_LOST)


def _ending_fault(base: Base, frames: CameraFrameSource, camera: str,
                  recorded: bool) -> str | None:
    """A failure that ends the run by itself (one line, its kind first), or None. Only the
    Kobuki has a link and a dead-man to lose."""
    if isinstance(base, KobukiBase):
        lost = base.link_lost
        if lost is not None:
            return f"BASE_LINK_LOST: {lost}"
        if base.deadman_mode is DeadmanMode.TRIPPED:
            return f"DEADMAN_TRIPPED: the dead-man stopped the base ({base.deadman_reason})"
    # A recorded clip that ran out ends the run (the caller's CLIP end); one that failed (a frame
    # over the pixel limit, an unreadable file) is a lost camera like a live one's failure.
    if frames.error is not None and not (recorded and frames.ended):
        return f"CAMERA_LOST: --camera {camera}: {frames.error}"
    return None


def _closed_link_end(base: KobukiBase, loop_end: LoopEnd) -> LoopEnd:
    """What ended the loop, once the base is closed: where no stop the control side had to
    write itself got through (its port gone, or a device that stopped reading), the base may
    still drive, and whatever ended the loop the run ends as a failure saying so (it had ended
    'operator stop' with exit 0, or 'halted', while the base drove its last command); a run
    ended by BASE_LINK_LOST gets the link's last word (whether the stop went out)."""
    if (failed := base.stop_failed) is not None:
        return LoopEnd(LoopEndKind.FAILURE, f"BASE_LINK_LOST: {failed}", loop_end.steps)
    if (loop_end.kind is LoopEndKind.FAILURE and loop_end.text.startswith("BASE_LINK_LOST: ")
            and base.link_lost):
        return replace(loop_end, text=f"BASE_LINK_LOST: {base.link_lost}")
    return loop_end


#: The flag that lets a real base drive on an assumed camera (`assumed_camera`).
ASSUME_CAMERA_FLAG = "--assume-camera"


def assumed_camera(calibration_path: str | None,
                   calibration: CameraCalibration | None) -> str | None:
    """What perception would assume about the camera, in one clause, or None when the
    calibration describes it whole (its lens and its ground pose): with no calibration the
    simulator's default camera, with one that has no ground pose (`lanewarden calibrate`
    without `calibrate ground`) the simulator's mount. Either way tape and seam widths are
    measured in millimetres through a camera that may not be yours, so a lane can be seen where
    there is none (`run` refuses a real base on it: `refuse_assumed_camera`)."""
    mount = default_pose().describe()
    if calibration is None:  # (the loaded calibration decides, never the path alone)
        return (f"no --calibration: perception judges these frames as if from the simulator's "
                f"default camera (no lens distortion, {mount})")
    if calibration.ground is None:
        return (f"--calibration {calibration_path} has no ground pose (`lanewarden calibrate "
                f"ground` was not run): perception assumes the simulator's mount ({mount})")
    return None


def refuse_assumed_camera(base_kind: str, camera: str, calibration_path: str | None,
                          calibration: CameraCalibration | None, assume: bool) -> None:
    """The robot does not drive on an assumed camera (`assumed_camera`) unless the user says so
    (`--assume-camera`): a UsageError for `--base kobuki`; the bench bases (sim, none) only get
    `start_warnings`' warning. A new user's run of a `lane-ends` clip on the Kobuki stand-in with
    no calibration drove to the clip's end, where with its calibration it halted at the tape's
    end."""
    said = assumed_camera(calibration_path, calibration)
    if said is None or assume or base_kind != "kobuki":
        return
    fix = ("--calibration FILE from `lanewarden calibrate`, then `lanewarden calibrate ground`"
           if calibration is None else
           f"its ground pose (`lanewarden calibrate ground --calibration {calibration_path} "
           "...`)")
    raise UsageError(f"--base kobuki: {said}; through another lens or mount it can see a lane "
                     f"where there is none and drive on; expected {fix}, or "
                     f"{ASSUME_CAMERA_FLAG} to drive on the assumed camera anyway"
                     f"{clip_calibration_hint(camera) if calibration is None else ''}")


def assume_camera_note(base_kind: str, calibration_path: str | None,
                       calibration: CameraCalibration | None, assume: bool) -> str | None:
    """What `--assume-camera` did not do, when it changes nothing (None otherwise): on a bench
    base nothing is refused anyway, and a calibration with its ground pose assumes nothing (a
    reviewer: the flag was accepted there without a word)."""
    if not assume:
        return None
    if base_kind != "kobuki":
        return (f"{ASSUME_CAMERA_FLAG} changes nothing with --base {base_kind}: only the robot "
                "(--base kobuki) is refused an assumed camera")
    if assumed_camera(calibration_path, calibration) is None:
        return (f"{ASSUME_CAMERA_FLAG} changes nothing: --calibration {calibration_path} has its "
                "lens and its ground pose, nothing is assumed")
    return None


def start_warnings(camera: str, calibration_path: str | None,
                   calibration: CameraCalibration | None, controller_name: str,
                   config: LanewardenConfig | None = None) -> list[str]:
    """What `run` says at start-up, before the base opens, about a run that may not stop where
    a user expects: no calibration (perception then judges the frames as the simulator's default
    camera's; a lens it does not undistort can show a lane where there is none: a clip of
    `lane-ends` through a distorted lens, run without its calibration, drove to the clip's end
    at confidence 0.89 where with it the run halted at the tape's end), naming a sim clip's own
    calibration beside `--camera` when there is one; and the lecture's controller, which never
    halts on lane loss; and a lane with little room to drift (`config.narrow_lane_warning`)."""
    warnings = []
    said = assumed_camera(calibration_path, calibration)
    if said is not None and calibration is not None:
        warnings.append(f"{said}; with another height or pitch it measures tapes and seams "
                        "wrong and can see a lane where there is none (run lanewarden "
                        "calibrate ground)")
    elif said is not None:
        warnings.append(f"{said}; through another lens or mount it can see a lane where there "
                        "is none and drive on (calibrate yours: lanewarden calibrate, then "
                        f"lanewarden calibrate ground){clip_calibration_hint(camera)}")
    if config is not None and (narrow := narrow_lane_warning(config)):
        warnings.append(narrow)
    if controller_name == "lecture":
        warnings.append("--controller lecture: the lecture's baseline never halts on lane loss "
                        "(it keeps its last turn and follows floor seams); only the operator's "
                        "stop and the physical hazards stop it: run it on a safe, enclosed track "
                        "only")
    return warnings


def run_robot(
    config: LanewardenConfig,
    *,
    camera: str,
    port: str | None,
    calibration_path: str | None,
    controller_name: str,
    duration_s: float | None,
    base_kind: str = "kobuki",
    record: Path | None = None,
    record_image: str = PERCEPTION_INPUT,
    view: str | None = None,
    meta: dict[str, object] | None = None,
    assume_camera: bool = False,
) -> RunSummary:
    clock = Ticker(config.supervisor.camera_period_s)
    controller_factory(controller_name)  # an unknown name fails here, before the camera opens
    calibration = load_calibration(calibration_path) if calibration_path else None

    max_pixels = config.perception.max_image_pixels
    capture = open_camera(camera, max_pixels)
    replay_fps = replay_rate_fps(camera, capture, 1.0 / clock.period_s)
    frames = CameraFrameSource(capture, clock.now, replay_fps, max_pixels=max_pixels)
    try:
        first = _first_frame(frames, clock, camera)
        height, width = first.shape[:2]
        if why := too_small(width, height):  # before the detector is set up for that size
            raise UsageError(f"--camera {camera}: its first frame: {why}")
        if replay_fps is not None:  # a file: a run's own video is not a camera's view
            require_camera_view(first, f"--camera {camera}")
        if calibration is not None:
            require_usable_calibration(calibration, (width, height), config.calibration,
                                       f"--calibration {calibration_path}", "refusing to engage")
        # after the camera's and the calibration's own checks, before anything can move
        refuse_assumed_camera(base_kind, camera, calibration_path, calibration, assume_camera)
        stack = build_stack(config, controller=controller_name, calibration=calibration,
                            debug_tap=True,  # the live page draws the detection's overlay
                            image_size=(width, height))
        print(stack.detector.describe_ground(calibration_path), flush=True)  # stdout: status
        for said in start_warnings(camera, calibration_path, calibration, controller_name,
                                   config):
            print(f"warning: {said}", flush=True)  # beside the ground model's line it qualifies
        if note := assume_camera_note(base_kind, calibration_path, calibration, assume_camera):
            print(f"note: {note}", flush=True)

        session = RunSession(
            SessionOptions(base_kind=base_kind, record=record, record_image=record_image,
                           view=view, calibration_path=Path(calibration_path)
                           if calibration_path else None,
                           meta={"camera": camera, "controller": controller_name,
                                 "image_size": [width, height], **(meta or {})}),
            config, clock.now)
        last: StepRecord | None = None
        steps = 0
        watch = RunWatch()
        loop_end = LoopEnd(LoopEndKind.ERROR, "an error")
        started = clock.now()
        try:
            with (
                open_base(base_kind, port=port, config=config.actuation, clock=clock.now) as base,
                signal_requests() as requests,
            ):
                warning = base.priority_warning() if isinstance(base, KobukiBase) else None
                if warning is not None:
                    print(f"lanewarden: warning: {warning}", file=sys.stderr, flush=True)
                loop = ControlLoop(*session.wrap(frames, stack, base), record=session.after_step)
                panel = session.attach(OperatorEngage(loop, base))
                frames.play()
                started = clock.restart()
                panel.start("the run command")  # the explicit start; it only arms
                rearm_after_suspend = False
                try:
                    while True:
                        if requests.stop is not None:
                            loop_end = LoopEnd(LoopEndKind.OPERATOR,
                                               f"operator stop ({requests.stop.name})")
                            break
                        now = clock.now()
                        if requests.suspend:
                            requests.suspend = False
                            loop.operator_stop(now)  # stop first; HALT latches at the next step
                            if isinstance(base, KobukiBase):
                                base.hold_stopped(now)  # the dead-man holds stop meanwhile
                                rearm_after_suspend = True
                            session.suspending()
                            suspend()
                            session.resumed()
                            continue
                        if duration_s is not None and now - started >= duration_s:
                            loop_end = LoopEnd(LoopEndKind.DURATION,
                                               f"--duration {duration_s:g} s reached")
                            break
                        session.before_step(now)  # may wait for the dead-man (a resume)
                        now = clock.now()
                        last = loop.step(now)
                        steps += 1
                        watch.observe(last.state, last.halt_reason, last.time_s,
                                      last.frame_time_s)
                        fault = _ending_fault(base, frames, camera, replay_fps is not None)
                        if fault is not None:
                            loop_end = LoopEnd(LoopEndKind.FAILURE, fault)
                            break
                        if rearm_after_suspend and last.state == "HALT":
                            assert isinstance(base, KobukiBase)
                            base.rearm(now)  # still latched: only an explicit start/resume moves
                            rearm_after_suspend = False
                        if frames.end_seen:  # a recorded clip ran out, its last frame seen
                            loop_end = LoopEnd(LoopEndKind.CLIP, "end of the clip")
                            break
                        # an overrun: the watchdog sees it; no burst follows. A stop signal
                        # ends the wait at once (acted on at the top of the loop).
                        clock.wait(interrupted=requests.pending)
                finally:
                    loop_end = loop_end.with_steps(steps)  # the closing stop comes after these
                    now = clock.now()
                    loop.operator_stop(now)
                    session.before_step(now)
                    loop.step(clock.now())
            if isinstance(base, KobukiBase):
                loop_end = _closed_link_end(base, loop_end)
        except Exception as exc:
            if loop_end.kind is LoopEndKind.ERROR:  # the recording says which error, in one line
                # (the same steps: the closing stop after them is still not the run's end)
                loop_end = replace(loop_end, text=f"an error: {' '.join(str(exc).split())}"
                                   if str(exc).strip() else f"an error ({type(exc).__name__})")
            raise
        finally:
            end = end_reason(watch, loop_end)
            lines = session.close(end, loop_end, None if loop_end.kind is LoopEndKind.ERROR
                                  else end.exit_code)
        return RunSummary(
            steps=steps,
            duration_s=clock.now() - started,
            log_path=session.folder / RUN_MCAP,
            end=end,
            lines=tuple(lines),
            final_status=session.final_status,
        )
    finally:
        frames.close()
