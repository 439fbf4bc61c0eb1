"""The lane observation: perception's only output, and the supervisor's only view of the image.

Two frames:
- image pixels (edges, slopes): origin at the top-left corner, x to the right, y DOWN (OpenCV's
  convention) of the analysed (undistorted) image. Slopes are reported in the lecture's
  convention, with y pointing UP (see `perception.geometry` for the definition and why a right
  bend makes the slope sum negative).
- the robot frame on the floor (offsets, headings): metres and radians, x forward, y LEFT
  (REP 103), origin on the floor under the robot's centre, through the camera's ground model.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TypeAlias


@dataclass(frozen=True)
class LaneEdge:
    """One chosen lane edge, as a segment in image pixels (x right, y down).

    (x1, y1) is the end nearest the robot (larger y, bottom of the image); (x2, y2) the far end.
    `slope` is the lecture-convention slope (y up), bounded, see `perception.geometry`.
    `support_px` is the total length, in pixels, of the Hough segments that voted for this edge.
    On the floor (robot frame), the edge's near part is a line `offset_m` from the robot's
    centre (signed: positive when it passes left of it) running at `heading_rad` from the robot's
    heading (counter-clockwise, i.e. to the left, positive); `near_m` is how far ahead of the
    robot's centre that near part begins (its nearest point on the floor, metres, robot x), and
    `far_m` how far ahead it ends (the far point its direction was measured to: in a bend the
    line is that stretch's chord). None when not measured.
    """

    x1: float
    y1: float
    x2: float
    y2: float
    slope: float
    support_px: float = 0.0
    offset_m: float | None = None
    heading_rad: float | None = None
    near_m: float | None = None
    far_m: float | None = None

    def as_json(self) -> dict[str, float | None]:
        return {
            "x1": round(self.x1, 2),
            "y1": round(self.y1, 2),
            "x2": round(self.x2, 2),
            "y2": round(self.y2, 2),
            "slope": round(self.slope, 4),
            "offset_m": _rounded(self.offset_m, 4),
            "heading_rad": _rounded(self.heading_rad, 4),
            "near_m": _rounded(self.near_m, 4),
            "far_m": _rounded(self.far_m, 4),
        }


def _rounded(value: float | None, digits: int) -> float | None:
    return None if value is None else round(value, digits)


@dataclass(frozen=True)
class LaneObservation:
    """What perception saw in one frame.

    - `left` / `right`: the chosen edges, or None when that side was not found.
    - `slope_sum`: left.slope + right.slope (lecture convention), None unless both edges exist.
    - `confidence`: in [0, 1]; `components` names each factor that went into it (each in [0, 1]),
      so a log can say why confidence fell.
    - `frame_index`, `time_s`: the frame's index and capture time on the injected clock.
    - `lane_offset_m`: the lane's centre line (midway between the two edges, on the floor) passes
      this far from the robot's centre, metres, positive when it lies to the robot's LEFT (the
      robot is right of the lane centre). None unless both edges exist.
    - `lane_heading_rad`: the lane's direction relative to the robot's heading, radians,
      positive when the lane runs off to the left (counter-clockwise). None unless both edges
      exist. The slope sum barely sees a lateral offset; these two are the centring signal, in
      units that do not depend on the camera.
    """

    frame_index: int
    time_s: float
    left: LaneEdge | None
    right: LaneEdge | None
    slope_sum: float | None
    confidence: float
    components: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    lane_offset_m: float | None = None
    lane_heading_rad: float | None = None

    @property
    def both_edges(self) -> bool:
        return self.left is not None and self.right is not None

    @property
    def sides_seen(self) -> int:
        """The edges perception found in the image: those present, less the one it placed the
        lane's width from the other while that tape was out of sight (`perception.one_side`:
        both edges present with `components["both_sides"]` 0.5)."""
        edges = (self.left is not None) + (self.right is not None)
        if edges == 2 and self.components.get("both_sides", 1.0) < 1.0:
            return 1
        return edges

    def as_json(self) -> dict[str, object]:
        return {
            "frame_index": self.frame_index,
            "time_s": round(self.time_s, 6),
            "left": None if self.left is None else self.left.as_json(),
            "right": None if self.right is None else self.right.as_json(),
            "slope_sum": None if self.slope_sum is None else round(self.slope_sum, 4),
            "confidence": round(self.confidence, 4),
            "components": {k: round(v, 4) for k, v in self.components.items()},
            "lane_offset_m": _rounded(self.lane_offset_m, 4),
            "lane_heading_rad": _rounded(self.lane_heading_rad, 4),
        }


def weakest_component(components: Mapping[str, float]) -> tuple[str, float] | None:
    """The confidence component that held the confidence down most: the lowest (the first of
    equals), or None when none is below 1 (nothing held it down)."""
    lowest = min(components.items(), key=lambda item: item[1], default=None)
    return lowest if lowest is not None and lowest[1] < 1.0 else None


#: What a frame's `consistency` is measured against: an earlier observation, several of them (the
#: best agreement counts: the control loop passes the frame before and the last lane its
#: supervisor trusted), or none (neutral).
LaneReference: TypeAlias = "LaneObservation | tuple[LaneObservation, ...] | None"


def reference_lanes(previous: LaneReference) -> tuple[LaneObservation, ...]:
    """The observations a `LaneReference` names, as a tuple (empty for None)."""
    if previous is None:
        return ()
    return previous if isinstance(previous, tuple) else (previous,)
