"""Replay: perception and the supervisor on recorded frames, on a fake clock, step by step.

The sources (a run folder or its run.mcap, a ROS 2 bag, a video, images, a Donkeycar tub) are
recognised and read, within bounds, by lanewarden.replay_sources. A recorded run's steps are fed
back exactly as recorded (step times, frame identities and times, base feedback, failures,
operator requests; see lanewarden.run_record) with the run's own config and calibration, and
every replayed step is compared with the recorded one (frame, state, events, command, halt
reason): the first divergence is reported, so a change in perception or the supervisor can be
tested on real runs. Other sources give one step per frame at the frame's time, a base whose
feedback is always fresh, and a start at the first step.

The loop is the very `ControlLoop` the robot and the simulator run; only its frame source and base
are scripted from the recording. Never reads a clock and never sleeps.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from lanewarden.actuation.base import BaseFeedback, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.assembly import DetectionTap, build_stack
from lanewarden.config import LanewardenConfig
from lanewarden.errors import UsageError
from lanewarden.perception.calibration import CameraCalibration
from lanewarden.perception.detector import DetectionDebug
from lanewarden.perception.observation import LaneObservation, LaneReference
from lanewarden.replay_sources import (
    FrameStore,
    ReplaySource,
    frame_indices,
    missing_frames,
    open_replay_source,
    replay_config,
)
from lanewarden.run_mcap import CAMERA_GRAY, PERCEPTION_INPUT
from lanewarden.run_record import RecordedStep, StepInput
from lanewarden.supervisor.loop import ControlLoop, Frame, StepRecord
from lanewarden.supervisor.watchdog import FINGERPRINT_STRIDE
from lanewarden.wording import counted

__all__ = ["Divergence", "ReplaySource", "ReplayedStep", "check_preparation", "compare_step",
           "frame_indices", "missing_frames", "open_replay_source", "replay_config",
           "replay_steps"]


# ---- the scripted parts of the loop -----------------------------------------------------------
_NAMED: dict[tuple[str, type[Exception]], type[Exception]] = {}


def recorded_error(name: str, message: str, base: type[Exception]) -> Exception:
    """An exception that reads exactly like the recorded one (type name and message), so the
    loop's event detail comes out the same."""
    key = (name, base)
    if key not in _NAMED:
        _NAMED[key] = type(name, (base,), {})
    return _NAMED[key](message)


def fingerprint_stand_in(fingerprint: str) -> np.ndarray:
    """What the loop sees of a frame whose supervisor fingerprint was recorded: a one-row array
    whose every FINGERPRINT_STRIDE-th byte is a byte of that fingerprint, so two stand-ins have
    the same fingerprint (`frame_fingerprint`) exactly when the recorded ones are the same, and
    the watchdog's repeated and frozen image checks decide as they did on the run."""
    data = np.frombuffer(bytes.fromhex(fingerprint), np.uint8)
    return np.repeat(data, FINGERPRINT_STRIDE).reshape(1, -1)


class ScriptedFrames:
    """The loop's FrameSource during replay: the frame the recording says the step got. When
    the step recorded the frame's fingerprint, the loop gets its stand-in (and the detector,
    through `ReplayDetection`, the recorded image)."""

    def __init__(self, store: FrameStore, reuse_missing: bool) -> None:
        self._store = store
        #: a recorded run's frame missing from its recording (dropped while recording): the
        #: loop gets the frame before it, as close to the run as the replay can get; a frame
        #: that is there but does not decode (a clip's, or a run's damaged one) is no frame at
        #: all (the loop's camera sees nothing new)
        self._reuse_missing = reuse_missing
        self.step: StepInput | None = None
        #: (index, the recorded image; None: perception refused the frame on the run)
        self._cache: tuple[int, np.ndarray | None] | None = None
        self._shown: np.ndarray | None = None
        self._refused: tuple[str, str] | None = None
        self.missing: list[int] = []

    @property
    def image(self) -> np.ndarray | None:
        """The newest frame's recorded image (None: none yet, or refused on the run)."""
        return None if self._cache is None else self._cache[1]

    def read(self, now: float) -> Frame | None:
        step = self.step
        assert step is not None
        if step.frame_error is not None:
            raise recorded_error(*step.frame_error, Exception)
        if step.frame is None:
            return None
        index, time_s = step.frame
        if self._cache is None or self._cache[0] != index:
            refused = step.frame_refused
            image = None if refused is not None else self._store.image(index)
            if image is None and refused is None:
                self.missing.append(index)
                if (not self._reuse_missing or index in self._store.undecoded
                        or self._cache is None
                        or self._cache[1] is None):
                    return None
                image = self._cache[1]  # not what the run saw: the replay cannot be exact
            self._cache = (index, image)
            self._refused = refused
            fingerprint = step.frame_fingerprint
            self._shown = image if fingerprint is None else fingerprint_stand_in(fingerprint)
        if self._shown is None:  # refused, with no fingerprint recorded (not written so)
            self._shown = fingerprint_stand_in("")
        return Frame(image=self._shown, index=index, time_s=time_s)

    def recorded_image(self, shown: np.ndarray) -> np.ndarray:
        """The image behind what the loop was shown (a stand-in or the image itself); raises
        what perception raised on the run for a frame it refused."""
        if shown is not self._shown or self._cache is None:
            return shown
        if self._refused is not None:
            raise recorded_error(*self._refused, Exception)
        image = self._cache[1]
        assert image is not None
        return image


