"""Choosing the lane edge on each side: the lecture's open problem.

For one side of the image (left: lines crossing the ROI bottom left of where the robot's centre
line does, leaning "/" or at most `max_past_vertical_deg` past vertical; right: mirror image):

1. Verified tapes. Two candidate lines of nearly the same direction (`pair_angle_tol_deg`) and
   opposite polarity are the two edges of one tape when their distance ON THE FLOOR, measured
   at the nearest row both reach (the best resolved) through the ground model, scores as tape
   rather than seam (`perception.tape_rules.tape_width_score` at least
   MIN_VERIFIED_WIDTH_SCORE: nearer the tape's width than the widest seam's), measured no
   farther than the look-ahead (where the start-up check guarantees the camera can tell), and
   the band between them looks
   like tape (`perception.tape_rules.band_is_tape`). Dark tape on a light floor (-1, +1) and
   light tape on a dark floor (+1, -1) both count; dashed tape too (its dashes merge into one
   line per edge, see `perception.lines`).
2. Which tapes: by closeness to the tape's width and to the lane's position, not by length. With
   tapes on both sides, the pair of tapes of the same kind (both dark or both light) whose inner
   edges lie `lane.width_m - tape.width_m` apart on the floor and run parallel wins
   (`lane_fit`), then the best
   width scores (1 within the tape's tolerance), then the nearest measurement (best resolved,
   and where a bending tape's chain starts), then the widths closest to the tape's.
3. Single edges, on a side without a verified tape. A line without a verified partner (Hough
   often misses the outer edge of a curving tape) is checked by the brightness profile across it
   (`perception.tape_rules.tape_profile_fraction`): a tape `width_m` wide on its outer side along
   at least `min_profile_fraction` of it makes it a tape edge scored by that fraction. When that
   side lies outside the image (a tape at the border, the inner tape of a sharp bend) nothing can
   be checked: `unverifiable_score`, but where the other side has a verified tape, only for an
   edge that steps at least UNVERIFIABLE_MIN_CONTRAST_SHARE as strongly as that tape's inner
   edge (`LineRow.contrast`): a tape at the border still shows a tape's contrast, a faint floor
   shading in the image's corner does not (a real no-lane frame, shifted by a third of a pixel,
   paired one with the lane's one tape at confidence 0.77). Not with `lane.dashed_side` left or
   right (a road's dashed centre line is often of another paint than its edge line), nor with
   per-side tape widths that differ (two different tapes). Otherwise it is not a tape edge
   (score 0). Among single
   edges the value is the chain's support x that score (x `unpaired_preference` when refuted);
   a line with polarity 0 (same brightness on both sides: grout, a crack) is only chosen when
   there is nothing else. None of these is a verified tape (`SideChoice.verified`).
   One fallback: where the best single edge's profile does not say tape (or there is none), a
   signed line and a line of NO sign beyond it, whose width and band say tape as in 1, are the
   tape (a ceiling light mirrored over a glossy tape's outer edge leaves that edge no sign, and
   the tape half light, half dark, fails the inner edge's profile there). Never with the sign
   missing on the inner (reported) edge, whose sign says which side of it is floor.
4. The reported edge is the tape's INNER edge (the one nearer the lane centre: a left tape's
   right edge, a right tape's left edge), consistently, so the distance between the two reported
   edges is the free lane width.
5. Bends: Hough fits straight pieces to a curved edge. From the chosen line the edge is followed
   both ways through lines of the same polarity whose end lies within `chain_gap_frac_of_height`
   of the current end (not running alongside it) and that turn by at most `chain_max_turn_deg`.
   The reported segment runs from the chain's nearest point to where it crosses the look-ahead
   row (`SizeSetup.look_ahead_row`), or to its far end if shorter: the chord over a fixed
   stretch of floor, which is what reacts to a bend ahead, steadily from frame to frame.

Implementation note: a frame has a handful of candidate lines, so this works on plain Python
floats (one `LineSet.rows()` conversion), which is several times faster than numpy on arrays of
five elements. Pure function of the lines, the blurred frame, the size setup and the config.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.confidence import floor_angle_deg, free_width_m, ramp
from lanewarden.perception.config import EdgesConfig, PerceptionConfig
from lanewarden.perception.floor_config import LaneConfig, TapeConfig
from lanewarden.perception.floor_view import FloorView, Point, direction, distance_to_line
from lanewarden.perception.geometry import Side
from lanewarden.perception.kept import KeptPerObject
from lanewarden.perception.lines import LineRow, pairs_within_angle
from lanewarden.perception.size_setup import SizeSetup
from lanewarden.perception.tape_rules import (
    WidthTerms,
    band_is_tape,
    tape_profile_fraction,
    width_score,
    width_terms,
)

_MAX_CHAIN_STEPS = 8
#: Pairs band-checked per side (the check reads pixels), best width first.
_MAX_TAPE_CHECKS = 4
#: Verified tapes kept per side for the joint choice.
_MAX_TAPES_KEPT = 3
#: A pair verifies a tape only when its width is nearer the tape than the widest seam (the
#: middle of the width score's ramp between the two hypotheses).
MIN_VERIFIED_WIDTH_SCORE = 0.5
_MAX_SINGLE_CHECKS = 3
#: Where the other side has a verified tape, an edge whose tape cannot be checked (at the
#: image's border) stands in for a tape only when it steps at least this share as strongly as
#: that tape's inner edge. On the JetBot set's lane frames such edges step 0.73-1.8 times as
#: strongly as the verified tape's (black tape both sides); the floor shading a shifted no-lane
#: frame paired with its one tape, 0.36 times.
UNVERIFIABLE_MIN_CONTRAST_SHARE = 0.5

#: `follow_edge`: of the lines that could continue a chain, one stepping less than this share as
#: strongly as the chain's current line (`LineRow.contrast`) is taken only when none steps more.
#: Where a glossy bending tape's edge ends a Hough piece, a floor seam crossing it can start
#: nearer than the edge's next piece: simulated parquet at 320x240, the tape's edge stepping
#: 100-106 grey levels and the seam 30, the chain ran off along the seam.
CHAIN_MIN_CONTRAST_SHARE = 0.5
#: A lone line's chain is assumed at most this many times as long as the line itself when
#: deciding whether it is worth following and checking (singles come strongest first).
_CHAIN_BONUS_LIMIT = 4.0


@dataclass(frozen=True)
class SideChoice:
    """The edge chosen on one side.

    - `chain`: line indices of the edge, nearest first; `near_line` is chain[0] (used for the
      lane width, the parallel check and the metric offset and heading, where a bend has not yet
      curved it).
    - `partner`: the tape's other edge, None when the edge is not part of a verified tape.
    - `verified`: a verified tape (a pair: width on the floor and band), the only evidence that
      can make a lane confident.
    - `tape_score`: in [0, 1], how tape-like the edge is: the pair's width score, a lone edge's
      profile fraction, `unverifiable_score`, or 0.
    - `tape_width_m`: the pair's width on the floor, metres (None for a lone edge).
    - `tape_dark`: for a verified tape, whether it is darker than the floor (None otherwise).
    - `polarity`: the reported (inner) edge's polarity (`perception.lines`: +1 lighter to its
      right, -1 darker, 0 no clear contrast); with the tape's kind it says which side of the
      edge the floor is.
    - `support_px`: total length of the chain's Hough segments.
    - `x1, y1` near end and `x2, y2` far end of the reported segment (pixels, y down).
    """

    side: Side
    chain: tuple[int, ...]
    partner: int | None
    verified: bool
    tape_score: float
    tape_width_m: float | None
    tape_dark: bool | None
    polarity: float
    support_px: float
    x1: float
    y1: float
    x2: float
    y2: float

    @property
    def near_line(self) -> int:
        return self.chain[0]

    @property
    def line_ids(self) -> frozenset[int]:
        """Every line this choice is made of: its chain and its tape partner."""
        return frozenset(self.chain if self.partner is None else (*self.chain, self.partner))


class TapeCandidate(NamedTuple):
    """A pair of lines whose width on the floor verifies a tape: its `inner` and `outer` edges,
    width score, width on the floor, whether it is darker than the floor, where its inner edge
    was measured (`at`, floor metres), the image rows both edges cover (`rows`, for the band
    check) and the configured tape width it is ranked against (`tape_width_m`). (A named tuple:
    made for every pair that measures as tape, at a third of a frozen dataclass's cost.)"""

    inner: LineRow
    outer: LineRow
    score: float
    width_m: float
    dark: bool
    at: Point
    rows: tuple[float, float] = (0.0, 0.0)
    tape_width_m: float = 0.0

    def band_is_tape(self, smooth_gray: NDArray[np.uint8], config: PerceptionConfig) -> bool:
        return band_is_tape(smooth_gray, self.inner, self.outer, *self.rows, config.tape)

    def rank(self) -> tuple[float, float, float]:
        """Best first: the width score (1 within the tape's tolerance), then the nearest
        measurement, to the centimetre (the best resolved, and where a bending tape's chain
        starts), then the width closest to the tape's."""
        return self.score, -round(self.at[0], 2), -abs(self.width_m - self.tape_width_m)


def side_candidates(
    rows: list[LineRow], side: Side, centre_x: float, config: PerceptionConfig
) -> list[LineRow]:
    """The lines that may be this side's edge (`centre_x`: where the robot's centre line
    crosses the ROI's bottom row)."""
    min_h = config.edges.min_angle_from_horizontal_deg
    past = config.edges.max_past_vertical_deg
    if side == "left":
        return [r for r in rows if r.x_bottom < centre_x and min_h <= r.angle_deg <= 90.0 + past]
    return [r for r in rows
            if r.x_bottom >= centre_x and 90.0 - past <= r.angle_deg <= 180.0 - min_h]


def choose_edges(
    rows: list[LineRow],
    smooth_gray: NDArray[np.uint8],
    setup: SizeSetup,
    config: PerceptionConfig,
) -> tuple[SideChoice | None, SideChoice | None]:
    """The left and right edges (None where a side has no candidate line). `rows` are the
    frame's candidate lines, `smooth_gray` the blurred frame they came from."""
    view, look_ahead_m, centre_x = setup.view, setup.look_ahead_m, setup.centre_x_bottom
    cands = {"left": side_candidates(rows, "left", centre_x, config),
             "right": side_candidates(rows, "right", centre_x, config)}
    # The band check reads pixels: only for the tapes the choice would take, each at most once.
    # (Kept with the tape itself: a tape let go of could leave its id to another one.)
    checked: dict[int, tuple[TapeCandidate, bool]] = {}

    def band_ok(tape: TapeCandidate) -> bool:
        key = id(tape)
        if key not in checked:
            checked[key] = (tape, tape.band_is_tape(smooth_gray, config))
        return checked[key][1]

    # (Each side's candidates come with their ranks, best first: nothing is ranked twice.)
    left_tape, right_tape = _pick_tapes(
        *_tape_candidates(cands["left"], "left", view, config, look_ahead_m, False),
        *_tape_candidates(cands["right"], "right", view, config, look_ahead_m, False),
        config, band_ok, ranked=True)

    def fallback(side: Side) -> TapeCandidate | None:
        """A tape whose outer edge has no sign, the best ranked whose band is tape."""
        unsigned, _ = _tape_candidates(cands[side], side, view, config, look_ahead_m, True)
        return _best_accepted(unsigned, None, band_ok)

    # A border edge must show the other side's tape's contrast only where the lane's two lines
    # are one tape: not where one of them is dashed (a road's centre line, often another paint:
    # yellow dashes step a third as strongly as a white edge line in gray), nor where the config
    # gives the two sides' tapes different widths (two different tapes).
    tape = config.tape
    one_tape = (config.lane.dashed_side in (None, "both")
                and tape.side_width_m("left") == tape.side_width_m("right"))
    left = _side_choice(rows, cands["left"], left_tape, smooth_gray, "left", setup, config,
                        fallback, right_tape if one_tape else None)
    right = _side_choice(rows, cands["right"], right_tape, smooth_gray, "right", setup, config,
                         fallback, left_tape if one_tape else None)
    return left, right


def measure_pair(a: LineRow, b: LineRow, side: Side, view: FloorView,
                 config: PerceptionConfig) -> tuple[LineRow, LineRow, float, float, Point] | None:
    """(inner, outer, width score, width on the floor in metres, measured point) of two lines
    taken as one tape's edges, measured at the nearest image row both reach; None when they
    share no rows or cannot be put on the floor."""
    y_lo = max(a.far_y, b.far_y)
    y_hi = min(a.near_y, b.near_y)
    if y_hi <= y_lo:
        return None
    inner, outer, u = _inner_outer(a, b, y_hi, side == "left")
    at = view.to_floor(u, y_hi)
    measured = _measure(inner, outer, u, y_hi, at, view,
                        width_terms(config.tape.for_side(side)))
    if measured is None:
        return None
    score, width_m = measured
    return inner, outer, score, width_m, at


def _inner_outer(a: LineRow, b: LineRow, y: float, left: bool) -> tuple[LineRow, LineRow, float]:
    """(inner, outer, the inner edge's column at image row `y`) of two lines taken as one tape's
    edges on the left side (`left`) or the right."""
    xa = a.cx + (y - a.cy) * a.ux / a.uy  # LineRow.x_at, written out (every pair's path)
    xb = b.cx + (y - b.cy) * b.ux / b.uy
    return (a, b, xa) if (xa > xb) == left else (b, a, xb)


def _measure(inner: LineRow, outer: LineRow, u: float, v: float, at: Point, view: FloorView,
             terms: WidthTerms) -> tuple[float, float] | None:
    """(width score, width on the floor) of a tape whose inner edge is measured at pixel (u, v),
    on the floor `at` (`view.to_floor(u, v)`); None when it cannot be put on the floor.
    `terms`: the side's `perception.tape_rules.width_terms`. (`direction`, `distance_to_line`
    and `FloorView.metres_per_px_across` written out, in their arithmetic's order: this is
    every measured pair's path, and the three calls cost a fifth of the choice on a straight
    lane.)"""
    at_x, at_y = at
    near_x, near_y = outer.near_fx, outer.near_fy
    dx, dy = outer.far_fx - near_x, outer.far_fy - near_y  # the outer edge's floor direction
    norm = math.hypot(dx, dy)
    if norm < 1e-15:
        return None  # (no direction)
    dx, dy = dx / norm, dy / norm
    if not math.isfinite(at_x + at_y + near_x + near_y + dx + dy):
        return None
    width_m = abs(dx * (at_y - near_y) - dy * (at_x - near_x))
    # One pixel's step perpendicular to the inner edge, on the floor, across the outer edge
    # (its floor normal (-dy, dx)).
    x1, y1 = view.to_floor(u - inner.uy, v + inner.ux)
    return width_score(width_m, abs((x1 - at_x) * -dy + (y1 - at_y) * dx), terms), width_m


def tape_candidates(
    cand: list[LineRow], side: Side, view: FloorView, config: PerceptionConfig,
    look_ahead_m: float, *, unsigned_outer: bool = False,
) -> list[TapeCandidate]:
    """The pairs among one side's candidates whose width on the floor verifies a tape, best first
    (`TapeCandidate.rank`), at most _MAX_TAPE_CHECKS; their bands are not checked yet. A pair is
    only measured up to the look-ahead distance (`look_ahead_m`, the size setup's): there the
    camera is known to resolve tape from seam (checked at start-up); farther on, pixels grow and
    a seam may measure as tape. Pairs whose lines lie less than a third or more than three of
    this side's tape widths apart on the floor (from one's near end) are skipped before being
    measured (a cheap filter: the measurement decides).

    `unsigned_outer`: instead of two edges of opposite signs, a signed INNER edge and an outer
    edge of no sign (polarity 0): a glossy tape whose outer edge a mirrored ceiling light left
    without a sign (`_side_choice` takes such a tape only as a fallback).

    (Every check is a filter, each pair's cheapest first: the outcome is the same in any order.
    `measure_pair`'s steps are taken one at a time so that a pair of the wrong kind or beyond
    the look-ahead is not measured further.)"""
    return _tape_candidates(cand, side, view, config, look_ahead_m, unsigned_outer)[0]


#: A tape's `TapeCandidate.rank`.
Rank = tuple[float, float, float]


def _tape_candidates(
    cand: list[LineRow], side: Side, view: FloorView, config: PerceptionConfig,
    look_ahead_m: float, unsigned_outer: bool,
) -> tuple[list[TapeCandidate], list[Rank]]:
    """`tape_candidates` and their `rank()`s (taken once here, the order they are in)."""
    angle_tol, tape_width, terms = _pair_rules(config.tape, side)
    rough_min, rough_max = tape_width / 3.0, 3.0 * tape_width
    look_ahead = look_ahead_m
    left = side == "left"
    any_kind = config.tape.kind == "any"  # (`of_configured_kind` takes every tape then)
    hypot, to_floor = math.hypot, view.to_floor
    # (Each line's sign and angle in a list: most pairs fail these first two checks.)
    polarity = [r.polarity for r in cand]
    angle = [r.angle_deg for r in cand]
    found: list[TapeCandidate] = []
    ranks: list[Rank] = []
    for i, j in _pairs_worth_checking(cand, angle_tol, tape_width, unsigned_outer):
        if unsigned_outer:
            if (polarity[i] == 0) == (polarity[j] == 0):
                continue
        elif polarity[i] * polarity[j] >= 0:
            continue
        if abs(angle[i] - angle[j]) > angle_tol:
            continue
        a, b = cand[i], cand[j]
        # The image rows both cover, where the pair is measured (none: no tape).
        y_lo = b.far_y if b.far_y > a.far_y else a.far_y  # (max() and min(), written out)
        y_hi = b.near_y if b.near_y < a.near_y else a.near_y
        if y_hi <= y_lo:
            continue
        # Distance from a's near end to b's line on the floor (not yet where they are
        # measured): a third to three tape widths, or no tape.
        bx, by = b.far_fx - b.near_fx, b.far_fy - b.near_fy
        rough = abs(bx * (a.near_fy - b.near_fy) - by * (a.near_fx - b.near_fx))
        norm = hypot(bx, by)
        if not rough_min <= rough / (1e-9 if 1e-9 > norm else norm) <= rough_max:
            continue
        inner, outer, u = _inner_outer(a, b, y_hi, left)
        if inner.polarity == 0:
            continue  # (unsigned_outer: the sign must be the inner edge's)
        if not any_kind and not of_configured_kind(inner, side, config):
            continue
        # Beyond the look-ahead refused before the width is measured (a filter like the
        # others: the same pairs pass).
        at = to_floor(u, y_hi)
        if at[0] > look_ahead:
            continue
        measured = _measure(inner, outer, u, y_hi, at, view, terms)
        if measured is None or measured[0] < MIN_VERIFIED_WIDTH_SCORE:
            continue
        score, width_m = measured
        tape = TapeCandidate(inner, outer, score, width_m, darker_beyond(inner, side), at,
                             (y_lo, y_hi), tape_width)
        found.append(tape)
        ranks.append(tape.rank())  # (taken here once: the choice of tapes orders by it again)
    if len(found) > 1:
        order = sorted(range(len(found)), key=ranks.__getitem__, reverse=True)
        found = [found[k] for k in order[:_MAX_TAPE_CHECKS]]
        ranks = [ranks[k] for k in order[:_MAX_TAPE_CHECKS]]
    return found, ranks


def _derive_pair_rules(tape: TapeConfig, side: Side) -> tuple[float, float, WidthTerms]:
    return tape.pair_angle_tol_deg, tape.side_width_m(side), width_terms(tape.for_side(side))


#: (`pair_angle_tol_deg`, the side's tape width, its `width_terms`) that `tape_candidates`
#: measures pairs by, kept per config and side (a config's properties cost more than a pair's
#: first checks).
_pair_rules: KeptPerObject[TapeConfig, tuple[float, float, WidthTerms]] = KeptPerObject(
    _derive_pair_rules)


#: From this many candidate lines on a side (a textured floor: terrazzo's chips give a hundred
#: and more at 320x240), `_pairs_worth_checking` sifts the pairs with numpy first; below it the
#: plain loop is cheaper than building the arrays.
_SIFT_FROM_LINES = 16
#: The sift keeps a pair whose rough distance misses the window by up to this share of it: numpy's
#: hypot may differ from math's in the last bit, and the loop's own check then decides.
_SIFT_SLACK = 1e-9


def _pairs_worth_checking(cand: list[LineRow], angle_tol: float, tape_width: float,
                          unsigned_outer: bool) -> Iterable[tuple[int, int]]:
    """The pairs (i, j), i < j, in that order, that `tape_candidates`' checks (signs, angle,
    rough distance, rows in common) could pass: all of them for a few lines; with many
    (`_SIFT_FROM_LINES`), only those the same checks pass in numpy (a superset: the loop checks
    each again, so the result is the loop's, bit for bit)."""
    n = len(cand)
    if n < _SIFT_FROM_LINES:
        return itertools.combinations(range(n), 2)
    columns = np.array([(r.polarity, r.angle_deg, r.near_fx, r.near_fy, r.far_fx, r.far_fy,
                         r.near_y, r.far_y) for r in cand], dtype=np.float64)
    polarity, angle, near_fx, near_fy, far_fx, far_fy, near_y, far_y = columns.T
    if not np.isfinite(angle).all():
        return itertools.combinations(range(n), 2)  # (a line made by hand; never from Hough)
    i, j = pairs_within_angle(angle, angle_tol)
    if unsigned_outer:
        keep = (polarity[i] == 0.0) != (polarity[j] == 0.0)
    else:
        keep = polarity[i] * polarity[j] < 0.0
    keep &= np.abs(angle[i] - angle[j]) <= angle_tol
    # `measure_pair` measures a pair only on image rows both lines cover.
    keep &= ~(np.minimum(near_y[i], near_y[j]) <= np.maximum(far_y[i], far_y[j]))
    i, j = i[keep], j[keep]
    bx, by = far_fx[j] - near_fx[j], far_fy[j] - near_fy[j]
    rough = (np.abs(bx * (near_fy[i] - near_fy[j]) - by * (near_fx[i] - near_fx[j]))
             / np.maximum(np.hypot(bx, by), 1e-9))
    keep = ((rough >= tape_width / 3.0 * (1.0 - _SIFT_SLACK))
            & (rough <= 3.0 * tape_width * (1.0 + _SIFT_SLACK)))
    i, j = i[keep], j[keep]
    in_order = np.lexsort((j, i))  # the loop's order: by i, then j
    return zip(i[in_order].tolist(), j[in_order].tolist(), strict=True)


def darker_beyond(inner: LineRow, side: Side) -> bool:
    """Whether the tape beyond a signed line, as this side's INNER tape edge, is darker than the
    floor: its sign says which side of it is floor (a left edge lighter to its right)."""
    return (inner.polarity > 0) == (side == "left")


def of_configured_kind(inner: LineRow, side: Side, config: PerceptionConfig) -> bool:
    """Whether a signed line, as this side's INNER tape edge, belongs to a tape of the kind
    `tape.kind` says (always with `any`; `darker_beyond`)."""
    kind = config.tape.kind
    return kind == "any" or darker_beyond(inner, side) == (kind == "dark")


def verified_tapes(
    cand: list[LineRow],
    smooth_gray: NDArray[np.uint8],
    side: Side,
    view: FloorView,
    config: PerceptionConfig,
    look_ahead_m: float,
) -> list[TapeCandidate]:
    """The verified tapes among one side's candidates (width on the floor and band), best
    first, at most _MAX_TAPES_KEPT (`tape_candidates`, then `band_is_tape`)."""
    tapes = [t for t in tape_candidates(cand, side, view, config, look_ahead_m)
             if t.band_is_tape(smooth_gray, config)]
    return tapes[:_MAX_TAPES_KEPT]


def lane_fit(left: TapeCandidate, right: TapeCandidate, config: PerceptionConfig) -> float:
    """How well two tapes' inner edges make a lane on the floor: their distance (from where the
    left one was measured to the right one's line) against the free width
    (`PerceptionConfig.free_width_m`): 1 within `lane.width_tolerance_m` of it, 0 at twice;
    times how parallel they run, as the `parallel` confidence component scores it (1 within
    `lane.parallel_tolerance_deg`, 0 at twice). A lane's two tapes run parallel: a slat or
    strip across the lane can lie the lane's width from the other tape where it is measured,
    never along it."""
    r_near, r_dir = _floor_line(right.inner)
    return _lane_fit(left.at, _floor_line(left.inner)[1], r_near, r_dir, free_width_m(config),
                     config.lane)


def _floor_line(line: LineRow) -> tuple[Point, Point]:
    """A line's near end on the floor and its unit floor direction, towards its far end."""
    near = (line.near_fx, line.near_fy)
    return near, direction(near, (line.far_fx, line.far_fy))


def _lane_fit(left_at: Point, l_dir: Point, r_near: Point, r_dir: Point, free_m: float,
              lane: LaneConfig) -> float:
    """`lane_fit` of a left tape measured at `left_at` whose inner edge runs along `l_dir` and a
    right tape whose inner edge runs through `r_near` along `r_dir` (`_floor_line`)."""
    gap = distance_to_line(left_at, r_near, r_dir)
    return (ramp(gap - free_m, lane.width_tolerance_m)
            * ramp(floor_angle_deg(l_dir, r_dir), lane.parallel_tolerance_deg))


def pick_tapes(
    left: list[TapeCandidate],
    right: list[TapeCandidate],
    config: PerceptionConfig,
    accept: Callable[[TapeCandidate], bool] = lambda tape: True,
) -> tuple[TapeCandidate | None, TapeCandidate | None]:
    """One tape per side among those `accept` takes (the band check, asked only of the tapes
    that would be chosen): with tapes on both sides, the pair of the same kind (dark or light)
    that best fits the lane (`lane_fit`: its width, parallel edges), then the best width scores,
    then the nearest; otherwise
    each side's best (`TapeCandidate.rank`)."""
    return _pick_tapes(left, [t.rank() for t in left], right, [t.rank() for t in right], config,
                       accept, ranked=False)


def _pick_tapes(
    left: list[TapeCandidate],
    left_ranks: list[Rank],
    right: list[TapeCandidate],
    right_ranks: list[Rank],
    config: PerceptionConfig,
    accept: Callable[[TapeCandidate], bool],
    *,
    ranked: bool,
) -> tuple[TapeCandidate | None, TapeCandidate | None]:
    """`pick_tapes` with each tape's `rank()` given (`left_ranks`, `right_ranks`); `ranked`:
    each side's tapes are in rank order already, best first, ties in their first order
    (`tape_candidates`' order), so ordering them again would keep them as they are."""
    if len(left) == 1 and len(right) == 1:
        # One tape a side (most frames): nothing to order, the same questions in the same order.
        lt, rt = left[0], right[0]
        if accept(lt) and accept(rt):
            return lt, rt
        return (lt if accept(lt) else None), (rt if accept(rt) else None)
    combos = []
    if left and right:
        # (`lane_fit` of every combination, each tape's inner edge put on the floor once.)
        left_dirs = [_floor_line(t.inner)[1] for t in left]
        right_lines = [_floor_line(t.inner) for t in right]
        free_m, lane = free_width_m(config), config.lane
        combos = sorted(
            ((lt.dark == rt.dark,
              _lane_fit(lt.at, l_dir, *r_line, free_m, lane) * lt.score * rt.score,
              lt.score * rt.score, lr[1] + rr[1], lr[2] + rr[2], -i, -j)
             for i, (lt, lr, l_dir) in enumerate(zip(left, left_ranks, left_dirs, strict=True))
             for j, (rt, rr, r_line) in enumerate(zip(right, right_ranks, right_lines,
                                                       strict=True))),
            reverse=True,
        )
    for *_, neg_i, neg_j in combos:  # the indices are negated so that ties keep list order
        lt, rt = left[-neg_i], right[-neg_j]
        if accept(lt) and accept(rt):
            return lt, rt
    if ranked:
        return _best_accepted(left, None, accept), _best_accepted(right, None, accept)
    return _best_accepted(left, left_ranks, accept), _best_accepted(right, right_ranks, accept)


def _best_accepted(
    tapes: list[TapeCandidate],
    ranks: list[Rank] | None,
    accept: Callable[[TapeCandidate], bool],
) -> TapeCandidate | None:
    """The best ranked of `tapes` (their `rank()`s: `ranks`; None: `tapes` are in rank order
    already, as `tape_candidates` gives them) that `accept` takes (ties: the first)."""
    if ranks is None:
        for tape in tapes:
            if accept(tape):
                return tape
        return None
    order = sorted(range(len(tapes)), key=ranks.__getitem__, reverse=True)
    return next((tapes[i] for i in order if accept(tapes[i])), None)


def _side_choice(
    rows: list[LineRow],
    cand: list[LineRow],
    tape: TapeCandidate | None,
    smooth_gray: NDArray[np.uint8],
    side: Side,
    setup: SizeSetup,
    config: PerceptionConfig,
    fallback: Callable[[Side], TapeCandidate | None],
    other_tape: TapeCandidate | None = None,
) -> SideChoice | None:
    """The side's choice: its verified tape; else its best lone edge, unless that edge's
    profile does not say tape (or there is none) and `fallback` finds a tape whose outer edge
    has no sign (`tape_candidates(unsigned_outer=True)`). `other_tape`: the other side's
    verified tape, whose contrast a lone edge that cannot be checked must show (rule 3)."""
    height, width = smooth_gray.shape[:2]
    size = (width, height)
    dark: bool | None
    single = None
    if tape is None:
        single = _best_single(rows, cand, smooth_gray, side, setup, config, other_tape)
        if single is None or single[1] < config.tape.min_profile_fraction:
            tape = fallback(side)
    if tape is not None:
        chain = follow_edge(rows, tape.inner.line_id, size, config)
        partner: int | None = tape.outer.line_id
        verified, score, width_m, dark = True, tape.score, tape.width_m, tape.dark
    else:
        if single is None:
            return None
        chain, score = single
        partner, verified, width_m, dark = None, False, None, None
    near = rows[chain[0]]
    x2, y2 = _chain_point_at(rows, chain, setup.look_ahead_row)
    return SideChoice(side, chain, partner, verified, score, width_m, dark, near.polarity,
                      _support(rows, chain), near.near_x, near.near_y, x2, y2)


def _support(rows: list[LineRow], chain: tuple[int, ...]) -> float:
    """Total length of a chain's Hough segments (`SideChoice.support_px`), summed in chain
    order."""
    return sum([rows[k].support_px for k in chain])


def _best_single(
    rows: list[LineRow],
    cand: list[LineRow],
    smooth_gray: NDArray[np.uint8],
    side: Side,
    setup: SizeSetup,
    config: PerceptionConfig,
    other_tape: TapeCandidate | None = None,
) -> tuple[tuple[int, ...], float] | None:
    """(chain, tape score) of the best lone edge on a side without a verified tape
    (`other_tape`: as in `_side_choice`)."""
    if not cand:
        return None
    height, width = smooth_gray.shape[:2]
    polar = sorted((r for r in cand if r.polarity != 0 and of_configured_kind(r, side, config)),
                   key=lambda r: -r.support_px)
    # nothing signed (of the configured kind): the strongest line of no sign, or with no kind
    # configured the strongest line at all (never a line whose sign says the other kind)
    plain = cand if config.tape.kind == "any" else [r for r in cand if r.polarity == 0]
    if not polar and not plain:
        return None
    singles = polar or [max(plain, key=lambda r: r.support_px)]
    preference = config.tape.unpaired_preference
    best: tuple[float, tuple[int, ...], float] | None = None
    # The profile is a function of the chain alone, and the strongest lines of one bending
    # edge often follow into the same chain: read each chain's profile once.
    profiles: dict[tuple[int, ...], float | None] = {}
    view, side_tape = setup.view, config.tape.for_side(side)
    for line in singles[:_MAX_SINGLE_CHECKS]:
        if best is not None and line.support_px * _CHAIN_BONUS_LIMIT <= best[0]:
            break  # even a chain of four times its own length could not win
        chain = follow_edge(rows, line.line_id, (width, height), config)
        support = _support(rows, chain)
        if best is not None and support <= best[0]:
            continue  # cannot win even as a perfect tape edge: skip the profile
        if chain in profiles:
            fraction = profiles[chain]
        else:
            fraction = profiles[chain] = tape_profile_fraction(smooth_gray, rows, chain, side,
                                                               view, side_tape)
        if fraction is None and not fainter_than_tape(line, other_tape):
            # The tape's far side would be outside the image: nothing to check it against.
            score, factor = config.tape.unverifiable_score, config.tape.unverifiable_score
        elif fraction is None:
            score, factor = 0.0, preference  # too faint for the tape the other side shows
        elif fraction >= config.tape.min_profile_fraction:
            score, factor = fraction, fraction
        else:
            score, factor = 0.0, preference
        value = support * factor
        if best is None or value > best[0]:
            best = (value, chain, score)
    assert best is not None
    return best[1], best[2]


def fainter_than_tape(line: LineRow, tape: TapeCandidate | None) -> bool:
    """Whether `line` steps less than UNVERIFIABLE_MIN_CONTRAST_SHARE as strongly as `tape`'s
    inner edge (never without a tape, or where either contrast was not measured)."""
    if tape is None:
        return False
    return abs(line.contrast) < UNVERIFIABLE_MIN_CONTRAST_SHARE * abs(tape.inner.contrast)


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


def follow_edge(
    rows: list[LineRow], start: int, size: tuple[int, int], config: PerceptionConfig
) -> tuple[int, ...]:
    """The chain of lines continuing `start` away from the robot and towards it: same polarity,
    an end within the chain gap, turning by at most `chain_max_turn_deg`."""
    width, height = size
    first = rows[start]
    polarity = first.polarity
    usable = ([r for r in rows if r.line_id != start] if polarity == 0
              else [r for r in rows if r.polarity == polarity and r.line_id != start])
    if not usable:
        return (start,)
    gap, max_turn, on_line_px = _chain_rules(config.edges, width, height)
    away = _extend(first, usable, gap, max_turn, on_line_px, away=True)
    towards = _extend(first, usable, gap, max_turn, on_line_px, away=False)
    if not away and not towards:
        return (start,)
    return tuple([r.line_id for r in reversed(towards)] + [start] + [r.line_id for r in away])


def _derive_chain_rules(edges: EdgesConfig, width: int,
                        height: int) -> tuple[float, float, float]:
    return (edges.chain_gap_frac_of_height * height, edges.chain_max_turn_deg,
            max(1.5, 0.5 * edges.cluster_offset_frac_of_width * width))


#: (chain gap, `chain_max_turn_deg`, on-line tolerance in pixels) that `follow_edge` follows a
#: chain by at an image size, kept per config and size (the config's fields cost about as much
#: as following a short chain).
_chain_rules: KeptPerObject[EdgesConfig, tuple[float, float, float]] = KeptPerObject(
    _derive_chain_rules)


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
    quarter of the gap, its end then on the current line's extension within twice
    `on_line_px`), or, when it overlaps more, lies on it across the overlap (within
    `on_line_px`: the same edge split by Hough). A line running alongside at a few pixels is a
    neighbour (a seam beside a tape edge), not the same edge. Across a gap, the step from one
    line's end to the next one's must itself run within `max_turn` of the current direction: a
    bending edge continues forwards, it does not jump sideways onto a seam beside it. Of the
    lines that pass, the nearest is taken, but one much fainter than the current line
    (CHAIN_MIN_CONTRAST_SHARE) only when no other passes: a seam crossing the edge is not its
    continuation."""
    found: list[LineRow] = []
    overlap = 0.25 * gap
    min_cos = math.cos(math.radians(max_turn))
    two_on_line = 2.0 * on_line_px
    hypot = math.hypot
    # (The current line's values are bound once per step, and a line farther than the best so
    # far is passed over before the checks that could only refuse it: the same choice.)
    # `pool`: the usable lines that still reach past the chain's end, in their order. The end
    # only moves on (away: up the image, by more than a row a step; towards: down), so a line
    # that did not reach past it never will, and later steps pass it over without a look.
    pool = usable
    for _ in range(_MAX_CHAIN_STEPS):
        best: LineRow | None = None
        best_dist = gap
        best_faint = False
        # (a continuation stepping less than CHAIN_MIN_CONTRAST_SHARE as strongly as the current
        # line is "faint"; never where either contrast was not measured: NaN compares False)
        faint_below = CHAIN_MIN_CONTRAST_SHARE * abs(current.contrast)
        c_angle, c_ux, c_uy = current.angle_deg, current.ux, current.uy
        c_cx, c_cy = current.cx, current.cy
        if away:
            end_x, end_y = current.far_x, current.far_y
        else:
            end_x, end_y = current.near_x, current.near_y
        beyond = end_y - 1.0 if away else end_y + 1.0  # (a line must reach past this row)
        if beyond != beyond:
            pool = usable  # (no row to compare with (NaN): every line is looked at, as before)
        reaching: list[LineRow] = []
        for r in pool:
            if away:
                if r.far_y >= beyond:
                    continue
            elif r.near_y <= beyond:
                continue
            reaching.append(r)
            if abs(r.angle_deg - c_angle) > max_turn:
                continue
            if away:
                shared = r.near_y - end_y  # rows both lines cover
                step_x, step_y = r.near_x - end_x, r.near_y - end_y
            else:
                shared = end_y - r.far_y
                step_x, step_y = r.far_x - end_x, r.far_y - end_y
            dist = hypot(step_x, step_y)
            faint = abs(r.contrast) < faint_below
            if faint and best is not None and not best_faint:
                continue  # a faint line never displaces one that steps like the current line
            stronger = best_faint and not faint
            if dist > (gap if stronger else best_dist):
                continue
            if shared > overlap:
                mid = (end_y + shared / 2.0) if away else (end_y - shared / 2.0)
                # (`LineRow.x_at` of both lines, written out)
                if abs(r.cx + (mid - r.cy) * r.ux / r.uy
                       - (c_cx + (mid - c_cy) * c_ux / c_uy)) > on_line_px:
                    continue
            elif shared > 0.0:
                # It overlaps a little (Hough's pieces of a curve do): it must start on the
                # current line's extension, not beside it.
                if abs(step_x * c_uy - step_y * c_ux) > two_on_line:
                    continue
            elif dist > two_on_line:
                forward = c_ux * step_x + c_uy * step_y
                if (forward if away else -forward) < min_cos * dist:
                    continue
            if dist <= best_dist or stronger:
                best, best_dist, best_faint = r, dist, faint
        if best is None:
            break
        found.append(best)
        usable.remove(best)
        reaching.remove(best)
        pool = reaching
        current = best
    return found
