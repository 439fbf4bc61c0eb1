"""The lane observation: perception's only output, and the supervisor's only view of the image.

Coordinate frame: image pixels, origin at the top-left corner, x to the right, y DOWN (OpenCV's
convention). Slopes are reported in the lecture's convention, with y pointing UP (see
`perception.geometry` for the definition and why a right bend makes the slope sum negative).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType


@dataclass(frozen=True)
class LaneEdge:
    """One chosen lane edge, as a segment in image pixels (x right, y down).

    (x1, y1) is the end nearest the robot (larger y, bottom of the image); (x2, y2) the far end.
    `slope` is the lecture-convention slope (y up), bounded, see `perception.geometry`.
    `support_px` is the total length, in pixels, of the Hough segments that voted for this edge.
    """

    x1: float
    y1: float
    x2: float
    y2: float
    slope: float
    support_px: float = 0.0

    def as_json(self) -> dict[str, float]:
        return {
            "x1": round(self.x1, 2),
            "y1": round(self.y1, 2),
            "x2": round(self.x2, 2),
            "y2": round(self.y2, 2),
            "slope": round(self.slope, 4),
        }


@dataclass(frozen=True)
class LaneObservation:
    """What perception saw in one frame.

    - `left` / `right`: the chosen edges, or None when that side was not found.
    - `slope_sum`: left.slope + right.slope (lecture convention), None unless both edges exist.
    - `confidence`: in [0, 1]; `components` names each factor that went into it (each in [0, 1]),
      so a log can say why confidence fell.
    - `frame_index`, `time_s`: the frame's index and capture time on the injected clock.
    - `center_offset`: where the lane centre (midway between the two edges) crosses the bottom of
      the region of interest, relative to the image centre, in half image widths: 0 centred,
      positive when the lane centre lies right of the image centre (the robot is left of the lane
      centre). None unless both edges exist. The slope sum alone barely sees a lateral offset;
      this is the centring signal.
    """

    frame_index: int
    time_s: float
    left: LaneEdge | None
    right: LaneEdge | None
    slope_sum: float | None
    confidence: float
    components: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    center_offset: float | None = None

    @property
    def both_edges(self) -> bool:
        return self.left is not None and self.right is not None

    def as_json(self) -> dict[str, object]:
        return {
            "frame_index": self.frame_index,
            "time_s": round(self.time_s, 6),
            "left": None if self.left is None else self.left.as_json(),
            "right": None if self.right is None else self.right.as_json(),
            "slope_sum": None if self.slope_sum is None else round(self.slope_sum, 4),
            "confidence": round(self.confidence, 4),
            "components": {k: round(v, 4) for k, v in self.components.items()},
            "center_offset": None if self.center_offset is None else round(self.center_offset, 4),
        }
