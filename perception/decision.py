"""The lecture's steering decision from one observation: straight, left, right, or none.

"none" when the observation has no slope sum (an edge is missing) or its confidence is below
`trust_min_confidence`; otherwise the lecture's rule on the slope sum (y up, see
`perception.geometry`): below -turn_slope_sum turn right, above +turn_slope_sum turn left.

Both thresholds belong to the supervisor (perception only reports slopes and a confidence): the
composition root (lanewarden/assembly.py, `decision_rule`) passes `supervisor.confidence_usable_min`
and `supervisor.turn_enter_slope_sum`, so what `lanewarden detect` prints and the video overlay
shows agrees with what the supervisor trusts. The supervisor filters the slope sum over time
instead of acting on single frames. Pure function.
"""

from __future__ import annotations

from typing import Literal

from lanewarden.perception.observation import LaneObservation

Decision = Literal["straight", "left", "right", "none"]


def decide(
    observation: LaneObservation, *, trust_min_confidence: float, turn_slope_sum: float
) -> Decision:
    slope_sum = observation.slope_sum
    if slope_sum is None or observation.confidence < trust_min_confidence:
        return "none"
    if slope_sum < -turn_slope_sum:
        return "right"
    if slope_sum > turn_slope_sum:
        return "left"
    return "straight"
