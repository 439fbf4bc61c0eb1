"""The robot runner: camera -> perception -> supervisor -> Kobuki, on the monotonic clock.

The only place in Lanewarden that reads the wall (monotonic) clock for control and the only loop
that sleeps. Everything it drives is the same stack (lanewarden/assembly.py: detector, controller,
SafetyGate, `ControlLoop`) the simulator steps on a fake clock.
Order of start-up is chosen so nothing moves until every check passed: config, calibration, camera
(and its image size against the calibration), then the base, then an explicit start. On any exit
(end of duration, Ctrl-C, SIGTERM, an error) the loop is told to stop, the base is closed (which
sends stop and leaves the dead-man holding it), and the log is flushed.
"""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import FrameType

from lanewarden.actuation.kobuki_base import KobukiBase
from lanewarden.assembly import build_stack
from lanewarden.camera_source import CameraFrameSource, open_camera, replay_rate_fps
from lanewarden.config import LanewardenConfig
from lanewarden.perception.calibration import load_calibration, require_usable_calibration
from lanewarden.supervisor.clock import MonotonicClock
from lanewarden.supervisor.controllers import controller_factory
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.loop import StepRecord
from lanewarden.supervisor.recorder import JsonlRecorder

FIRST_FRAME_TIMEOUT_S = 3.0


@dataclass(frozen=True)
class RunSummary:
    steps: int
    duration_s: float
    final_state: str
    halt_reason: str | None
    log_path: Path


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
    frames = CameraFrameSource(capture, clock.now, replay_rate_fps(camera, capture, 1.0 / period),
                               max_pixels=max_pixels)
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

        stop_requested = [False]
        last: StepRecord | None = None
        steps = 0
        with (
            KobukiBase.open(port, clock=clock.now, config=config.actuation) as base,
            JsonlRecorder(log_path) as recorder,
            _stop_on_signals(stop_requested),
        ):
            loop = stack.connect(frames, base, recorder)
            started = clock.now()
            loop.start(started)
            next_tick = started
            try:
                while not stop_requested[0]:
                    now = clock.now()
                    if duration_s is not None and now - started >= duration_s:
                        break
                    last = loop.step(now)
                    steps += 1
                    next_tick += period
                    delay = next_tick - clock.now()
                    if delay > 0:
                        time.sleep(delay)
                    else:
                        next_tick = clock.now()  # overrun: the watchdog sees it; don't burst
            finally:
                now = clock.now()
                loop.operator_stop(now)
                last = loop.step(now)
        return RunSummary(
            steps=steps,
            duration_s=clock.now() - started,
            final_state=last.state if last else "HALT",
            halt_reason=last.halt_reason if last else None,
            log_path=log_path,
        )
    finally:
        frames.close()