class ReplayDetection:
    """The stack's detection tap during replay: the detector gets each frame's recorded image
    (a frame prepared on the run, `PreparedImage`, goes in as it is)."""

    def __init__(self, tap: DetectionTap, frames: ScriptedFrames) -> None:
        self._tap = tap
        self._frames = frames

    def detect(self, image: np.ndarray, frame_index: int, time_s: float,
               previous: LaneReference = None) -> LaneObservation:
        self._tap.last = None
        return self._tap.detect(self._frames.recorded_image(image), frame_index, time_s,
                                previous)


class ScriptedBase:
    """The loop's Base during replay: the recorded feedback and failures; sends go nowhere."""

    def __init__(self) -> None:
        self.step: StepInput | None = None
        self._failed_sends = 0
        self.sent: list[VelocityCommand] = []

    def begin(self, step: StepInput) -> None:
        self.step = step
        self._failed_sends = 0

    def send(self, command: VelocityCommand, now: float) -> None:
        self.sent.append(command)
        step = self.step
        if step is not None and self._failed_sends < step.send_errors:
            self._failed_sends += 1
            raise ActuationError("replayed send failure")

    def feedback(self, now: float) -> BaseFeedback:
        step = self.step
        assert step is not None
        if step.feedback_error is not None:
            raise recorded_error(*step.feedback_error, ActuationError)
        return step.feedback if step.feedback is not None else BaseFeedback()

    def close(self) -> None:
        pass


@dataclass(frozen=True)
class Divergence:
    step: int
    time_s: float
    what: str
    recorded: object
    replayed: object

    def describe(self) -> str:
        return (f"step {self.step} (t = {self.time_s:.3f} s): {self.what} was "
                f"{self.recorded!r} in the recording, {self.replayed!r} in the replay")


def compare_step(step: int, recorded: RecordedStep, step_input: StepInput,
                 replayed: StepRecord, start_s: float = 0.0) -> Divergence | None:
    """The first field of a step that differs: frame, state, events, command, halt reason;
    dated from `start_s` (the run's first step: a recording's times are the robot's monotonic
    clock)."""
    command = (replayed.command.linear_m_s, replayed.command.angular_rad_s)
    checks: list[tuple[str, object, object]] = [
        ("frame index", recorded.frame_index, replayed.frame_index),
        ("state", recorded.state, replayed.state),
        ("events", list(recorded.events), list(replayed.events)),
        ("command", step_input.command, command),
        ("halt reason", recorded.halt_reason, replayed.halt_reason),
    ]
    for what, was, now in checks:
        if was != now:
            return Divergence(step, step_input.t - start_s, what, was, now)
    return None


@dataclass(frozen=True)
class ReplayedStep:
    """One replayed step, for the caller's outputs (video, plot, log)."""

    index: int
    step_input: StepInput
    record: StepRecord
    image: np.ndarray | None
    detection: tuple[LaneObservation, DetectionDebug] | None
    divergence: Divergence | None


