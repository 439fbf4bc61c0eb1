"""The confidence score: how far the supervisor may trust this frame's slope sum.

Components (each in [0, 1], all reported in `LaneObservation.components`):
- `both_sides`: 1 with a left and a right edge, 0.5 with one, 0 with none.
- `support_left` / `support_right`: total length of the edge's Hough segments relative to
  `support_full_frac_of_height` of the image height (capped at 1): sparse evidence scores low.
- `lane_width`: distance between the two edges at the ROI bottom (as a fraction of image width)
  against the expected `width_at_bottom_frac_of_width`: 1 within the tolerance, 0 at twice it.
  Catches a tape edge paired with a seam or a stray line.
- `vanishing_point`: where the two edges' lines meet, against (0.5, `horizon_y_norm`): 1 within
  the tolerances, 0 at twice them. Two lane edges on a flat floor meet at the horizon; random
  lines don't.
- `tape_pair_left` / `tape_pair_right`: the edge is one side of a tape (two parallel edges of
  opposite polarity, tape-wide apart), not a seam or a lone line: the pair's width score; 0
  unpaired, `tape.unverifiable_score` when the partner would lie outside the image.
- `consistency`: agreement with the previous observation (edge position at the ROI bottom and edge
  angle), when one is given; 1 when there is none or nothing to compare (neutral, not a check).

Combination (a weighted geometric product, weights in `confidence.weights`):

    confidence = both_sides^w_b * support_left^(w_s/2) * support_right^(w_s/2) * lane_width^w_w
                 * vanishing_point^w_v * tape_pair_left^(w_t/2) * tape_pair_right^(w_t/2)
                 * consistency^w_c

A weight of 1 makes a component a full gate (a 0 forces confidence 0), smaller weights soften it,
0 ignores it. Per-side components share their weight. Components that need both edges are 0 when
one is missing. The tile-grout-only floor, the lecture's failure, scores 0 through `tape_pair`.

Pure function: no images, no clock.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType

from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.geometry import intersect_lines, x_at_row
from lanewarden.perception.observation import LaneEdge, LaneObservation

COMPONENT_NAMES = (
    "both_sides",
    "support_left",
    "support_right",
    "lane_width",
    "vanishing_point",
    "tape_pair_left",
    "tape_pair_right",
    "consistency",
)

Line = tuple[float, float, float, float]


def _ramp(deviation: float, tolerance: float) -> float:
    """1 for |deviation| <= tolerance, linear down to 0 at twice the tolerance."""
    return min(1.0, max(0.0, 2.0 - abs(deviation) / tolerance))


def lane_components(
    *,
    size: tuple[int, int],
    y_bottom: float,
    left_line: Line | None,
    right_line: Line | None,
    left_support_px: float,
    right_support_px: float,
    left_tape: float,
    right_tape: float,
    config: PerceptionConfig,
) -> dict[str, float]:
    """All components except `consistency`. Lines are (x1, y1, x2, y2) in pixels, through the
    near part of each edge (where a bend has not yet curved it)."""
    width, height = size
    cc = config.confidence
    lane = config.lane
    full = cc.support_full_frac_of_height * height
    sides = (left_line is not None) + (right_line is not None)
    comps = {
        "both_sides": sides / 2.0,
        "support_left": min(1.0, left_support_px / full) if left_line is not None else 0.0,
        "support_right": min(1.0, right_support_px / full) if right_line is not None else 0.0,
        "lane_width": 0.0,
        "vanishing_point": 0.0,
        "tape_pair_left": left_tape if left_line is not None else 0.0,
        "tape_pair_right": right_tape if right_line is not None else 0.0,
    }
    if left_line is not None and right_line is not None:
        x_left = x_at_row(*left_line, y_bottom)
        x_right = x_at_row(*right_line, y_bottom)
        lane_width = (x_right - x_left) / width
        if lane_width > 0.0:
            comps["lane_width"] = _ramp(
                lane_width - lane.width_at_bottom_frac_of_width, lane.width_tolerance_frac_of_width
            )
        meet = intersect_lines(left_line, right_line)
        if meet is not None:
            vx = meet[0] / width - 0.5
            vy = meet[1] / height - lane.horizon_y_norm
            comps["vanishing_point"] = _ramp(vx, lane.vanishing_x_tolerance_norm) * _ramp(
                vy, lane.vanishing_y_tolerance_norm
            )
    return comps


def consistency_component(
    left: LaneEdge | None,
    right: LaneEdge | None,
    previous: LaneObservation | None,
    size: tuple[int, int],
    y_bottom: float,
    config: PerceptionConfig,
) -> float:
    """Agreement with `previous`: per side present in both, the edge's column at the ROI bottom
    and its angle; the worst side counts. 1 when there is nothing to compare."""
    if previous is None:
        return 1.0
    width = size[0]
    cc = config.confidence
    score = 1.0
    for now, before in ((left, previous.left), (right, previous.right)):
        if now is None or before is None:
            continue
        shift = (
            x_at_row(now.x1, now.y1, now.x2, now.y2, y_bottom)
            - x_at_row(before.x1, before.y1, before.x2, before.y2, y_bottom)
        ) / width
        turn = _angle(now) - _angle(before)
        score = min(
            score,
            _ramp(shift, cc.consistency_offset_tol_frac_of_width)
            * _ramp(turn, cc.consistency_angle_tol_deg),
        )
    return score


def _angle(edge: LaneEdge) -> float:
    return math.degrees(math.atan2(edge.y1 - edge.y2, edge.x2 - edge.x1))


def combine(components: Mapping[str, float], config: PerceptionConfig) -> float:
    """The weighted geometric product of the components (see module docstring)."""
    w = config.confidence.weights
    exponents = {
        "both_sides": w.both_sides,
        "support_left": w.support / 2.0,
        "support_right": w.support / 2.0,
        "lane_width": w.lane_width,
        "vanishing_point": w.vanishing_point,
        "tape_pair_left": w.tape_pair / 2.0,
        "tape_pair_right": w.tape_pair / 2.0,
        "consistency": w.consistency,
    }
    total = 1.0
    for name, exponent in exponents.items():
        if exponent == 0.0:
            continue
        value = min(1.0, max(0.0, float(components.get(name, 1.0))))
        if value == 0.0:
            return 0.0
        total *= value**exponent
    return total


def frozen_components(components: Mapping[str, float]) -> Mapping[str, float]:
    """An immutable, ordered view of the components (the observation is frozen)."""
    return MappingProxyType({name: float(components[name]) for name in COMPONENT_NAMES})
