"""Perception: turns one camera frame into a `LaneObservation` with a confidence score.

Knows images, never motors: nothing in this package imports `supervisor`, `actuation` or
`scenarios`, and nothing here reads a clock (frame times are passed in).
"""

from lanewarden.perception.errors import PerceptionError
from lanewarden.perception.observation import LaneEdge, LaneObservation

__all__ = ["LaneEdge", "LaneObservation", "PerceptionError"]