def preparation_changed(source: ReplaySource, config: LanewardenConfig,
                        calibration: CameraCalibration | None, *, config_named: str,
                        calibration_named: str) -> tuple[str, str, str] | None:
    """(why, what was expected, how to record to try others) when a recording of perception's
    prepared input cannot be replayed with this config and calibration (its frames are already
    gray, undistorted and blurred as the run's were), or one of the camera's gray with another
    `perception.gray` (its frames made gray as the run's were); `why` begins with what was
    given (`config_named`, `calibration_named`: e.g. "--config 'blur7.yaml'"). None: it can
    (or it holds the camera's own colour frames)."""
    recorded = source.config if source.config is not None else LanewardenConfig()
    image = source.meta.get("image")
    if (image in (PERCEPTION_INPUT, CAMERA_GRAY)
            and config.perception.gray != recorded.perception.gray):
        kept = "perception's input" if image == PERCEPTION_INPUT else "the camera's gray"
        return (f"{config_named}: perception.gray {config.perception.gray.model_dump()}, but "
                f"{source.name} was recorded as {kept}, its colour frames made gray on the run "
                f"with {recorded.perception.gray.model_dump()}", "the recorded perception.gray",
                "--record-lossy, colour JPEG,")
    if image != PERCEPTION_INPUT:
        return None
    if config.perception.blur != recorded.perception.blur:
        return (f"{config_named}: perception.blur {config.perception.blur.model_dump()}, but "
                f"{source.name} was recorded as perception's input, its frames blurred on the "
                f"run with {recorded.perception.blur.model_dump()}", "the recorded blur",
                "--record-gray")
    if not same_calibration(calibration, source.calibration):
        if calibration is None:
            given = "no calibration"
        else:
            w, h = calibration.image_size
            given = f"{calibration_named} (for {w}x{h} images)"
        if source.calibration is None:
            return (f"{given}: {source.name} was recorded as perception's input without a "
                    "calibration (its frames were not undistorted)", "no --calibration",
                    "--record-gray")
        w, h = source.calibration.image_size
        return (f"{given}: {source.name} was recorded as perception's input, its frames "
                f"undistorted on the run with another calibration (for {w}x{h} images)",
                "no --calibration (the recording's own)", "--record-gray")
    return None


def check_preparation(source: ReplaySource, config: LanewardenConfig,
                      calibration: CameraCalibration | None, command: str = "replay", *,
                      config_path: str | None = None,
                      calibration_path: str | None = None) -> None:
    """UsageError (one line) when `preparation_changed` says why the source cannot be replayed
    (or surveyed: `command`) with this config and calibration; it names the flag and file
    given (`config_path`, `calibration_path`)."""
    why = preparation_changed(
        source, config, calibration,
        config_named=f"--config '{config_path}'" if config_path else "the config given",
        calibration_named=(f"--calibration '{calibration_path}'" if calibration_path
                           else "the calibration given"))
    if why:
        text, expected, record_with = why
        raise UsageError(f"{text}; expected {expected}, to {command} it as recorded (record with "
                         f"{record_with} to try others)")


def same_calibration(a: CameraCalibration | None, b: CameraCalibration | None) -> bool:
    """The same undistortion (intrinsics, distortion, image size)."""
    if a is None or b is None:
        return a is b
    return (a.image_size == b.image_size and np.array_equal(a.camera_matrix, b.camera_matrix)
            and np.array_equal(a.dist_coeffs, b.dist_coeffs))


def replay_steps(source: ReplaySource, config: LanewardenConfig,
                 calibration: CameraCalibration | None,
                 controller: str) -> Iterator[ReplayedStep]:
    """Run the loop over the source's steps; yields each replayed step (compared with the
    recording for a run folder). UsageError when the source holds perception's prepared input
    and the config or calibration would prepare frames differently."""
    check_preparation(source, config, calibration)
    first = source.frames.image(0)
    size = None if first is None else (first.shape[1], first.shape[0])
    stack = build_stack(config, controller=controller, calibration=calibration, debug_tap=True,
                        image_size=size)
    tap = stack.tap
    assert tap is not None
    frames = ScriptedFrames(source.frames, reuse_missing=source.kind == "run")
    base = ScriptedBase()
    # the very stack `run` drives (detector, controller, gate), with the recorded images
    loop = ControlLoop(frames, ReplayDetection(tap, frames), stack.gate, base)
    start_s: float | None = None
    for k, step_input in enumerate(source.steps):
        end = source.frames.stream_end()
        if (k > 0 and end is not None and step_input.frame is not None
                and step_input.frame[0] >= end):
            # a video whose header claims more frames than its stream holds: replayed as far as
            # it goes (a 1 MB AVI claiming 999 999 frames of its 3 had stepped the loop through
            # them all, minutes and 1.1 GB: an attacker's review); one whose first frame does
            # not decode is said to be damaged (frames_undecoded), after its first step
            if end > 0:
                source.incomplete.append(f"its stream ends after {counted(end, 'frame')}, "
                                         f"where its header claims {len(source.steps)}")
            break
        now = step_input.t
        if start_s is None:
            start_s = now
        for request in step_input.requests:
            if request == "start":
                loop.start(now)
            elif request == "resume":
                loop.resume(now)
            else:
                loop.operator_stop(now)
        frames.step = step_input
        base.begin(step_input)
        record = loop.step(now)
        detection = None
        if tap.last is not None and tap.last[0] == record.frame_index and record.observation:
            detection = (tap.last[1], tap.last[2])
        tap.last = None
        divergence = None
        if source.recorded is not None:
            divergence = compare_step(k, source.recorded[k], step_input, record, start_s)
        yield ReplayedStep(k, step_input, record, frames.image, detection, divergence)
    source.frames.close()
