"""The lecture's steering decision from one observation: straight, left, right, or none.

"none" when the observation has no slope sum (an edge is missing) or its confidence is below
`confidence.min_confidence`; otherwise the lecture's rule on the slope sum (y up, see
`perception.geometry`): below -turn_slope_sum turn right, above +turn_slope_sum turn left.

This is what `lanewarden detect` prints; the supervisor filters the slope sum over time instead of
acting on single frames. Pure function.
"""

from __future__ import annotations

from typing import Literal

from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.observation import LaneObservation

Decision = Literal["straight", "left", "right", "none"]


def decide(observation: LaneObservation, config: PerceptionConfig) -> Decision:
    slope_sum = observation.slope_sum
    if slope_sum is None or observation.confidence < config.confidence.min_confidence:
        return "none"
    threshold = config.decision.turn_slope_sum
    if slope_sum < -threshold:
        return "right"
    if slope_sum > threshold:
        return "left"
    return "straight"
