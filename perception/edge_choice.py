"""Choosing the lane edge on each side: the lecture's open problem.

For one side of the image (left: lines crossing the ROI bottom left of the image centre, leaning
"/" or at most `max_past_vertical_deg` past vertical; right: mirror image):

1. Tape pairs. Two candidate lines of nearly the same direction (`pair_angle_tol_deg`) and
   opposite polarity are the two edges of one tape when
   - their gap, measured horizontally at the nearest row both reach (the best-resolved one) and
     projected to the ROI bottom through the horizon (perspective makes far tape thinner), is
     tape-wide as a fraction of image width: a 48 mm tape is ~8.6% with the default camera, 4 mm
     tile grout ~0.7%, so the two sides of a grout seam never pass;
   - they are at least `min_gap_px` apart where measured: blur keeps the two sides of ANY thin
     line a few pixels apart whatever the resolution (this keeps grout out at 160x120, where a
     4 mm seam is a pixel wide);
   - the band between them differs from the floor just outside BOTH edges, in the same
     direction (`_band_is_tape`): this rejects the strip of floor between a seam and a tape.
   Dark tape on a light floor (-1, +1) and light tape on a dark floor (+1, -1) both count; dashed
   tape too (its dashes merge into one line per edge, see `perception.lines`).
   An unpaired edge whose partner would lie outside the image (a tape cut by the image border,
   the inner tape of a sharp bend) gets `unverifiable_score` instead of 0: absent evidence there
   is not evidence of a seam.
2. Preference: a tape scores the support of both its edges times its tape score; a line with no
   partner scores its support times `unpaired_preference`. The best one wins.
3. The reported edge is the tape's INNER edge (the one nearer the lane centre: a left tape's right
   edge, a right tape's left edge), consistently, so the distance between the two reported edges
   is the free lane width.
4. Bends: Hough fits straight pieces to a curved edge. From the chosen line the edge is followed
   both ways through lines of the same polarity whose end lies within `chain_gap_frac_of_height`
   and that turn by at most `chain_max_turn_deg`; the reported segment runs from the chain's
   nearest point to its farthest. Its slope is therefore the chord of the visible edge, which is
   what reacts to a bend ahead.

Implementation note: a frame has a handful of candidate lines, so this works on plain Python
floats (one `LineSet.rows()` conversion), which is several times faster than numpy on arrays of
five elements. Pure function of a `LineSet`, the blurred frame and the config.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from perception.config import PerceptionConfig
from perception.geometry import Side
from perception.lines import LineRow

_MAX_CHAIN_STEPS = 8
_MAX_TAPE_CHECKS = 4


@dataclass(frozen=True)
class SideChoice:
    """The edge chosen on one side.

    - `chain`: line indices of the edge, nearest first; `near_line` is chain[0] (used for the
      lane width, vanishing point and centre offset, where a bend has not yet curved it).
    - `partner`: the tape's other edge, None when the edge is not part of a tape.
    - `tape_score`: in [0, 1], how tape-like the pair is (0 without a partner, or
      `unverifiable_score` when the partner would be outside the image).
    - `support_px`: total length of the chain's Hough segments.
    - `x1, y1` near end and `x2, y2` far end of the reported segment (pixels, y down).
    """

    side: Side
    chain: tuple[int, ...]
    partner: int | None
    tape_score: float
    support_px: float
    x1: float
    y1: float
    x2: float
    y2: float

    @property
    def near_line(self) -> int:
        return self.chain[0]


def side_candidates(
    rows: list[LineRow], side: Side, width: int, config: PerceptionConfig
) -> list[LineRow]:
    """The lines that may be this side's edge."""
    min_h = config.edges.min_angle_from_horizontal_deg
    past = config.edges.max_past_vertical_deg
    centre = 0.5 * width
    if side == "left":
        return [r for r in rows if r.x_bottom < centre and min_h <= r.angle_deg <= 90.0 + past]
    return [r for r in rows if r.x_bottom >= centre and 90.0 - past <= r.angle_deg <= 180.0 - min_h]


