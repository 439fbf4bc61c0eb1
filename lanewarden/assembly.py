"""The composition root: the one place that builds the control stack from the config.

`lanewarden run` (camera + Kobuki) and `lanewarden sim` / `demo` (synthetic camera + SimBase) get
the same stack from `build_stack`: the lane detector (undistorting with the given calibration), the
chosen controller, the SafetyGate between that controller and the base, and the per-frame decision
rule with the supervisor's thresholds. `ControlStack.connect` then joins it to a frame source, a
base and a record sink (all three parameters: a Kobuki or a SimBase, a run.jsonl recorder or a
list) as the one `ControlLoop`. `base drive` gets its bring-up gate, and a loop with no camera
around it (`build_bring_up_loop`), here too.

The simulator (scenarios/) receives `build_stack` as a parameter instead of importing it: the
layers below never import the CLI side. Nothing here reads a clock, a camera or a port.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Protocol

import numpy as np

from lanewarden.actuation.base import Base, VelocityCommand
from lanewarden.config import LanewardenConfig
from lanewarden.perception.calibration import CameraCalibration, Undistorter
from lanewarden.perception.decision import Decision, decide
from lanewarden.perception.detector import DetectionDebug, LaneDetector
from lanewarden.perception.observation import LaneObservation, LaneReference
from lanewarden.supervisor.control_io import Controller
from lanewarden.supervisor.controllers import DEFAULT_CONTROLLER, FixedCommand, make_controller
from lanewarden.supervisor.gate import SafetyGate
from lanewarden.supervisor.limiter import CommandLimits
from lanewarden.supervisor.loop import ControlLoop, Frame, FrameSource, StepRecord

DecisionRule = Callable[[LaneObservation], Decision]


class DetectionTap:
    """The real detector, run through `detect_debug` so a recording or a live view can draw its
    overlay. Satisfies the loop's Detector protocol and returns exactly what `detect` would."""

    def __init__(self, detector: LaneDetector) -> None:
        self._detector = detector
        self.last: tuple[int, LaneObservation, DetectionDebug] | None = None

    def detect(self, image: np.ndarray, frame_index: int, time_s: float,
               previous: LaneReference = None) -> LaneObservation:
        self.last = None
        observation, debug = self._detector.detect_debug(image, frame_index, time_s, previous)
        self.last = (frame_index, observation, debug)
        return observation


@dataclass(frozen=True)
class ControlStack:
    """Everything between a frame source and a base, for one run.

    `detector`: perception. `controller`: what it would like to send. `gate`: what may be sent
    (wraps `controller`). `decide`: perception's per-frame decision with the supervisor's
    thresholds (for printing and overlays; the controller does not use it). `tap`: the newest
    detection with its debug data, when `build_stack(debug_tap=True)` asked for it.
    """

    detector: LaneDetector
    controller: Controller
    gate: SafetyGate
    decide: DecisionRule
    tap: DetectionTap | None = None

    def connect(self, frames: FrameSource, base: Base,
                record: Callable[[StepRecord], None] | None = None) -> ControlLoop:
        """The run's control loop (call once: the controller keeps the run's history)."""
        return ControlLoop(frames, self.tap or self.detector, self.gate, base, record=record)


class BuildStack(Protocol):
    """`build_stack`'s signature: what the simulator receives instead of importing this module."""

    def __call__(self, config: LanewardenConfig, *, controller: str = ...,
                 calibration: CameraCalibration | None = ...,
                 debug_tap: bool = ...,
                 image_size: tuple[int, int] | None = ...) -> ControlStack: ...


def decision_rule(config: LanewardenConfig) -> DecisionRule:
    """`perception.decision.decide` with the supervisor's trust and turn thresholds."""
    return partial(decide, trust_min_confidence=config.supervisor.confidence_usable_min,
                   turn_slope_sum=config.supervisor.turn_enter_slope_sum)  # fmt: skip


def build_stack(
    config: LanewardenConfig,
    *,
    controller: str = DEFAULT_CONTROLLER,
    calibration: CameraCalibration | None = None,
    debug_tap: bool = False,
    image_size: tuple[int, int] | None = None,
) -> ControlStack:
    """The stack for one run; SupervisorError (one line) for an unknown controller name.

    `image_size`: the frames' (width, height) when known. Without a calibration the detector then
    assumes the default camera at that size, so a config this camera cannot work with is refused
    here, before anything moves (`PerceptionConfigError`, exit 2), not frame by frame."""
    chosen = make_controller(controller, config.supervisor)
    undistorter = Undistorter(calibration) if calibration is not None else None
    detector = LaneDetector(config.perception, undistorter, image_size=image_size)
    return ControlStack(
        detector=detector,
        controller=chosen,
        gate=SafetyGate(chosen, config.supervisor),
        decide=decision_rule(config),
        tap=DetectionTap(detector) if debug_tap else None,
    )


def build_bring_up_gate(config: LanewardenConfig, command: VelocityCommand) -> SafetyGate:
    """`base drive`: the same gate (hazards, latch, ramp) around one fixed command, capped at the
    base's own limits rather than the supervisor's driving caps."""
    limits = CommandLimits.for_bring_up(config.supervisor, config.actuation.max_linear_m_s,
                                        config.actuation.max_angular_rad_s)  # fmt: skip
    return SafetyGate(FixedCommand(command), config.supervisor, limits)


class NoCamera:
    """`base drive` has no camera: no frame, ever, so there is nothing to detect either."""

    def read(self, now: float) -> Frame | None:
        return None

    def detect(self, image: np.ndarray, frame_index: int, time_s: float,
               previous: LaneReference = None) -> LaneObservation:
        raise AssertionError("no camera: the loop never has a frame to detect on")


def build_bring_up_loop(config: LanewardenConfig, command: VelocityCommand,
                        base: Base) -> ControlLoop:
    """`base drive`: the one `ControlLoop` (feedback -> the bring-up gate -> base, failures as
    events), with no camera."""
    no_camera = NoCamera()
    return ControlLoop(no_camera, no_camera, build_bring_up_gate(config, command), base)
