"""What one lane observation is worth: well-formed? usable? confident? which events it raises.

Per new frame:
- malformed (non-finite numbers, confidence outside [0, 1], slope sum inconsistent with the edges,
  or not the frame it claims to be): `observation_problem` says why (MALFORMED_OBSERVATION);
- no edge: BOTH_EDGES_LOST; one edge: ONE_EDGE_LOST;
- confidence below `confidence_usable_min`: LANE_UNTRUSTED (no usable lane);
- confidence below `confidence_degrade_below` for `low_confidence_degrade_frames` frames in a row:
  LANE_LOW_CONFIDENCE.
"Usable" (resets the lane-lost timer): at least one edge and confidence >= the usable minimum.
"Confident" (counts towards engage/recover): both edges and confidence >=
`confidence_confident_min`.
Pure; the only memory is the low-confidence streak.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import FrameInfo
from lanewarden.supervisor.events import Event


@dataclass(frozen=True)
class LaneAssessment:
    events: frozenset[Event]
    usable: bool
    confident: bool
    slope_sum: float | None
    """The measurement for the slope filter (None: predict only)."""


def _finite(*values: float | None) -> bool:
    """Every value is None or a finite number."""
    for value in values:
        if value is not None and not (isinstance(value, int | float) and math.isfinite(value)):
            return False
    return True


def _edge_problem(name: str, edge: LaneEdge | None) -> str | None:
    if edge is None:
        return None
    if not _finite(edge.x1, edge.y1, edge.x2, edge.y2, edge.slope):
        return f"{name} edge has a non-finite coordinate or slope"
    return None


def observation_problem(observation: LaneObservation, frame: FrameInfo | None) -> str | None:
    """Why `observation` cannot be trusted as data (None: it is well-formed)."""
    obs = observation
    if not (_finite(obs.confidence) and 0.0 <= obs.confidence <= 1.0):
        return f"confidence {obs.confidence!r} is not in [0, 1]"
    if not _finite(obs.slope_sum):
        return f"slope_sum {obs.slope_sum!r} is not finite"
    if not _finite(obs.lane_offset_m, obs.lane_heading_rad):
        return (f"lane_offset_m {obs.lane_offset_m!r} / lane_heading_rad "
                f"{obs.lane_heading_rad!r} is not finite")
    if obs.both_edges != (obs.slope_sum is not None):
        return "slope_sum must be given exactly when both edges are"
    for name, edge in (("left", obs.left), ("right", obs.right)):
        problem = _edge_problem(name, edge)
        if problem:
            return problem
    if frame is not None and obs.frame_index != frame.index:
        return f"observation is for frame {obs.frame_index}, expected frame {frame.index}"
    return None


class LaneEvidence:
    def __init__(self, config: SupervisorConfig) -> None:
        self._config = config
        self._low_confidence_frames = 0

    def assess(self, observation: LaneObservation) -> LaneAssessment:
        """Events and flags for one well-formed observation of a new frame."""
        cfg = self._config
        obs = observation
        events: set[Event] = set()
        edges = (obs.left is not None) + (obs.right is not None)
        if edges == 0:
            events.add(Event.BOTH_EDGES_LOST)
        elif edges == 1:
            events.add(Event.ONE_EDGE_LOST)
        trusted = obs.confidence >= cfg.confidence_usable_min
        if edges > 0 and not trusted:
            events.add(Event.LANE_UNTRUSTED)
        if obs.confidence < cfg.confidence_degrade_below:
            self._low_confidence_frames += 1
        else:
            self._low_confidence_frames = 0
        if self._low_confidence_frames >= cfg.low_confidence_degrade_frames:
            events.add(Event.LANE_LOW_CONFIDENCE)
        usable = edges > 0 and trusted
        confident = edges == 2 and obs.confidence >= cfg.confidence_confident_min
        measurement = obs.slope_sum if (edges == 2 and trusted) else None
        return LaneAssessment(frozenset(events), usable, confident, measurement)
