"""The control loop: frame source -> perception -> SafetyGate(controller) -> base, one `step(now)`
per tick.

Shared by the simulator and the robot runner. The caller owns the clock and calls `step(now)` once
per camera period WHETHER OR NOT a frame arrived (a dead camera must still be noticed). Each step:
read the newest frame (non-blocking), run perception on it if it is new, read the base's feedback,
hand it all to the SafetyGate (which asks its controller and decides what may be sent), send the
gate's command, and hand a `StepRecord` to `record`. The loop takes a gate, never a bare
controller: nothing a controller says reaches the base except through the gate.

Failures are faults, never crashes and never a stale command: the frame source raising becomes
CAMERA_ERROR, the detector raising anything becomes PERCEPTION_ERROR, the base raising an
ActuationError becomes BASE_LINK_LOST; the gate and the controller see them as events and halt.
Operator requests (`start`, `resume`, `operator_stop`) are delivered to the gate at the next step;
`operator_stop` also sends a zero command to the base at once.

This module never reads a clock and never sleeps.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from types import MappingProxyType
from typing import Protocol

import numpy as np

from lanewarden.actuation.base import STOP, Base, BaseFeedback, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.perception.observation import LaneObservation, LaneReference
from lanewarden.supervisor.control_io import ControlInputs, Controller, ControlOutput, FrameInfo
from lanewarden.supervisor.errors import exception_line
from lanewarden.supervisor.events import Event, ordered
from lanewarden.supervisor.watchdog import frame_fingerprint

__all__ = [
    "ControlInputs",
    "ControlLoop",
    "ControlOutput",
    "Controller",
    "Detector",
    "Frame",
    "FrameInfo",
    "FrameSource",
    "Gate",
    "StepRecord",
]


@dataclass(frozen=True)
class Frame:
    """One camera image (BGR uint8 HxWx3 or gray HxW), its index and its capture time (seconds on
    the loop's clock)."""

    image: np.ndarray
    index: int
    time_s: float


class FrameSource(Protocol):
    def read(self, now: float) -> Frame | None:
        """The newest frame captured at or before `now` (the same one again until a newer one
        exists); None when there is no frame. Must not block."""


class Detector(Protocol):
    def detect(
        self,
        image: np.ndarray,
        frame_index: int,
        time_s: float,
        previous: LaneReference = None,
    ) -> LaneObservation: ...


class Gate(Protocol):
    """What the loop drives: a `SafetyGate` (or a wrapper around one that behaves the same, like
    the recording tap). A bare `Controller` is not a Gate: it has no `lane_memory_s`, so a type
    checker refuses to hand the loop a controller without its gate."""

    @property
    def lane_memory_s(self) -> float:
        """How long the last lane the supervisor trusted stays the one perception's
        `consistency` is measured against (`ControlLoop._reference`)."""

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput: ...


def _round(value: float | None, digits: int = 6) -> float | None:
    return None if value is None else round(float(value), digits)


@dataclass(frozen=True)
class StepRecord:
    """What happened in one step (one line of run.jsonl).

    `frame_index`/`frame_time_s`: the newest frame (None: none yet). `time_s`: the step's time.
    `observation`: perception's output if the frame was new and perception succeeded.
    `filtered_slope_sum`: the slope sum the controller acted on (filtered for the supervised
    controller, raw for the lecture's). `events`: event names in priority order. `command`: what
    the gate sent to the base. `lane_trusted`: whether the supervisor trusted this step's new frame
    (None: no new frame judged, or a controller that judges none, such as the lecture's).
    """

    frame_index: int | None
    time_s: float
    observation: LaneObservation | None
    filtered_slope_sum: float | None
    slope_sum_variance: float | None
    state: str
    events: tuple[str, ...]
    command: VelocityCommand
    halt_reason: str | None
    frame_time_s: float | None = None
    innovation: float | None = None
    filtered_center_offset: float | None = None
    lane_trusted: bool | None = None

    def as_json(self) -> dict[str, object]:
        return {
            "frame_index": self.frame_index,
            "time_s": _round(self.time_s),
            "frame_time_s": _round(self.frame_time_s),
            "state": self.state,
            "events": list(self.events),
            "command": {
                "linear_m_s": _round(self.command.linear_m_s),
                "angular_rad_s": _round(self.command.angular_rad_s),
            },
            "halt_reason": self.halt_reason,
            "filtered_slope_sum": _round(self.filtered_slope_sum, 4),
            "slope_sum_variance": _round(self.slope_sum_variance),
            "innovation": _round(self.innovation, 4),
            "filtered_center_offset": _round(self.filtered_center_offset, 4),
            "lane_trusted": self.lane_trusted,
            "observation": None if self.observation is None else self.observation.as_json(),
        }


class ControlLoop:
    def __init__(
        self,
        frames: FrameSource,
        detector: Detector,
        gate: Gate,
        base: Base,
        *,
        record: Callable[[StepRecord], None] | None = None,
    ) -> None:
        self._frames = frames
        self._detector = detector
        self._gate = gate
        self._base = base
        self._record = record
        self._last_index: int | None = None
        self._last_fingerprint: bytes | None = None
        # The lane perception's `consistency` is measured against (`_reference`), and how long it
        # stays so: read once here, so a gate without it fails at assembly, not frame by frame.
        self._reference_lane: LaneObservation | None = None
        self._previous: LaneObservation | None = None
        self._lane_memory_s = float(gate.lane_memory_s)
        self._start = False
        self._resume = False
        # Counted, not flagged: a stop requested from another thread while a step runs is never
        # lost (the step re-sends STOP after its own command, and the next step latches HALT).
        self._stop_requests = 0
        self._stops_delivered = 0
        self._base_failure: str | None = None

    def start(self, now: float) -> None:
        """Ask to engage (from the initial HALT); takes effect at the next step."""
        self._start = True

    def resume(self, now: float) -> None:
        """Ask to leave a latched HALT; the controller still needs a confident lane."""
        self._resume = True

    def operator_stop(self, now: float) -> None:
        """Stop now: a zero command goes to the base immediately; HALT latches at the next step.
        Safe to call from another thread than the one that steps."""
        self._stop_requests += 1
        self._send(STOP, now)

    def step(self, now: float) -> StepRecord:
        events: set[Event] = set()
        details: dict[Event, str] = {}
        stop_requests = self._stop_requests
        if stop_requests != self._stops_delivered:
            events.add(Event.OPERATOR_STOP)
        start, self._start = self._start, False
        resume, self._resume = self._resume, False
        info, observation = self._perceive(now, events, details)
        feedback = self._feedback(now, events, details)

        output = self._gate.step(
            ControlInputs(
                frame=info,
                observation=observation,
                feedback=feedback,
                events=frozenset(events),
                event_details=MappingProxyType(details),
                start_requested=start,
                resume_requested=resume,
            ),
            now,
        )
        self._stops_delivered = stop_requests
        sent_events = output.events  # the gate's are in priority order already
        if not self._send(output.command, now):
            sent_events = ordered((*sent_events, Event.BASE_LINK_LOST))
        if self._stop_requests != stop_requests and not output.command.is_stop:
            self._send(STOP, now)  # a stop arrived during this step: it wins over our command
        self._remember(observation, output.lane_trusted)
        record = self._make_record(now, info, observation, output, sent_events)
        if self._record is not None:
            self._record(record)
        return record

    def _perceive(
        self, now: float, events: set[Event], details: dict[Event, str]
    ) -> tuple[FrameInfo | None, LaneObservation | None]:
        """The newest frame's identity, and perception's observation if the frame is new. A
        camera or perception failure becomes an event (with its detail), never a crash."""
        try:
            frame = self._frames.read(now)
        except Exception as exc:  # any camera failure is a fault, never a crash
            events.add(Event.CAMERA_ERROR)
            details[Event.CAMERA_ERROR] = exception_line(exc)
            return None, None
        if frame is None:
            return None, None
        is_new = self._last_index is None or frame.index != self._last_index
        if is_new:
            self._last_index = frame.index
            self._last_fingerprint = frame_fingerprint(frame.image)
        info = FrameInfo(frame.index, frame.time_s, self._last_fingerprint, is_new)
        if not is_new:
            return info, None
        try:
            observation = self._detector.detect(
                frame.image, frame.index, frame.time_s, previous=self._reference(frame.time_s)
            )
        except Exception as exc:  # perception's failure halts; it never crashes the loop
            events.add(Event.PERCEPTION_ERROR)
            details[Event.PERCEPTION_ERROR] = exception_line(exc)
            return info, None
        return info, observation

    def _reference(self, frame_time_s: float) -> LaneReference:
        """What a new frame's `consistency` is measured against: the previous observation,
        whatever it was, and the last lane the supervisor trusted, if its frame is at most
        `Gate.lane_memory_s` older than this one; the better agreement counts. Not only the
        previous one: after one frame that took a floor seam for an edge, the next frame's true
        lane would disagree with it, and one wrong frame in two would leave no frame consistent
        at all. Not only the trusted one: it may be several frames old, and a camera that moves
        fast shifts the lane more than the per-frame tolerance in that time. Without a recent
        trusted lane (before engaging, after a loss) each frame must agree with the one before,
        as a false lane on bare floor rarely does."""
        lane, previous = self._reference_lane, self._previous
        if (lane is None or lane is previous
                or not 0.0 <= frame_time_s - lane.time_s <= self._lane_memory_s):
            return previous
        return lane if previous is None else (previous, lane)

    def _remember(self, observation: LaneObservation | None, trusted: bool | None) -> None:
        """Keep a new observation as the previous one, and as the reference lane when the
        supervisor trusted it, or when its controller judges no lanes (`trusted` None: the
        lecture's, which never had a notion of a trusted lane)."""
        if observation is None:
            return
        self._previous = observation
        if trusted is not False:
            self._reference_lane = observation

    def _feedback(
        self, now: float, events: set[Event], details: dict[Event, str]
    ) -> BaseFeedback | None:
        """The base's newest feedback; its failure, or a failed send since the last step, is
        BASE_LINK_LOST."""
        feedback: BaseFeedback | None = None
        try:
            feedback = self._base.feedback(now)
        except ActuationError as exc:
            events.add(Event.BASE_LINK_LOST)
            details[Event.BASE_LINK_LOST] = exception_line(exc)
        if self._base_failure is not None:
            events.add(Event.BASE_LINK_LOST)
            details.setdefault(Event.BASE_LINK_LOST, self._base_failure)
            self._base_failure = None
        return feedback

    def _send(self, command: VelocityCommand, now: float) -> bool:
        try:
            self._base.send(command, now)
        except ActuationError as exc:
            self._base_failure = exception_line(exc)
            return False
        return True

    @staticmethod
    def _make_record(
        now: float,
        info: FrameInfo | None,
        observation: LaneObservation | None,
        output: ControlOutput,
        events: tuple[Event, ...],
    ) -> StepRecord:
        return StepRecord(
            frame_index=None if info is None else info.index,
            time_s=now,
            observation=observation,
            filtered_slope_sum=output.filtered_slope_sum,
            slope_sum_variance=output.slope_sum_variance,
            state=output.state,
            events=tuple(e.value for e in events),
            command=output.command,
            halt_reason=output.halt_reason,
            frame_time_s=None if info is None else info.time_s,
            innovation=output.innovation,
            filtered_center_offset=output.filtered_center_offset,
            lane_trusted=output.lane_trusted,
        )
