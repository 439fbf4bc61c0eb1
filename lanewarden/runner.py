"""The robot runner: camera -> perception -> supervisor -> base, on the monotonic clock.

The only place in Lanewarden that reads the wall (monotonic) clock for control and the only loop
that sleeps. Everything it drives is the same stack (lanewarden/assembly.py: detector, controller,
SafetyGate, `ControlLoop`) the simulator steps on a fake clock.
Order of start-up is chosen so nothing moves until every check passed: config, calibration, camera
(and its image size against the calibration), the recording folder and the live view's port, then
the base (`--base kobuki|sim|none`), then an explicit start. On any exit (end of duration, Ctrl-C,
SIGTERM, the end of a clip, an error) the loop is told to stop, a last step sends the stop, the
base is closed (which sends stop and leaves the dead-man holding it), and the recording is
finished.

What ends a run, and its exit code: Ctrl-C/SIGTERM, `--duration`, the end of a clip or image
sequence: 0. A live camera that stops delivering, or the base's link lost for good (the dead-man
gone, the port unplugged): 3, a safety stop, with one line naming the reason. A HALT the operator
can resume from (lane lost, operator stop, a bumper) does not end the run.
"""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import FrameType

from lanewarden.assembly import build_stack
from lanewarden.bases import open_base
from lanewarden.camera_source import CameraFrameSource, CameraLost, open_camera, replay_rate_fps
from lanewarden.config import LanewardenConfig
from lanewarden.perception.calibration import load_calibration, require_usable_calibration
from lanewarden.run_session import RunSession, SessionOptions
from lanewarden.supervisor.clock import MonotonicClock
from lanewarden.supervisor.controllers import controller_factory
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.loop import ControlLoop, StepRecord

FIRST_FRAME_TIMEOUT_S = 3.0
EXIT_OK = 0
EXIT_SAFETY_STOP = 3


@dataclass(frozen=True)
class RunSummary:
    steps: int
    duration_s: float
    final_state: str
    halt_reason: str | None
    end_reason: str
    exit_code: int
    record_folder: Path
    lines: tuple[str, ...]


@contextmanager
def _stop_on_signals(request_stop: list[bool]) -> Iterator[None]:
    """SIGINT/SIGTERM set a flag the loop checks every period (the handler itself does no I/O)."""

    def handler(signum: int, frame: FrameType | None) -> None:
        request_stop[0] = True

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _first_frame(frames: CameraFrameSource, clock: MonotonicClock, camera: str) -> tuple[int, int]:
    """The camera's image size (width, height), once its first frame arrived."""
    deadline = clock.now() + FIRST_FRAME_TIMEOUT_S
    problem = "the camera opened but delivered nothing"
    while clock.now() < deadline:
        try:
            first = frames.read(clock.now())
        except CameraLost as exc:
            problem = str(exc)
            break
        if first is not None:
            height, width = first.image.shape[:2]
            return width, height
        time.sleep(0.02)
    raise SupervisorError(f"--camera {camera}: no frame within {FIRST_FRAME_TIMEOUT_S:.0f} s "
                          f"({problem})")


def _run_over(record: StepRecord, frames: CameraFrameSource,
              link_lost: str | None) -> tuple[str, int] | None:
    """(end reason, exit code) when this step ends the run, else None."""
    if Event.CAMERA_ERROR.value in record.events and frames.error is not None:
        if frames.ended:
            return f"end of the clip: {frames.error}", EXIT_OK
        return f"camera lost: {frames.error}", EXIT_SAFETY_STOP
    if Event.BASE_LINK_LOST.value in record.events and link_lost is not None:
        return f"base link lost: {link_lost}", EXIT_SAFETY_STOP
    return None


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
    record_lossy: bool = False,
    view: str | None = None,
    meta: dict[str, object] | None = None,
) -> RunSummary:
    clock = MonotonicClock()
    controller_factory(controller_name)  # an unknown name fails here, before the camera opens
    calibration = load_calibration(calibration_path) if calibration_path else None

    max_pixels = config.perception.max_image_pixels
    capture = open_camera(camera, max_pixels)
    period = config.supervisor.camera_period_s
    frames = CameraFrameSource(capture, clock.now, replay_rate_fps(camera, capture, 1.0 / period),
                               max_pixels=max_pixels)
    try:
        width, height = _first_frame(frames, clock, camera)
        if calibration is not None:
            require_usable_calibration(calibration, (width, height), config.calibration,
                                       f"--calibration {calibration_path}")
        stack = build_stack(config, controller=controller_name, calibration=calibration,
                            debug_tap=True)  # the live page draws the detection's overlay

        session = RunSession(
            SessionOptions(base_kind=base_kind, record=record, record_lossy=record_lossy,
                           view=view, calibration_path=Path(calibration_path)
                           if calibration_path else None,
                           meta={"camera": camera, "controller": controller_name,
                                 "image_size": [width, height], **(meta or {})}),
            config, clock.now)
        stop_requested = [False]
        last: StepRecord | None = None
        end_reason, exit_code = "an error (see the message)", None
        steps = 0
        started = clock.now()
        try:
            with (
                open_base(base_kind, port=port, config=config.actuation, clock=clock.now) as base,
                _stop_on_signals(stop_requested),
            ):
                parts = session.wrap(frames, stack, base)
                loop = ControlLoop(*parts, record=session.after_step)
                panel = session.attach(loop)
                frames.play()
                started = clock.now()
                panel.start("the run command")  # the explicit start; it only arms
                next_tick = started
                try:
                    while True:
                        if stop_requested[0]:
                            end_reason, exit_code = "operator stop (Ctrl-C or SIGTERM)", EXIT_OK
                            break
                        now = clock.now()
                        if duration_s is not None and now - started >= duration_s:
                            end_reason, exit_code = f"--duration {duration_s:g} s reached", EXIT_OK
                            break
                        session.before_step(now)
                        last = loop.step(now)
                        steps += 1
                        over = _run_over(last, frames, getattr(base, "link_lost", None))
                        if over is not None:
                            end_reason, exit_code = over
                            break
                        next_tick += period
                        delay = next_tick - clock.now()
                        if delay > 0:
                            time.sleep(delay)
                        else:
                            next_tick = clock.now()  # overrun: the watchdog sees it; don't burst
                finally:
                    now = clock.now()
                    loop.operator_stop(now)
                    session.before_step(now)
                    last = loop.step(now)
        finally:
            lines = session.close(end_reason, exit_code)
        assert exit_code is not None  # set on every way out of the loop that does not raise
        return RunSummary(
            steps=steps,
            duration_s=clock.now() - started,
            final_state=last.state if last else "HALT",
            halt_reason=session.stats.halt_cause or (last.halt_reason if last else None),
            end_reason=end_reason,
            exit_code=exit_code,
            record_folder=session.folder,
            lines=tuple(lines),
        )
    finally:
        frames.close()
