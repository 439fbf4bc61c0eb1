"""The confidence score: how far the supervisor may trust this frame's lane.

Components (each in [0, 1], all reported in `LaneObservation.components`):
- `both_sides`: 1 with a left and a right edge, 0.5 with one, 0 with none.
- `support_left` / `support_right`: total length of the edge's Hough segments relative to
  `support_full_frac_of_height` of the image height (capped at 1): sparse evidence scores low.
- `lane_width`: distance between the two edges ON THE FLOOR against the free width between the
  tapes (`lane.width_m` less half of each side's tape): 1 within `lane.width_tolerance_fraction`
  of `lane.width_m`, 0 at twice it. Catches a tape edge paired with a seam or a stray line; the
  config makes sure one tape's own two edges never score (`perception.config`).
- `parallel`: the angle between the two edges on the floor: 1 within
  `lane.parallel_tolerance_deg`, 0 at twice it. Lane edges are parallel; random lines are not.
- `tape_pair_left` / `tape_pair_right`: the edge is one side of a tape, not a seam or a lone
  line: a verified pair's width score, a lone edge's profile fraction, `tape.unverifiable_score`
  when its tape's far side is outside the image; 0 for a seam or a refuted line.
- `verified_tape`: 1 when at least one side is a verified tape (two edges whose width on the
  floor is a tape's, with a tape's band between them), else 0. Always a full gate (no weight):
  edges nobody could check (at the image border) never make a lane confident on their own.
- `floor_between`: 1 when the two reported edges enclose floor, not a tape: the verified tapes
  are of one kind (dark or light), each reported edge's polarity puts the floor on its inner
  side for that kind (a dark tape's inner edge is darker outwards, lighter inwards), and the two
  edges are not lines of one and the same tape. Else 0; always a full gate. One tape's two
  edges, a light floor strip taken for a tape beside a dark one, or an edge whose brightness
  says nothing (polarity 0) never make a lane.
- `heading`: 1 when the lane (the line midway between the two edges on the floor) runs within
  `lane.max_heading_deg` of the robot's heading, else 0; always a full gate. In the simulator's
  courses a robot following its lane stays within 25 degrees (benchmarks/lane_headings.py); a
  pair seen across the view is a corner to find again, not a lane to steer along, and the
  lecture's slope sum may read it as straight and steer across the tape in front.
- `consistency`: agreement with the previous observation (each reported edge's position and
  direction on the floor), when one is given; 1 when there is none or nothing to compare
  (neutral).

Combination (a weighted geometric product, weights in `confidence.weights`):

    confidence = both_sides^w_b * support_left^(w_s/2) * support_right^(w_s/2) * lane_width^w_w
                 * parallel^w_p * tape_pair_left^(w_t/2) * tape_pair_right^(w_t/2)
                 * verified_tape * floor_between * heading * consistency^w_c

A weight of 1 makes a component a full gate (a 0 forces confidence 0), smaller weights soften it,
0 ignores it. Per-side components share their weight. Components that need both edges are 0 when
one is missing. The tile-grout-only floor, the lecture's failure, scores 0 through `tape_pair`
and `verified_tape`.

Pure function: no images, no clock.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from lanewarden.perception.config import ConfidenceWeights, PerceptionConfig
from lanewarden.perception.floor_view import (
    FloorView,
    Point,
    direction,
    distance_to_line,
    signed_offset,
)
from lanewarden.perception.kept import KeptPerObject
from lanewarden.perception.observation import (
    LaneEdge,
    LaneObservation,
    LaneReference,
    reference_lanes,
)

#: Each component in a phrase, for a reader of a report (the docstring above says how each is
#: computed), in the order `LaneObservation.components` gives them.
COMPONENT_MEANINGS = MappingProxyType({
    "both_sides": "a lane edge found on each side (0.5 with one)",
    "support_left": "how much line the left edge rests on (short or sparse edges score low)",
    "support_right": "how much line the right edge rests on",
    "lane_width": "the two edges lie the configured lane width apart on the floor",
    "parallel": "the two edges run parallel on the floor",
    "tape_pair_left": "the left edge is a tape's edge (verified by its width and band, or by "
                      "its brightness profile; tape.unverifiable_score, 0.6 by default, when its "
                      "tape lies beyond the image's border and cannot be checked)",
    "tape_pair_right": "the right edge is a tape's edge (as tape_pair_left)",
    "verified_tape": "at least one side is a tape verified by its width and band (a gate)",
    "floor_between": "the two edges enclose floor, not a tape or a floor strip (a gate)",
    "heading": "the lane runs within lane.max_heading_deg of the robot's heading (a gate)",
    "consistency": "agreement with the frame before (1 for a still)",
})
COMPONENT_NAMES = tuple(COMPONENT_MEANINGS)


@dataclass(frozen=True)
class EdgeEvidence:
    """What confidence needs of one chosen edge: its near line on the floor (`point`, unit
    `direction` away from the robot, robot frame metres), its Hough support in pixels, its tape
    score, whether it is a verified tape and of which kind (`dark`: darker than the floor; None
    when not verified), the reported edge's `polarity` (+1 lighter to its right in the image,
    -1 darker, 0 unclear) and the candidate lines it is made of (`line_ids`: its chain and its
    tape partner)."""

    point: Point
    direction: Point
    support_px: float
    tape_score: float
    verified: bool
    dark: bool | None = None
    polarity: float = 0.0
    line_ids: frozenset[int] = frozenset()
    #: how far ahead (robot x, metres) the near line ends: the far point `direction` runs to
    far_m: float | None = None


def ramp(deviation: float, tolerance: float) -> float:
    """1 for |deviation| <= tolerance, linear down to 0 at twice the tolerance."""
    if not math.isfinite(deviation):
        return 0.0
    return min(1.0, max(0.0, 2.0 - abs(deviation) / tolerance))


def floor_angle_deg(a: Point, b: Point) -> float:
    """Angle between two floor directions, degrees in [0, 180]."""
    return math.degrees(abs(math.atan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1])))


def lane_components(
    *,
    height_px: int,
    left: EdgeEvidence | None,
    right: EdgeEvidence | None,
    config: PerceptionConfig,
) -> dict[str, float]:
    """All components except `consistency`."""
    cc = config.confidence
    full = cc.support_full_frac_of_height * height_px
    sides = (left is not None) + (right is not None)
    comps = {
        "both_sides": sides / 2.0,
        "support_left": min(1.0, left.support_px / full) if left is not None else 0.0,
        "support_right": min(1.0, right.support_px / full) if right is not None else 0.0,
        "lane_width": 0.0,
        "parallel": 0.0,
        "tape_pair_left": left.tape_score if left is not None else 0.0,
        "tape_pair_right": right.tape_score if right is not None else 0.0,
        "verified_tape": 1.0 if ((left is not None and left.verified)
                                 or (right is not None and right.verified)) else 0.0,
        "floor_between": 0.0,
        "heading": 0.0,
    }
    if left is not None and right is not None:
        comps["floor_between"] = floor_between(left, right)
        heading_deg = math.degrees(abs(lane_heading_rad(left.direction, right.direction)))
        comps["heading"] = 1.0 if heading_deg <= config.lane.max_heading_deg else 0.0
        gap = 0.5 * (distance_to_line(left.point, right.point, right.direction)
                     + distance_to_line(right.point, left.point, left.direction))
        expected = free_width_m(config)
        # The left edge must lie left of the right one (a crossed pair is no lane).
        left_of = (right.direction[0] * (left.point[1] - right.point[1])
                   - right.direction[1] * (left.point[0] - right.point[0]))
        if left_of > 0.0:
            comps["lane_width"] = ramp(gap - expected, config.lane.width_tolerance_m)
        comps["parallel"] = ramp(floor_angle_deg(left.direction, right.direction),
                                  config.lane.parallel_tolerance_deg)
    return comps


def lane_centre(left: EdgeEvidence, right: EdgeEvidence) -> tuple[float, float]:
    """(offset, heading) of the line midway between the two edges on the floor: its signed
    distance from the robot's centre (left +) and its direction (radians, left +)."""
    heading = lane_heading_rad(left.direction, right.direction)
    d = (math.cos(heading), math.sin(heading))
    offset = 0.5 * (signed_offset(left.point, d) + signed_offset(right.point, d))
    return offset, heading


