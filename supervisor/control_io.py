"""What a controller receives and returns each step: the contract between the loop, the SafetyGate
and a controller.

The control loop (supervisor/loop.py) gathers the facts of one step into `ControlInputs` (the newest
frame's identity, the observation if the frame was new and perception succeeded, base feedback,
operator requests, and the events the loop itself raised) and hands them to the `SafetyGate`
(supervisor/gate.py). The gate adds the physical hazards it found and the command it sent last,
asks its `Controller` what it would like to send (a `ControlOutput`), and returns the output with
the command it allows: only the gate's output reaches the base. Plain frozen data: no behaviour.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Protocol

from lanewarden.actuation.base import STOP, BaseFeedback, VelocityCommand
from lanewarden.perception.observation import LaneObservation
from lanewarden.supervisor.events import Event


@dataclass(frozen=True)
class FrameInfo:
    """Identity of the newest frame the loop got: index, capture time (s, the injected clock's time
    base), a cheap fingerprint of its pixels (None if it could not be taken) and whether it is new
    this step (a frame source returns the same frame again until the next one is captured)."""

    index: int
    time_s: float
    fingerprint: bytes | None
    is_new: bool


@dataclass(frozen=True)
class ControlInputs:
    """Everything a controller may use in one step.

    - `frame`: None when the frame source has produced no frame yet (or failed).
    - `observation`: perception's output for a NEW frame; None when there was no new frame or
      perception raised (then `events` holds PERCEPTION_ERROR).
    - `feedback`: the base's newest feedback; None when the base gave none.
    - `events`: events raised outside the controller (by the loop): OPERATOR_STOP, CAMERA_ERROR,
      PERCEPTION_ERROR, BASE_LINK_LOST; `event_details` gives their one-line details.
    - `start_requested` / `resume_requested`: the operator asked to engage (from HALT).
    - `previous_command`: the command the gate let out in the previous step (STOP at first).
    """

    frame: FrameInfo | None = None
    observation: LaneObservation | None = None
    feedback: BaseFeedback | None = None
    events: frozenset[Event] = frozenset()
    event_details: Mapping[Event, str] = field(default_factory=lambda: MappingProxyType({}))
    start_requested: bool = False
    resume_requested: bool = False
    previous_command: VelocityCommand = STOP


@dataclass(frozen=True)
class ControlOutput:
    """One step's decision. From a controller: the command it would like to send (the gate limits
    it, or zeroes it). From the gate: the command sent. `lane_trusted`: what the supervisor made of
    this step's new frame (None: no new frame judged, or a controller that judges none)."""

    command: VelocityCommand = STOP
    state: str = "HALT"
    events: tuple[Event, ...] = ()
    halt_reason: str | None = None
    filtered_slope_sum: float | None = None
    slope_sum_variance: float | None = None
    innovation: float | None = None
    filtered_center_offset: float | None = None
    lane_trusted: bool | None = None


class Controller(Protocol):
    """One step's inputs -> the command it would like to send. Implemented by SupervisedController,
    LectureController and the bring-up tool's FixedCommand; always driven through a SafetyGate."""

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput: ...
