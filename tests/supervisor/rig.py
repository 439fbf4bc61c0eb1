"""Test rigs for the supervisor: hand-built observations, a controller driven on a fake clock, and
doubles of the things around the supervisor (a camera, a perception stand-in, a base that records).

The doubles replace the *neighbours* (camera, perception, base), never the supervisor's own logic.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from lanewarden.actuation.base import STOP, BaseFeedback, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.perception.errors import PerceptionError
from lanewarden.perception.observation import LaneEdge, LaneObservation, LaneReference
from lanewarden.supervisor.clock import FakeClock
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, ControlOutput, FrameInfo
from lanewarden.supervisor.controller import SupervisedController
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.gate import SafetyGate
from lanewarden.supervisor.loop import Frame

DT = 1.0 / 30.0
LEFT_EDGE = LaneEdge(100.0, 480.0, 300.0, 200.0, 1.6, 250.0)
RIGHT_EDGE = LaneEdge(540.0, 480.0, 340.0, 200.0, -1.6, 250.0)


def observation(
    index: int,
    time_s: float,
    *,
    slope_sum: float = 0.0,
    confidence: float = 0.9,
    left: bool = True,
    right: bool = True,
    lane_offset_m: float = 0.0,
    left_edge_m: float | None = None,
) -> LaneObservation:
    """A well-formed observation (slope sum and lane centre only when both edges exist).
    `left_edge_m`: the left edge measured on the floor, parallel to the robot, this far left of
    its centre line and seen from 0.4 m ahead (None: not measured on the floor)."""
    both = left and right
    left_edge = LEFT_EDGE if left_edge_m is None else replace(
        LEFT_EDGE, offset_m=left_edge_m, heading_rad=0.0, near_m=0.4)
    return LaneObservation(
        frame_index=index,
        time_s=time_s,
        left=left_edge if left else None,
        right=RIGHT_EDGE if right else None,
        slope_sum=slope_sum if both else None,
        confidence=confidence,
        lane_offset_m=lane_offset_m if both else None,
        lane_heading_rad=0.0 if both else None,
    )


_UNSET = object()


class Rig:
    """A SupervisedController behind its SafetyGate (as every run has it), stepped at 30 Hz on a
    fake clock with hand-made inputs. Outputs are the gate's (what would reach the base)."""

    def __init__(self, config: SupervisorConfig | None = None) -> None:
        self.config = config or SupervisorConfig()
        self.controller = SupervisedController(self.config)
        self.gate = SafetyGate(self.controller, self.config)
        self.clock = FakeClock()
        self.index = -1
        self.frame: FrameInfo | None = None
        self.outputs: list[ControlOutput] = []
        self.first = True

    @property
    def state(self) -> str:
        return self.controller.state.value

    def step(
        self,
        *,
        slope_sum: float = 0.0,
        confidence: float = 0.9,
        left: bool = True,
        right: bool = True,
        lane_offset_m: float = 0.0,
        new_frame: bool = True,
        latency_s: float = 0.0,
        obs: object = _UNSET,
        feedback: object = _UNSET,
        events: Iterable[Event] = (),
        start: bool = False,
        resume: bool = False,
        advance_s: float = DT,
        fingerprint: bytes | None | object = _UNSET,
        left_edge_m: float | None = None,
    ) -> ControlOutput:
        """One control step `advance_s` after the previous one (the first step is at t=0)."""
        now = self.clock.now() if self.first else self.clock.advance(advance_s)
        self.first = False
        observation_: LaneObservation | None = None
        if new_frame:
            self.index += 1
            frame_time = now - latency_s
            fp = self.index.to_bytes(4, "big") if fingerprint is _UNSET else fingerprint
            assert fp is None or isinstance(fp, bytes)
            self.frame = FrameInfo(self.index, frame_time, fp, True)
            if obs is _UNSET:
                observation_ = observation(
                    self.index,
                    frame_time,
                    slope_sum=slope_sum,
                    confidence=confidence,
                    left=left,
                    right=right,
                    lane_offset_m=lane_offset_m,
                    left_edge_m=left_edge_m,
                )
            else:
                assert obs is None or isinstance(obs, LaneObservation)
                observation_ = obs
        elif self.frame is not None:
            self.frame = FrameInfo(
                self.frame.index, self.frame.time_s, self.frame.fingerprint, False
            )
        fb = BaseFeedback(received_at_s=now) if feedback is _UNSET else feedback
        assert fb is None or isinstance(fb, BaseFeedback)
        out = self.gate.step(
            ControlInputs(
                frame=self.frame,
                observation=observation_,
                feedback=fb,
                events=frozenset(events),
                start_requested=start,
                resume_requested=resume,
            ),
            now,
        )
        self.outputs.append(out)
        return out

    def engage(self, slope_sum: float = 0.0) -> ControlOutput:
        """Start, then confident frames until FOLLOW."""
        out = self.step(start=True, slope_sum=slope_sum)
        for _ in range(self.config.engage_confident_frames + 2):
            if out.state == "FOLLOW":
                return out
            out = self.step(slope_sum=slope_sum)
        raise AssertionError(f"did not engage: {out}")

    def run(self, steps: int, **kwargs: object) -> list[ControlOutput]:
        return [self.step(**kwargs) for _ in range(steps)]  # type: ignore[arg-type]