def lane_heading_rad(left: Point, right: Point) -> float:
    """The direction of the line midway between two edges with floor directions `left` and
    `right` (unit vectors away from the robot): radians from the robot's heading, left +."""
    return math.atan2(left[1] + right[1], left[0] + right[0])


def floor_between(left: EdgeEvidence, right: EdgeEvidence) -> float:
    """1 when the two reported edges enclose floor (see the module docstring), else 0.

    Polarity is the brightness right of an edge less left of it. The floor lies right of the
    left edge and left of the right one, so beside dark tapes (floor lighter) the left edge reads
    +1 and the right edge -1; beside light tapes the reverse. The tapes' kind comes from the
    verified ones (without a verified tape confidence is 0 anyway)."""
    # (The verified kinds compared one by one, not gathered into a set: it runs every frame.)
    if left.verified:
        dark = left.dark
        if right.verified and right.dark != dark:
            return 0.0  # two kinds
    elif right.verified:
        dark = right.dark
    else:
        return 0.0  # no kind
    if not left.line_ids.isdisjoint(right.line_ids):
        return 0.0
    floor_lighter = 1.0 if dark else -1.0
    return 1.0 if left.polarity == floor_lighter and right.polarity == -floor_lighter else 0.0


def consistency_component(
    left: LaneEdge | None,
    right: LaneEdge | None,
    previous: LaneReference,
    view: FloorView,
    config: PerceptionConfig,
) -> float:
    """Agreement with `previous` (with several observations: the best agreement with any of
    them): per side present in both, the reported segment (near end to the look-ahead) on the
    floor: how far its near end lies from the previous one's line and how much it turned; the
    worst side counts. 1 when there is nothing to compare. (The reported chord, not the near
    line: near Hough pieces come and go in a bend, the chord does not.)"""
    return max((_agreement(left, right, lane, view, config) for lane in reference_lanes(previous)),
               default=1.0)


