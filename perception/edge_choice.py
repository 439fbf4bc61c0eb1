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
   - the band between them is uniform and differs from the floor just outside BOTH edges, in
     the same direction, by more than those two floor samples differ (`_band_is_tape`): this
     rejects the strip of floor between a seam and a tape (one "outside" is tape), and a band
     with the real tape edge inside it.
   Dark tape on a light floor (-1, +1) and light tape on a dark floor (+1, -1) both count; dashed
   tape too (its dashes merge into one line per edge, see `perception.lines`).
2. Single edges. A line without a verified partner (Hough often misses the outer edge of a
   curving tape) is checked by the brightness profile across it (`tape_profile_fraction`): a
   tape of the expected width on its outer side along at least `min_profile_fraction` of it
   makes it a tape edge, scored by that fraction. When that side lies outside the image (a tape
   at the border, the inner tape of a sharp bend) nothing can be checked: `unverifiable_score`.
   Otherwise it is not a tape edge (score 0).
3. Preference: a tape pair is worth (support of its inner edge's whole chain, see 5, plus its
   outer edge's) x its width score; a single edge its chain's support x its profile fraction,
   x `unverifiable_score`, or x `unpaired_preference` when refuted. A line with polarity 0
   (same brightness on both sides: a thin line such as grout, not the edge of anything) is only
   chosen when there is nothing else. The best one wins. Counting the chain matters in bends: a
   curved tape breaks into short Hough pieces while a straight grout seam stays one long line.
4. The reported edge is the tape's INNER edge (the one nearer the lane centre: a left tape's right
   edge, a right tape's left edge), consistently, so the distance between the two reported edges
   is the free lane width.
5. Bends: Hough fits straight pieces to a curved edge. From the chosen line the edge is followed
   both ways through lines of the same polarity whose end lies within `chain_gap_frac_of_height`
   of the current end (not running alongside it) and that turn by at most `chain_max_turn_deg`.
   The reported segment runs from the chain's nearest point to where it crosses the look-ahead
   row (`look_ahead_y_norm`), or to its far end if shorter: the chord over a fixed stretch of
   floor, which is what reacts to a bend ahead, steadily from frame to frame.

Implementation note: a frame has a handful of candidate lines, so this works on plain Python
floats (one `LineSet.rows()` conversion), which is several times faster than numpy on arrays of
five elements. Pure function of a `LineSet`, the blurred frame and the config.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.geometry import Side
from lanewarden.perception.lines import LineRow

_MAX_CHAIN_STEPS = 8
_MAX_TAPE_CHECKS = 4
_CHAIN_BONUS_LIMIT = 4.0
_MAX_SINGLE_CHECKS = 3
_MAX_TAPES_VALUED = 2


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
    # A line with the same brightness on both sides (polarity 0) is a thin line (grout, a crack)
    # or noise, not the edge of anything: it is only chosen when nothing else is there.
    polar = sorted((r for r in cand if r.polarity != 0), key=lambda r: -r.support_px)
    singles = polar or [max(cand, key=lambda r: r.support_px)]
    preference = config.tape.unpaired_preference
    best: tuple[float, tuple[int, ...], int | None, float] | None = None  # value, chain, ...

    # 1. Verified tape pairs. Their value counts the inner edge's whole chain: a bending tape
    # breaks into short Hough pieces, a straight seam does not, and the tape must still win.
    to_beat = singles[0].support_px * preference
    pairs = _tape_pairs(cand, smooth_gray, side, y_bottom, to_beat, config)
    for inner, outer, score in itertools.islice(pairs, _MAX_TAPES_VALUED):
        chain = _follow_edge(rows, inner.line_id, (width, height), config)
        value = (sum(rows[k].support_px for k in chain) + outer.support_px) * score
        if best is None or value > best[0]:
            best = (value, chain, outer.line_id, score)

    # 2. Single edges, strongest first: valued by how much of their length the brightness
    # profile across them shows a tape on their outer side (a curved or half-visible tape whose
    # other edge Hough missed), `unpaired_preference` when that is below min_profile_fraction.
    taken = set() if best is None else {*best[1], best[2]}
    for line in singles[:_MAX_SINGLE_CHECKS]:
        if best is not None and line.support_px * _CHAIN_BONUS_LIMIT <= best[0]:
            break
        if line.line_id in taken:  # part of the tape already valued: same chain, less value
            continue
        chain = _follow_edge(rows, line.line_id, (width, height), config)
        support = sum(rows[k].support_px for k in chain)
        if best is not None and support <= best[0]:
            continue  # cannot win even as a perfect tape edge: skip the profile
        fraction = tape_profile_fraction(smooth_gray, rows, chain, side, y_bottom, config)
        if fraction is None:
            # The tape's far side would be outside the image: nothing to check it against.
            score, factor = config.tape.unverifiable_score, config.tape.unverifiable_score
        elif fraction >= config.tape.min_profile_fraction:
            score, factor = fraction, fraction
        else:
            score, factor = 0.0, preference
        value = support * factor
        if best is None or value > best[0]:
            best = (value, chain, None, score)

    assert best is not None
    _, chain, partner, score = best
    near = rows[chain[0]]
    x2, y2 = _chain_point_at(rows, chain, config.edges.look_ahead_y_norm * height)
    return SideChoice(
        side=side,
        chain=chain,
        partner=partner,
        tape_score=score,
        support_px=sum(rows[k].support_px for k in chain),
        x1=near.near_x,
        y1=near.near_y,
        x2=x2,
        y2=y2,
    )


def _chain_point_at(rows: list[LineRow], chain: tuple[int, ...], y: float) -> tuple[float, float]:
    """Where the chain (nearest line first) crosses image row `y`; its far end when it does not
    reach that far or starts beyond it. Between two lines of the chain, on the straight gap
    between them."""
    far = rows[chain[-1]]
    if far.far_y >= y or rows[chain[0]].near_y <= y + 1.0:
        # The edge stops short of the row, or lies wholly beyond it: report all of it.
        return far.far_x, far.far_y
    previous = rows[chain[0]]
    for k in chain:
        line = rows[k]
        if line.far_y > y:  # this line ends before the row
            previous = line
            continue
        if line.near_y >= y:  # the row crosses this line
            return line.x_at(y), y
        # The row falls in the gap between the previous line's far end and this one's near end.
        t = (previous.far_y - y) / max(previous.far_y - line.near_y, 1e-9)
        return previous.far_x + t * (line.near_x - previous.far_x), y
    return far.far_x, far.far_y


def tape_profile_fraction(
    smooth_gray: NDArray[np.uint8],
    rows: list[LineRow],
    chain: tuple[int, ...],
    side: Side,
    y_bottom: float,
    config: PerceptionConfig,
) -> float | None:
    """Fraction of the points sampled along an edge where the brightness across it looks like
    the INNER edge of a tape: a quarter, half and three quarters of an expected tape width
    outwards (left for a left edge) the brightness is uniform and differs, in the same
    direction, from both the lane floor half a width inwards and the floor 1.75 widths
    outwards, by more than those two floor samples differ from each other. A seam fails (the
    floor just beyond it is floor again), so does, mostly, a boundary between two floor shades.
    None when most samples fall outside the image (a tape at the image border: its far side
    cannot be seen)."""
    height, width = smooth_gray.shape[:2]
    horizon = config.lane.horizon_y_norm * height
    tape_px = config.tape.expected_width_frac_of_width * width
    c = config.tape.min_contrast_levels
    out = -1.0 if side == "left" else 1.0
    near_y = rows[chain[0]].near_y
    far_y = rows[chain[-1]].far_y
    n = config.tape.polarity_samples
    seen = hidden = tape_like = 0
    member = 0
    for i in range(n):
        y = near_y + (far_y - near_y) * (i + 0.5) / n
        while member < len(chain) - 1 and rows[chain[member]].far_y > y:
            member += 1
        x = rows[chain[member]].x_at(y)
        w = tape_px * (y - horizon) / (y_bottom - horizon)
        if w < 3.0:
            continue  # too far away to resolve a tape
        lo, hi = (x - out * 0.5 * w, x + out * 1.75 * w)
        if min(lo, hi) < 0.0 or max(lo, hi) > width - 1.0:
            hidden += 1
            continue
        row = smooth_gray[min(height - 1, max(0, int(y + 0.5)))]
        inner = float(row[int(lo + 0.5)])
        beyond = float(row[int(hi + 0.5)])
        b1 = float(row[int(x + out * 0.25 * w + 0.5)])
        b2 = float(row[int(x + out * 0.5 * w + 0.5)])
        b3 = float(row[int(x + out * 0.75 * w + 0.5)])
        seen += 1
        floor = (inner, beyond)
        step = max(min(floor) - max(b1, b2, b3), min(b1, b2, b3) - max(floor))
        if step > c and max(b1, b2, b3) - min(b1, b2, b3) < step and abs(inner - beyond) < step:
            tape_like += 1
    if seen == 0 or hidden > seen:
        return None if hidden else 0.0
    return tape_like / seen


def _tape_pairs(
    cand: list[LineRow],
    smooth_gray: NDArray[np.uint8],
    side: Side,
    y_bottom: float,
    to_beat: float,
    config: PerceptionConfig,
) -> Iterator[tuple[LineRow, LineRow, float]]:
    """Verified tapes among the candidates, as (inner edge, outer edge, tape score), best first
    by the value of the two lines alone, which must beat `to_beat` up to the bonus the chain of
    the inner edge may add (`_CHAIN_BONUS_LIMIT`). Only the `_MAX_TAPE_CHECKS` best pairs are
    band-checked, lazily: the check reads pixels."""
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
            if value * _CHAIN_BONUS_LIMIT > to_beat:
                inner, outer = (a, b) if (xa > xb) == (side == "left") else (b, a)
                pairs.append((value, score, inner, outer, y_lo, y_hi))
    pairs.sort(key=lambda p: -p[0])
    for _, score, inner, outer, y_lo, y_hi in pairs[:_MAX_TAPE_CHECKS]:
        if _band_is_tape(smooth_gray, inner, outer, y_lo, y_hi, config):
            yield inner, outer, score


def _band_is_tape(
    smooth_gray: NDArray[np.uint8],
    a: LineRow,
    b: LineRow,
    y_lo: float,
    y_hi: float,
    config: PerceptionConfig,
) -> bool:
    """Whether the band between lines a and b looks like tape: along enough of it, the band (at
    a quarter, half and three quarters across) differs from the floor just outside BOTH edges
    (half a band width out) by more than `min_contrast_levels`, all in the same direction; the
    band varies across, and the floor differs between its two sides, by less than that step.
    A floor strip between a grout seam and a tape fails (one of its "outsides" is tape), so
    does a band with a tape edge inside it (not uniform). Samples outside the image don't count
    against it; at least `min_band_fraction` of the others must look like tape."""
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
        # Three points across the band (a tape is uniform; a floor strip with a tape edge
        # inside it is not) against the floor half a band width beyond each edge.
        band = [float(row[min(width - 1, max(0, int(lo + f * (hi - lo) + 0.5)))])
                for f in (0.25, 0.5, 0.75)]
        outside = [
            float(row[int(x + 0.5)]) for x in (lo - half, hi + half) if 0.0 <= x <= width - 1.0
        ]
        if not outside:
            continue
        seen += 1
        # Darker (or lighter) than the floor on both sides by more than the contrast, and
        # uniform: the spread across the band is smaller than its step to the floor.
        spread = max(band) - min(band)
        step = max(min(outside) - max(band), min(band) - max(outside))
        floor_gap = max(outside) - min(outside)  # the floor on both sides is one floor
        if step > c and spread < step and floor_gap < step:
            tape_like += 1
    return seen > 0 and tape_like >= config.tape.min_band_fraction * seen


def _follow_edge(
    rows: list[LineRow], start: int, size: tuple[int, int], config: PerceptionConfig
) -> tuple[int, ...]:
    """The chain of lines continuing `start` away from the robot and towards it: same polarity,
    an end within the chain gap, turning by at most `chain_max_turn_deg`."""
    width, height = size
    polarity = rows[start].polarity
    usable = [r for r in rows if r.line_id != start and (polarity == 0 or r.polarity == polarity)]
    gap = config.edges.chain_gap_frac_of_height * height
    max_turn = config.edges.chain_max_turn_deg
    on_line_px = max(1.5, 0.5 * config.edges.cluster_offset_frac_of_width * width)
    away = _extend(rows[start], usable, gap, max_turn, on_line_px, away=True)
    towards = _extend(rows[start], usable, gap, max_turn, on_line_px, away=False)
    return tuple([r.line_id for r in reversed(towards)] + [start] + [r.line_id for r in away])


def _extend(
    current: LineRow,
    usable: list[LineRow],
    gap: float,
    max_turn: float,
    on_line_px: float,
    *,
    away: bool,
) -> list[LineRow]:
    """Lines continuing `current` away from the robot (a near end close to its far end) or
    towards it (a far end close to its near end), nearest first; taken ones leave `usable`.

    A continuation starts about where the current line stops (overlapping it by at most a
    quarter of the gap), or, when it overlaps more, lies on it across the overlap (within
    `on_line_px`: the same edge split by Hough). A line running alongside at a few pixels is a
    neighbour (a seam beside a tape edge), not the same edge."""
    found: list[LineRow] = []
    overlap = 0.25 * gap
    for _ in range(_MAX_CHAIN_STEPS):
        best: LineRow | None = None
        best_dist = gap
        for r in usable:
            if abs(r.angle_deg - current.angle_deg) > max_turn:
                continue
            if away:
                if r.far_y >= current.far_y - 1.0:
                    continue
                shared = r.near_y - current.far_y  # rows both lines cover
                dist = math.hypot(r.near_x - current.far_x, r.near_y - current.far_y)
            else:
                if r.near_y <= current.near_y + 1.0:
                    continue
                shared = current.near_y - r.far_y
                dist = math.hypot(r.far_x - current.near_x, r.far_y - current.near_y)
            if shared > overlap:
                mid = (current.far_y + shared / 2.0) if away else (current.near_y - shared / 2.0)
                if abs(r.x_at(mid) - current.x_at(mid)) > on_line_px:
                    continue
            if dist <= best_dist:
                best, best_dist = r, dist
        if best is None:
            break
        found.append(best)
        usable.remove(best)
        current = best
    return found