def tape_width_score(width_frac: float, gap_px: float, config: PerceptionConfig) -> float:
    """1 inside [width_min, width_max], falling linearly to 0 at 0.75x the minimum and at 1.25x
    the maximum; 0 when the two edges are closer than `min_gap_px` where measured."""
    if gap_px < config.tape.min_gap_px:
        return 0.0
    lo = config.tape.width_min_frac_of_width
    hi = config.tape.width_max_frac_of_width
    rise = (width_frac - 0.75 * lo) / (0.25 * lo)
    fall = (1.25 * hi - width_frac) / (0.25 * hi)
    return min(1.0, max(0.0, min(rise, fall)))


def choose_side(
    rows: list[LineRow],
    smooth_gray: NDArray[np.uint8],
    side: Side,
    y_bottom: float,
    config: PerceptionConfig,
) -> SideChoice | None:
    """The best edge on `side`, or None when there is no candidate line. `rows` are the frame's
    candidate lines, `smooth_gray` the blurred frame they came from, `y_bottom` the ROI's
    bottom row."""
    height, width = smooth_gray.shape[:2]
    cand = side_candidates(rows, side, width, config)
    if not cand:
        return None
    strongest = max(cand, key=lambda r: r.support_px)
    best_edge = strongest.line_id
    best_partner: int | None = None
    best_score = 0.0
    tape = _best_tape(
        cand, smooth_gray, side, y_bottom, strongest.support_px * config.tape.unpaired_preference,
        config,
    )
    if tape is not None:
        best_edge, best_partner, best_score = tape

    chain = _follow_edge(rows, best_edge, height, config)
    near = rows[chain[0]]
    far = rows[chain[-1]]
    support_px = sum(rows[k].support_px for k in chain)
    if best_partner is None and _partner_out_of_view(
        rows, chain, side, (width, height), y_bottom, config
    ):
        best_score = config.tape.unverifiable_score
    return SideChoice(
        side=side,
        chain=chain,
        partner=best_partner,
        tape_score=best_score,
        support_px=support_px,
        x1=near.near_x,
        y1=near.near_y,
        x2=far.far_x,
        y2=far.far_y,
    )


def _best_tape(
    cand: list[LineRow],
    smooth_gray: NDArray[np.uint8],
    side: Side,
    y_bottom: float,
    to_beat: float,
    config: PerceptionConfig,
) -> tuple[int, int, float] | None:
    """(inner edge, outer edge, tape score) of the best tape among the candidates whose value
    beats `to_beat`, or None."""
    height, width = smooth_gray.shape[:2]
    horizon = config.lane.horizon_y_norm * height
    angle_tol = config.tape.pair_angle_tol_deg
    pairs: list[tuple[float, float, LineRow, LineRow, float, float]] = []
    for i, a in enumerate(cand):
        for b in cand[i + 1 :]:
            if a.polarity * b.polarity >= 0 or abs(a.angle_deg - b.angle_deg) > angle_tol:
                continue
            y_lo = max(a.far_y, b.far_y)
            y_hi = min(a.near_y, b.near_y)  # nearest row both reach: the best resolved
            depth = y_hi - horizon
            if y_hi <= y_lo or depth <= 1.0:
                continue
            xa = a.x_at(y_hi)
            xb = b.x_at(y_hi)
            gap_px = abs(xa - xb)
            score = tape_width_score(gap_px * (y_bottom - horizon) / depth / width, gap_px, config)
            value = (a.support_px + b.support_px) * score
            if value > to_beat:
                inner, outer = (a, b) if (xa > xb) == (side == "left") else (b, a)
                pairs.append((value, score, inner, outer, y_lo, y_hi))
    pairs.sort(key=lambda p: -p[0])
    for _, score, inner, outer, y_lo, y_hi in pairs[:_MAX_TAPE_CHECKS]:
        if _band_is_tape(smooth_gray, inner, outer, y_lo, y_hi, config):
            return inner.line_id, outer.line_id, score
    return None


