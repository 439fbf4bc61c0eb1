"""A lane from one tape: the dashed line's edge put where the lane's width says, while its
dashes are out of sight.

A dashed centre line's gap, or a corner that turns its dashes out of the view: for a few frames
that side shows no tape, and the two-sided lane has no confidence (in the default campaign the
largest class of false halts: the yellow dashed line beside a white one, a dash gap in a corner
of the lecture's course). With `perception.lane.dashed_side` set to that side (the user's word
that its line is dashed: a solid line out of sight may have ended, and is never bridged), when
the other side is a verified tape (`SideChoice.verified`: two edges a tape width apart on the
floor with a tape's band between them) and the lane it gives agrees with a lane seen just before
(`confidence.consistency_component`, against the references that have both edges: seen, or one
of them placed, since a gap lasts several frames; the DEGRADED budget bounds such a chain), the
missing edge is reported where the lane's free width (`PerceptionConfig.free_width_m`) puts it,
on the floor, beside the seen edge's reported chord, and projected back into the image. Its slope
makes the slope sum, its floor line the lane centre, as for a seen edge.

Such an observation says so: `components["both_sides"]` is 0.5 (one side seen) with both edges
present (`LaneObservation.sides_seen` is 1). Its confidence is the two-sided formula's on the
seen side's evidence, so at most 0.5 (default weights): the supervisor takes it as usable (it
does not lose the lane), never as confident (it never engages or recovers on it, and it breaks a
run of confident frames), and raises ONE_EDGE_LOST (DEGRADED: half speed, clipped steering, and
the DEGRADED budget bounds how long it may go on). Its placed edge counts for the lane-departure
rule as a seen one does, and a placed lane that jumps where the robot could not have moved it is
no lane to the supervisor (`supervisor.lane_evidence`). The detector reports it
only when it scores higher than the two-sided lane, and never without a reference lane (a still
image, the first frame, after a loss).

Pure function of its arguments.
"""

from __future__ import annotations

import math

from lanewarden.perception.confidence import (
    EdgeEvidence,
    combine,
    consistency_component,
    frozen_components,
    lane_centre,
    lane_components,
)
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.floor_view import FloorView, Point, direction, signed_offset
from lanewarden.perception.geometry import Side, edge_slope, other_side
from lanewarden.perception.observation import (
    LaneEdge,
    LaneObservation,
    LaneReference,
    reference_lanes,
)

#: `components["both_sides"]` of a lane with one side seen.
ONE_SIDE = 0.5


def one_side_ceiling(config: PerceptionConfig) -> float:
    """The most a lane from one tape can score (`combine`: `both_sides` is ONE_SIDE, every other
    component at most 1): a frame whose own lane scores this much is never replaced by one."""
    return ONE_SIDE ** config.confidence.weights.both_sides


def lane_from_one_side(
    seen: Side,
    edge: LaneEdge,
    floor: EdgeEvidence,
    view: FloorView,
    height_px: int,
    config: PerceptionConfig,
    previous: LaneReference,
    frame_index: int,
    time_s: float,
) -> LaneObservation | None:
    """The lane from the verified tape on `seen` (its reported `edge` and its near line on the
    floor, `floor`), or None: no reference lane with both edges, or the seen edge cannot be put
    on the floor, or the other edge lies behind the camera."""
    references = tuple(lane for lane in reference_lanes(previous) if lane.both_edges)
    if not references or not floor.verified:
        return None
    other = other_side(seen)
    free = config.free_width_m
    # The reported chord, near end to the look-ahead, moved across the lane on the floor.
    a0, a1 = view.to_floor(edge.x1, edge.y1), view.to_floor(edge.x2, edge.y2)
    chord = direction(a0, a1)
    if not math.isfinite(sum((*a0, *a1, *chord))) or chord == (0.0, 0.0):
        return None
    across = _across(chord, seen, free)
    b0 = view.to_image(a0[0] + across[0], a0[1] + across[1])
    b1 = view.to_image(a1[0] + across[0], a1[1] + across[1])
    if not math.isfinite(sum((*b0, *b1))):
        return None
    # The near line on the floor, moved the same way (offset, heading, lane centre).
    shift = _across(floor.direction, seen, free)
    point = (floor.point[0] + shift[0], floor.point[1] + shift[1])
    far = None if floor.far_m is None else floor.far_m + shift[0]
    placed = EdgeEvidence(point=point, direction=floor.direction, support_px=floor.support_px,
                          tape_score=floor.tape_score, verified=False, dark=floor.dark,
                          polarity=-floor.polarity, far_m=far)
    placed_edge = LaneEdge(
        x1=b0[0], y1=b0[1], x2=b1[0], y2=b1[1],
        slope=edge_slope(b0[0], b0[1], b1[0], b1[1], other, config.edges.max_abs_slope),
        support_px=0.0, offset_m=signed_offset(point, floor.direction),
        heading_rad=math.atan2(floor.direction[1], floor.direction[0]), near_m=point[0],
        far_m=far)
    left, right = (edge, placed_edge) if seen == "left" else (placed_edge, edge)
    left_floor, right_floor = (floor, placed) if seen == "left" else (placed, floor)
    components = lane_components(height_px=height_px, left=left_floor, right=right_floor,
                                 config=config)
    components["both_sides"] = ONE_SIDE
    components["consistency"] = consistency_component(left, right, references, view, config)
    offset, heading = lane_centre(left_floor, right_floor)
    return LaneObservation(
        frame_index=frame_index, time_s=time_s, left=left, right=right,
        slope_sum=left.slope + right.slope, confidence=combine(components, config),
        components=frozen_components(components), lane_offset_m=offset,
        lane_heading_rad=heading)


def _across(direction_: Point, seen: Side, distance: float) -> Point:
    """`distance` across a floor line running along `direction_` (unit, away from the robot),
    towards the lane: to its right for a left edge, to its left for a right one."""
    dx, dy = direction_
    return (dy * distance, -dx * distance) if seen == "left" else (-dy * distance, dx * distance)