def _agreement(left: LaneEdge | None, right: LaneEdge | None, previous: LaneObservation,
               view: FloorView, config: PerceptionConfig) -> float:
    cc = config.confidence
    score = 1.0
    for now, before in ((left, previous.left), (right, previous.right)):
        if now is None or before is None:
            continue
        a0, a1 = view.to_floor(now.x1, now.y1), view.to_floor(now.x2, now.y2)
        b0, b1 = view.to_floor(before.x1, before.y1), view.to_floor(before.x2, before.y2)
        da, db = direction(a0, a1), direction(b0, b1)
        if not math.isfinite(sum((*a0, *b0, *da, *db))) or (0.0, 0.0) in (da, db):
            continue
        shift = distance_to_line(a0, b0, db)
        turn = floor_angle_deg(da, db)
        score = min(
            score,
            ramp(shift, cc.consistency_offset_tol_m) * ramp(turn, cc.consistency_angle_tol_deg),
        )
    return score


def combine(components: Mapping[str, float], config: PerceptionConfig) -> float:
    """The weighted geometric product of the components (see module docstring)."""
    total = 1.0
    get = components.get
    for name, exponent in _exponents(config.confidence.weights):
        value = float(get(name, 1.0))
        # min(1.0, max(0.0, value)), written out (the same for NaN: 0.0)
        value = value if value > 0.0 else 0.0
        value = value if value < 1.0 else 1.0
        if value == 0.0:
            return 0.0
        if value != 1.0:  # (1.0 ** exponent is 1.0: the product is the same without it)
            total *= value**exponent
    return total


def _derive_exponents(w: ConfidenceWeights) -> tuple[tuple[str, float], ...]:
    exponents = {
        "both_sides": w.both_sides,
        "support_left": w.support / 2.0,
        "support_right": w.support / 2.0,
        "lane_width": w.lane_width,
        "parallel": w.parallel,
        "tape_pair_left": w.tape_pair / 2.0,
        "tape_pair_right": w.tape_pair / 2.0,
        "verified_tape": 1.0,
        "floor_between": 1.0,
        "heading": 1.0,
        "consistency": w.consistency,
    }
    return tuple((name, exponent) for name, exponent in exponents.items() if exponent != 0.0)


#: (component, exponent) in `combine`'s order, leaving out those weighted 0 (ignored); kept
#: per weights object (building the table cost as much as the product).
_exponents: KeptPerObject[ConfidenceWeights, tuple[tuple[str, float], ...]] = KeptPerObject(
    _derive_exponents)


def _derive_free_width_m(config: PerceptionConfig) -> float:
    return config.free_width_m


#: `PerceptionConfig.free_width_m`, kept per config object (a property of three properties,
#: and the choice of tapes asks it of every pair of tapes).
free_width_m: KeptPerObject[PerceptionConfig, float] = KeptPerObject(_derive_free_width_m)


def frozen_components(components: Mapping[str, float]) -> Mapping[str, float]:
    """An immutable, ordered view of the components (the observation is frozen)."""
    return MappingProxyType({name: float(components[name]) for name in COMPONENT_NAMES})