def _band_is_tape(
    smooth_gray: NDArray[np.uint8],
    a: LineRow,
    b: LineRow,
    y_lo: float,
    y_hi: float,
    config: PerceptionConfig,
) -> bool:
    """Whether the band between lines a and b looks like tape: along enough of it, the middle
    differs from the floor just outside BOTH edges (half a band width out) by more than
    `min_contrast_levels`, in the same direction. A floor strip between a grout seam and a tape
    fails: beyond the seam lies floor as bright as the strip. Samples outside the image don't
    count against it; at least `min_band_fraction` of the others must look like tape."""
    height, width = smooth_gray.shape[:2]
    n = config.tape.polarity_samples
    c = config.tape.min_contrast_levels
    seen = 0
    tape_like = 0
    for k in range(1, n + 1):
        y = y_lo + (y_hi - y_lo) * k / (n + 1)
        row = smooth_gray[min(height - 1, max(0, int(y + 0.5)))]
        xa = a.x_at(y)
        xb = b.x_at(y)
        lo, hi = (xa, xb) if xa < xb else (xb, xa)
        half = 0.5 * (hi - lo)
        middle = float(row[min(width - 1, max(0, int(lo + half + 0.5)))])
        outside = [
            float(row[int(x + 0.5)]) for x in (lo - half, hi + half) if 0.0 <= x <= width - 1.0
        ]
        if not outside:
            continue
        seen += 1
        if all(middle < o - c for o in outside) or all(middle > o + c for o in outside):
            tape_like += 1
    return seen > 0 and tape_like >= config.tape.min_band_fraction * seen


def _partner_out_of_view(
    rows: list[LineRow],
    chain: tuple[int, ...],
    side: Side,
    size: tuple[int, int],
    y_bottom: float,
    config: PerceptionConfig,
) -> bool:
    """Whether an unpaired edge's tape partner would lie outside the image for most of its
    length: a tape of the expected width, on the outer side, crosses the image border (a tape at
    the image edge, the inner tape of a sharp bend). Its absence then proves nothing."""
    width, height = size
    horizon = config.lane.horizon_y_norm * height
    tape_px = config.tape.expected_width_frac_of_width * width
    sign = -1.0 if side == "left" else 1.0
    outside = 0.0
    total = 0.0
    for k in chain:
        r = rows[k]
        for t in (0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0):
            y = r.near_y + (r.far_y - r.near_y) * t
            depth = max(0.0, (y - horizon) / (y_bottom - horizon))
            partner = r.x_at(y) + sign * tape_px * depth
            if partner < 0.0 or partner > width - 1.0:
                outside += r.support_px
            total += r.support_px
    return total > 0.0 and outside >= 0.5 * total


def _follow_edge(
    rows: list[LineRow], start: int, height: int, config: PerceptionConfig
) -> tuple[int, ...]:
    """The chain of lines continuing `start` away from the robot and towards it: same polarity,
    an end within the chain gap, turning by at most `chain_max_turn_deg`."""
    polarity = rows[start].polarity
    usable = [r for r in rows if r.line_id != start and (polarity == 0 or r.polarity == polarity)]
    gap = config.edges.chain_gap_frac_of_height * height
    max_turn = config.edges.chain_max_turn_deg
    away = _extend(rows[start], usable, gap, max_turn, away=True)
    towards = _extend(rows[start], usable, gap, max_turn, away=False)
    return tuple([r.line_id for r in reversed(towards)] + [start] + [r.line_id for r in away])


def _extend(
    current: LineRow, usable: list[LineRow], gap: float, max_turn: float, *, away: bool
) -> list[LineRow]:
    """Lines continuing `current` away from the robot (a near end close to its far end) or
    towards it (a far end close to its near end), nearest first; taken ones leave `usable`."""
    found: list[LineRow] = []
    for _ in range(_MAX_CHAIN_STEPS):
        best: LineRow | None = None
        best_dist = gap
        for r in usable:
            if abs(r.angle_deg - current.angle_deg) > max_turn:
                continue
            if away:
                if r.far_y >= current.far_y - 1.0:
                    continue
                dist = math.hypot(r.near_x - current.far_x, r.near_y - current.far_y)
            else:
                if r.near_y <= current.near_y + 1.0:
                    continue
                dist = math.hypot(r.far_x - current.near_x, r.far_y - current.near_y)
            if dist <= best_dist:
                best, best_dist = r, dist
        if best is None:
            break
        found.append(best)
        usable.remove(best)
        current = best
    return found