# --- neighbours of the control loop ---


def noisy_image(index: int, size: tuple[int, int] = (16, 16)) -> np.ndarray:
    """A BGR image (tiny by default, `size` = (width, height)) whose pixels differ from frame to
    frame (like sensor noise)."""
    rng = np.random.default_rng(index)
    return rng.integers(0, 256, size=(size[1], size[0], 3), dtype=np.uint8)


@dataclass
class ScriptedCamera:
    """Frames every `period_s` from t=0. `read(now)` returns the newest frame captured at or before
    `now - latency_s(now)`. Frames stop after `stop_at_s`; from `freeze_at_s` on every new frame
    carries the same pixels (a frozen driver); `fail_at_s` makes read() raise. `size`: the
    frames' (width, height)."""

    period_s: float = DT
    stop_at_s: float = float("inf")
    freeze_at_s: float = float("inf")
    fail_at_s: float = float("inf")
    latency_s: Callable[[float], float] = lambda now: 0.0
    size: tuple[int, int] = (16, 16)
    _frozen: np.ndarray | None = None

    def read(self, now: float) -> Frame | None:
        if now >= self.fail_at_s:
            raise OSError("camera unplugged: /dev/video0")
        capture = min(now - self.latency_s(now), self.stop_at_s)
        if capture < 0.0:
            return None
        index = int(capture / self.period_s + 1e-9)
        time_s = index * self.period_s
        if time_s >= self.freeze_at_s:
            if self._frozen is None:
                self._frozen = noisy_image(index, self.size)
            image = self._frozen
        else:
            image = noisy_image(index, self.size)
        return Frame(image=image, index=index, time_s=time_s)


@dataclass
class ScriptedDetector:
    """A perception stand-in: `script(frame_index, time_s)` gives the observation (or raises)."""

    script: Callable[[int, float], LaneObservation] = lambda i, t: observation(i, t)
    calls: list[int] = field(default_factory=list)

    def detect(
        self,
        image: np.ndarray,
        frame_index: int,
        time_s: float,
        previous: LaneReference = None,
    ) -> LaneObservation:
        if not isinstance(image, np.ndarray) or image.size == 0:
            raise PerceptionError(f"frame {frame_index}: empty image")
        self.calls.append(frame_index)
        return self.script(frame_index, time_s)


@dataclass
class RecordingBase:
    """A base that records every command it is sent. Feedback is fresh unless told otherwise."""

    sent: list[tuple[float, VelocityCommand]] = field(default_factory=list)
    bumper: int = 0
    link_alive_until_s: float = float("inf")
    fail_send: bool = False
    fail_feedback: bool = False
    closed: bool = False

    def send(self, command: VelocityCommand, now: float) -> None:
        if self.fail_send:
            raise ActuationError("/dev/ttyUSB0: write failed (device disconnected)")
        self.sent.append((now, command))

    def feedback(self, now: float) -> BaseFeedback:
        if self.fail_feedback:
            raise ActuationError("/dev/ttyUSB0: read failed (device disconnected)")
        return BaseFeedback(received_at_s=min(now, self.link_alive_until_s), bumper=self.bumper)

    def close(self) -> None:
        self.closed = True
        self.sent.append((float("nan"), STOP))
