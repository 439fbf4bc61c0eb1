"""From Hough segments to candidate lines: drop flat segments, merge collinear ones, measure each
line's brightness polarity.

A `LineSet` holds every candidate line of one frame as parallel numpy arrays (struct of arrays, so
the per-frame work is a handful of vectorised operations rather than Python loops over segments).
Pixels: x right, y down; each line runs from its NEAR end (larger y) to its FAR end, and its unit
direction (ux, uy) points from near to far (uy <= 0).

Each line also carries where its near and far ends lie on the floor (robot frame metres, through
the ground model; NaN at or above the horizon), for the metric rules of edge choice.

Polarity: the sign of (brightness right of the line - brightness left of it), the median over a
few points along the line on the blurred image, a cheap stand-in for the Sobel sign across it
(the median, so a highlight crossing part of a glossy tape does not overturn it; and where the
least-lit half of the points clearly says the other sign, that half: a highlight covering more
than half of the edge, see `_polarity`).
+1 dark-to-light going right, -1 light-to-dark, 0 no clear contrast. The two edges of a tape have
opposite polarities (dark tape on a light floor: -1 then +1; light tape: +1 then -1).

Pure functions of their inputs: never draws. Per-segment arithmetic is numpy; the greedy
clustering pass alone loops in Python, over ints used as bit sets (see `_cluster_collinear`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.config import EdgesConfig
from lanewarden.perception.floor_config import TapeConfig
from lanewarden.perception.floor_view import FloorView

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Polarity is read at this many times `tape.polarity_samples` points along a line: its median
#: then holds while a highlight covers up to nearly half of the line, and the least-lit half of
#: them (see `_polarity`) is still a median of several points (cheap: one gather).
POLARITY_SAMPLE_FACTOR = 3
#: Where the median step says "no contrast", a line's polarity is the sign that at least this
#: share of its points show clearly, in one unbroken run from one end of the line...
POLARITY_VOTE_SHARE = 0.25
#: ...and at least this many times as many points as show the other sign (see `_vote`).
POLARITY_VOTE_MARGIN = 4


@dataclass(frozen=True)
class LineSet:
    """Candidate lines of one frame (all arrays have the same length n).

    - `angle_deg`: direction near->far, counter-clockwise from +x with y up (see geometry).
    - `cx, cy`: a point on the line (support-weighted centre of its segments), pixels.
    - `ux, uy`: unit direction near->far (uy <= 0, image y down).
    - `near_x, near_y, far_x, far_y`: the extent of its segments along the line.
    - `support_px`: total length of its segments.
    - `polarity`: +1, -1 or 0 (see module docstring).
    - `contrast`: the median brightness step across the line (right side minus left side, grey
      levels, at the polarity samples): how strongly it shows, whatever its polarity says.
    - `x_bottom`: column where the line crosses the ROI's bottom row.
    - `near_fx, near_fy, far_fx, far_fy`: its near and far ends on the floor, robot frame metres.
    - `segment_label`: for each input segment, the line it joined (-1: dropped as flat).
    """

    angle_deg: FloatArray
    cx: FloatArray
    cy: FloatArray
    ux: FloatArray
    uy: FloatArray
    near_x: FloatArray
    near_y: FloatArray
    far_x: FloatArray
    far_y: FloatArray
    support_px: FloatArray
    polarity: FloatArray
    x_bottom: FloatArray
    near_fx: FloatArray
    near_fy: FloatArray
    far_fx: FloatArray
    far_fy: FloatArray
    segment_label: IntArray
    contrast: FloatArray

    def __len__(self) -> int:
        return int(self.angle_deg.shape[0])

    def x_at(self, index: int | IntArray, row: float | FloatArray) -> FloatArray:
        """Column(s) where line(s) `index` cross image row(s) `row`."""
        return np.asarray(
            self.cx[index] + (row - self.cy[index]) * self.ux[index] / self.uy[index]
        )


    def rows(self) -> list[LineRow]:
        """The lines as plain-float rows, for the per-line logic of edge choice."""
        columns = (
            self.angle_deg, self.cx, self.cy, self.ux, self.uy, self.near_x, self.near_y,
            self.far_x, self.far_y, self.support_px, self.polarity, self.x_bottom,
            self.near_fx, self.near_fy, self.far_fx, self.far_fy, self.contrast,
        )
        values = zip(*(c.tolist() for c in columns), strict=True)
        return [LineRow(i, *row) for i, row in enumerate(values)]


class LineRow(NamedTuple):
    """One line of a `LineSet` as plain floats (same fields; `line_id` is its position)."""

    line_id: int
    angle_deg: float
    cx: float
    cy: float
    ux: float
    uy: float
    near_x: float
    near_y: float
    far_x: float
    far_y: float
    support_px: float
    polarity: float
    x_bottom: float
    near_fx: float
    near_fy: float
    far_fx: float
    far_fy: float
    #: NaN: not measured (a line made by hand); `LineSet.rows` always gives it.
    contrast: float = math.nan

    def x_at(self, row: float) -> float:
        """Column where the line crosses image row `row`."""
        return self.cx + (row - self.cy) * self.ux / self.uy


_EMPTY_F = np.zeros(0, dtype=np.float64)
#: A segment's columns with its two ends swapped.
_REVERSED = [2, 3, 0, 1]


def empty_line_set(segment_count: int = 0) -> LineSet:
    e = _EMPTY_F
    return LineSet(
        angle_deg=e, cx=e, cy=e, ux=e, uy=e, near_x=e, near_y=e, far_x=e, far_y=e,
        support_px=e, polarity=e, x_bottom=e, near_fx=e, near_fy=e, far_fx=e, far_fy=e,
        segment_label=np.full(segment_count, -1, dtype=np.intp), contrast=e,
    )


def _sum_by(label: IntArray, weights: FloatArray, n: int) -> FloatArray:
    """Per-line sums of `weights` (np.bincount, typed)."""
    return np.bincount(label, weights=weights, minlength=n).astype(np.float64, copy=False)


def build_line_set(
    segments: NDArray[np.int32] | None,
    smooth_gray: NDArray[np.uint8],
    y_bottom: float,
    floor: FloorView,
    edges: EdgesConfig,
    tape: TapeConfig,
) -> LineSet:
    """Group HoughLinesP output (N, 1, 4) into candidate lines and measure their polarity.

    Near-horizontal segments are dropped. The remaining ones are clustered greedily, longest
    first: a segment joins a longer one's line when its direction is within
    `cluster_angle_tol_deg` and its midpoint lies within `cluster_offset_frac_of_width` of that
    line (collinear pieces: Hough's broken edge, dashes of one tape). `floor` is the ground
    model of this image size (undistorted pixels).
    """
    if segments is None or len(segments) == 0:
        return empty_line_set()
    seg, angle = _oriented_segments(segments)
    min_h = edges.min_angle_from_horizontal_deg
    kept = np.nonzero((angle >= min_h) & (angle <= 180.0 - min_h))[0]
    if len(kept) == 0:
        return empty_line_set(len(seg))
    width = smooth_gray.shape[1]
    offset_tol = max(edges.cluster_offset_frac_of_width * width, 1.0)
    pieces = (_Pieces.of(seg, angle) if len(kept) == len(seg)
              else _Pieces.of(seg[kept], angle[kept]))
    line_of, lines = _cluster_collinear(pieces, edges.cluster_angle_tol_deg, offset_tol)
    label = np.full(len(seg), -1, dtype=np.intp)
    label[kept] = line_of
    fit = _fit_lines(pieces, line_of, lines)
    x_bottom = fit.cx + (y_bottom - fit.cy) * fit.ux / np.minimum(fit.uy, -1e-9)
    polarity, contrast = _polarity(smooth_gray, fit.near_x, fit.near_y, fit.far_x, fit.far_y,
                                   fit.ux, fit.uy, tape)
    count = len(fit.cx)
    ends_x, ends_y = floor.to_floor_many(np.concatenate([fit.near_x, fit.far_x]),
                                         np.concatenate([fit.near_y, fit.far_y]))
    return LineSet(
        angle_deg=np.degrees(np.arctan2(-fit.uy, fit.ux)),
        cx=fit.cx,
        cy=fit.cy,
        ux=fit.ux,
        uy=fit.uy,
        near_x=fit.near_x,
        near_y=fit.near_y,
        far_x=fit.far_x,
        far_y=fit.far_y,
        support_px=fit.support_px,
        polarity=polarity,
        x_bottom=x_bottom,
        near_fx=ends_x[:count],
        near_fy=ends_y[:count],
        far_fx=ends_x[count:],
        far_fy=ends_y[count:],
        segment_label=label,
        contrast=contrast,
    )


def _oriented_segments(segments: NDArray[np.int32]) -> tuple[FloatArray, FloatArray]:
    """Segments (N, 4) as floats running near (bottom) -> far (top), and their angle from the
    image's x axis with y up, degrees in [0, 180]."""
    raw = segments.reshape(-1, 4)
    seg = np.where((raw[:, 1] < raw[:, 3])[:, None], raw[:, _REVERSED], raw).astype(np.float64)
    angle = np.degrees(np.arctan2(seg[:, 1] - seg[:, 3], seg[:, 2] - seg[:, 0]))
    return seg, angle


@dataclass(frozen=True)
class _Pieces:
    """The kept segments, oriented near -> far, with what clustering and fitting both need:
    their run (`dx`, `dy`: pixels, y down), length, midpoint and angle (degrees, y up)."""

    seg: FloatArray
    dx: FloatArray
    dy: FloatArray
    length: FloatArray
    mid_x: FloatArray
    mid_y: FloatArray
    angle: FloatArray

    @staticmethod
    def of(seg: FloatArray, angle: FloatArray) -> _Pieces:
        dx, dy = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
        return _Pieces(seg=seg, dx=dx, dy=dy, length=np.hypot(dx, dy),
                       mid_x=0.5 * (seg[:, 0] + seg[:, 2]), mid_y=0.5 * (seg[:, 1] + seg[:, 3]),
                       angle=angle)


def _cluster_collinear(pieces: _Pieces, angle_tol_deg: float,
                       offset_tol_px: float) -> tuple[NDArray[np.intp], int]:
    """Greedy leader clustering, longest segment first: the line index of every segment, and
    the number of lines. A
    segment joins the leader's line when its direction is within `angle_tol_deg` and its
    midpoint within `offset_tol_px` of the leader's line (a precomputed compatibility matrix).

    The greedy pass runs on Python ints used as bit sets (bit j: segment j), one per segment
    for the segments compatible with it, plus the set of segments still free: a few dozen
    segments make a few lines, and this saves the few numpy calls per line the pass needed."""
    count = len(pieces.angle)
    compatible_with: list[int]
    if count <= _DENSE_UP_TO:  # each row's bits in one 64-bit word: one conversion for all rows
        packed = np.packbits(_compatible_dense(pieces, angle_tol_deg, offset_tol_px), axis=1,
                             bitorder="little")
        words = np.zeros((count, 8), dtype=np.uint8)
        words[:, :packed.shape[1]] = packed
        compatible_with = words.view("<u8").ravel().tolist()
    else:  # few pairs are compatible: each row's bits set one by one
        compatible_with = [0] * count
        rows, columns = _compatible_pairs(pieces, angle_tol_deg, offset_tol_px)
        for row, column in zip(rows.tolist(), columns.tolist(), strict=True):
            compatible_with[row] |= 1 << column
    line_of = [-1] * count
    free = (1 << count) - 1
    lines = 0
    for leader in np.argsort(-pieces.length, kind="stable").tolist():
        if not (free >> leader) & 1:
            if not free:
                break  # every segment has its line
            continue
        member = (compatible_with[leader] & free) | (1 << leader)
        free &= ~member
        while member:
            lowest = member & -member
            line_of[lowest.bit_length() - 1] = lines
            member ^= lowest
        lines += 1
    return np.array(line_of, dtype=np.intp), lines


#: Up to this many segments the compatibility matrix is computed whole; beyond it (a textured
#: floor: terrazzo's chips give 500 and more at 320x240) only for the pairs whose directions
#: are within the angle tolerance (`_compatible_pairs`), a few percent of them.
_DENSE_UP_TO = 64


def _compatible_dense(pieces: _Pieces, angle_tol_deg: float,
                      offset_tol_px: float) -> NDArray[np.bool_]:
    """[i, j]: `_compatible` for every pair of segments (the whole arrays broadcast against
    each other: no gathers)."""
    return _compatible(pieces, np.s_[:, None], np.s_[None, :], angle_tol_deg, offset_tol_px)


def _compatible_pairs(pieces: _Pieces, angle_tol_deg: float,
                      offset_tol_px: float) -> tuple[IntArray, IntArray]:
    """The (i, j) where `_compatible_dense` is True, exactly those, computed only for the pairs
    `pairs_within_angle` puts together."""
    i, j = pairs_within_angle(pieces.angle, angle_tol_deg, unordered=False)
    ok = _compatible(pieces, i, j, angle_tol_deg, offset_tol_px)
    return i[ok], j[ok]


#: Which segments `_compatible` compares: an index array, or an index expression such as
#: `np.s_[:, None]` (numpy's stubs type the two through different overloads).
_Which = Any


def _compatible(pieces: _Pieces, i: _Which, j: _Which, angle_tol_deg: float,
                offset_tol_px: float) -> NDArray[np.bool_]:
    """For segments `i` and `j` (index arrays, or index expressions such as `np.s_[:, None]`,
    broadcast together): whether segment j's direction lies within `angle_tol_deg` of segment
    i's and its midpoint within `offset_tol_px` of segment i's line."""
    dir_x, dir_y = pieces.dx / pieces.length, pieces.dy / pieces.length
    off_line = np.abs((pieces.mid_x[j] - pieces.mid_x[i]) * dir_y[i]
                      - (pieces.mid_y[j] - pieces.mid_y[i]) * dir_x[i])
    return np.asarray((np.abs(pieces.angle[j] - pieces.angle[i]) <= angle_tol_deg)
                      & (off_line <= offset_tol_px))


def pairs_within_angle(angle: FloatArray, tol_deg: float, *,
                       unordered: bool) -> tuple[IntArray, IntArray]:
    """The index pairs (i, j) whose `angle`s (finite) differ by at most `tol_deg`, found through
    a window over the sorted angles, so without looking at the others: every ordered pair, (i, i)
    included, or with `unordered` each pair of two indices once, as (smaller, larger). The
    window is a hair wider than `tol_deg` (callers check each pair exactly), so no pair within it
    is ever missed."""
    count = len(angle)
    order = np.argsort(angle, kind="stable")
    ordered = angle[order]
    reach = tol_deg * (1.0 + 1e-9) + 1e-9
    hi = np.searchsorted(ordered, ordered + reach, side="right")
    lo = (np.arange(1, count + 1) if unordered
          else np.searchsorted(ordered, ordered - reach, side="left"))
    width = hi - lo
    first = np.repeat(np.arange(count), width)
    starts = np.cumsum(width) - width
    second = lo[first] + (np.arange(int(width.sum())) - np.repeat(starts, width))
    i, j = order[first], order[second]
    if unordered:
        return np.minimum(i, j), np.maximum(i, j)
    return i, j


@dataclass(frozen=True)
class _LineFit:
    """Per line: the support-weighted unit direction (`ux`, `uy`: pixels, y down, pointing
    far), centre (`cx`, `cy`), its near and far ends, and its support (total segment length)."""

    ux: FloatArray
    uy: FloatArray
    cx: FloatArray
    cy: FloatArray
    near_x: FloatArray
    near_y: FloatArray
    far_x: FloatArray
    far_y: FloatArray
    support_px: FloatArray


def _fit_lines(pieces: _Pieces, line_of: NDArray[np.intp], lines: int) -> _LineFit:
    """Each of the `lines` lines from its member segments (oriented near -> far): direction and
    centre weighted by length; its extent is the lowest and highest projection of its members'
    ends on it (all members run near -> far within a few degrees of the line)."""
    seg = pieces.seg
    x1, y1, x2, y2 = seg[:, 0], seg[:, 1], seg[:, 2], seg[:, 3]
    length = pieces.length
    support = _sum_by(line_of, length, lines)
    ux = _sum_by(line_of, pieces.dx, lines)  # sum(unit * length)
    uy = _sum_by(line_of, pieces.dy, lines)
    norm = np.hypot(ux, uy)
    ux, uy = ux / norm, uy / norm
    cx = _sum_by(line_of, pieces.mid_x * length, lines) / support
    cy = _sum_by(line_of, pieces.mid_y * length, lines) / support
    # Each segment's line's centre and direction, gathered once for both ends.
    seg_cx, seg_cy, seg_ux, seg_uy = cx[line_of], cy[line_of], ux[line_of], uy[line_of]
    along_near = (x1 - seg_cx) * seg_ux + (y1 - seg_cy) * seg_uy
    along_far = (x2 - seg_cx) * seg_ux + (y2 - seg_cy) * seg_uy
    lowest = np.full(lines, np.inf)
    highest = np.full(lines, -np.inf)
    np.minimum.at(lowest, line_of, np.minimum(along_near, along_far))
    np.maximum.at(highest, line_of, np.maximum(along_near, along_far))
    return _LineFit(ux=ux, uy=uy, cx=cx, cy=cy,
                    near_x=cx + lowest * ux, near_y=cy + lowest * uy,
                    far_x=cx + highest * ux, far_y=cy + highest * uy, support_px=support)


@functools.cache
def _sample_fractions(k: int) -> FloatArray:
    """Where `k` points are sampled along a line: the middles of k equal parts (0..1)."""
    fractions = (np.arange(k, dtype=np.float64) + 0.5) / k
    fractions.flags.writeable = False
    return fractions


@functools.cache
def _image_limits(width: int, height: int) -> FloatArray:
    """The largest column and row of a `width` x `height` image, shaped (2, 1, 1) to clip
    stacked (x, y) sample points."""
    limits = np.array((width - 1.0, height - 1.0)).reshape(2, 1, 1)
    limits.flags.writeable = False
    return limits


def _polarity(
    gray: NDArray[np.uint8],
    near_x: FloatArray,
    near_y: FloatArray,
    far_x: FloatArray,
    far_y: FloatArray,
    ux: FloatArray,
    uy: FloatArray,
    tape: TapeConfig,
) -> tuple[FloatArray, FloatArray]:
    """(polarity, contrast) of each line. Its contrast: the median of (right side - left side)
    brightness over a few points sampled along it. Its polarity: the sign of that median (0
    when it is within `min_contrast_levels`), or the sign of the median over
    the least-lit half of them (the half whose darker side is darkest) when that is a clear
    step of the other sign, or of any sign where the median and the vote said none and the
    steps show a mirrored light along a tape (see below)."""
    height, width = gray.shape[:2]
    k = POLARITY_SAMPLE_FACTOR * tape.polarity_samples
    offset = max(tape.polarity_offset_frac_of_width * width, 1.5)
    # The sample points, x and y stacked (2, n, k): near + (far - near) * fraction (stacked, the
    # dozen numpy calls of the two coordinates are half as many: this runs on every frame).
    start = np.array((near_x, near_y))
    run = np.array((far_x, far_y))
    run -= start
    points = run[:, :, None] * _sample_fractions(k)
    points += start[:, :, None]
    # Normal pointing to +x ("right of the line"): (-uy, ux), since uy <= 0, and its opposite.
    # One gather for both sides: rows 0..n-1 right of the lines, n..2n-1 left of them.
    right_x, right_y = -uy * offset, ux * offset
    normals = np.array(((right_x, right_y), (-right_x, -right_y)))  # (side, x|y, n)
    sides = (points[:, None] + normals.transpose(1, 0, 2)[:, :, :, None]).reshape(2, -1, k)
    sides += 0.5
    np.maximum(sides, 0.0, out=sides)
    np.minimum(sides, _image_limits(width, height), out=sides)
    pixel = sides.astype(np.intp)
    values = gray[pixel[1], pixel[0]].astype(np.int16)
    n = len(near_x)
    right, left = values[:n], values[n:]
    step = right - left
    threshold = tape.min_contrast_levels
    # (For whole-number steps, step > t exactly when step > floor(t): compared as ints, twice
    # as fast as against a float.)
    whole_threshold = math.floor(threshold)
    # The median step, not the mean: a ceiling light mirrored in glossy tape makes a few samples
    # of its edges brighter on the tape's side than the floor by far more than the tape is darker
    # elsewhere, and their mean says "no contrast" (or the wrong sign).
    contrast = _median(step)
    whole = _signs(contrast, threshold)
    # Where a tape has a gap (a worn patch, a dash gap, the gap of a broken line coming into
    # view), the points in it show no step at all, and the median says "no contrast" once the
    # gap covers half the line. There, the sign that a quarter of the points in a row show
    # clearly, with at least twice as many points as show the other sign, is the line's.
    up, down = step > whole_threshold, step < -whole_threshold
    n_up, n_down = up.sum(axis=1), down.sum(axis=1)
    unclear = np.nonzero(whole == 0.0)[0]
    if unclear.size:
        whole[unclear] = _vote(up[unclear], down[unclear], n_up[unclear], n_down[unclear])
    # The light can also cover more than half of an edge, and turn the median. It only ADDS
    # light, to the side it lies on: where the edge's darker side is darkest, nothing is
    # mirrored. So where the median step over the least-lit half of the points (by the darker
    # side's brightness) is a clear step of the other sign, it wins. Only a clear reversal:
    # on a textured floor the least-lit half of a line picks its dark specks and would give
    # lines of no contrast a polarity (more candidate pairs to refute). A half's median is a
    # clear step against the line's sign only where at least half of the half's points (the
    # lower middle one included) are, so only lines with that many such steps are read.
    #
    # A row of lights mirrored along a tape can also leave the edge with no sign at all: lit
    # points stepping one way, unlit ones the other, neither four times the other, no run from
    # an end (campaign runs r00412, r00718 of the ninth run). Such a line is read where it is
    # least lit too, but only on the evidence a mirrored light leaves and a textured floor or a
    # patch beside a line does not: at least three quarters of the least-lit half step clearly
    # one way; a quarter of the points step clearly the other way (the light, lighter than the
    # floor, enough of it to be what hid the median); and the unlit steps reach both halves of
    # the line (a tape along all of it, not a patch).
    # A line of no sign is only read at all when both signs show on a quarter of its points:
    # that guard is the mirrored-light reading's "a quarter lit the other way" (the unlit
    # half's own sign is the other quarter), and it spares the others the sort.
    half = k // 2
    against = np.where(whole > 0.0, n_down, np.where(whole < 0.0, n_up, np.minimum(n_up, n_down)))
    quarter = (half - 1) // 2 + 1
    rows = np.nonzero(against >= quarter)[0]
    if rows.size:
        least_lit = np.argsort(np.minimum(right[rows], left[rows]), axis=1,
                               kind="stable")[:, :half]
        unlit = _signs(_median(np.take_along_axis(step[rows], least_lit, axis=1)), threshold)
        was = whole[rows]
        rising = (unlit > 0.0)[:, None]
        same = np.where(rising, up[rows], down[rows])
        unlit_same = np.take_along_axis(same, least_lit, axis=1).sum(axis=1)
        mirrored = ((was == 0.0) & (unlit != 0.0)
                    & (4 * unlit_same >= 3 * half)
                    & same[:, :half].any(axis=1) & same[:, half:].any(axis=1))
        whole[rows] = np.where((was * unlit < 0.0) | mirrored, unlit, was)
    return whole, contrast


def _vote(up: NDArray[np.bool_], down: NDArray[np.bool_], n_up: IntArray,
          n_down: IntArray) -> FloatArray:
    """Per row, from which points step up (`up`) and down (`down`) clearly, and how many: +1
    where at least `POLARITY_VOTE_SHARE` of the points step up, in one run from one end of the
    line unbroken but for gaps of one or two points (`_bridged`), and at least
    `POLARITY_VOTE_MARGIN` times as many points step up as down; -1 the other way round; 0
    otherwise. (A run from an end: a gap leaves the rest of a tape in one piece that runs to the
    line's end, while on a speckled floor, or across a patchy one where a stretch of lighter
    slats or chips happens to line up mid-line, a line of no contrast has no such run.)

    Each row's points as the bits of a Python int (bit j: point j): the few rows this is asked
    about cost a few integer operations each, where the same on boolean arrays took twenty-odd
    numpy calls."""
    k = up.shape[1]
    need = math.ceil(POLARITY_VOTE_SHARE * k)
    first = (1 << need) - 1  # the first `need` points
    last = first << (k - need)  # the last `need` points
    rising_bits, falling_bits = _RowBits(up), _RowBits(down)
    votes = []
    for row, (n_rising, n_falling) in enumerate(zip(n_up.tolist(), n_down.tolist(),
                                                    strict=True)):
        if (n_rising >= need and n_rising >= POLARITY_VOTE_MARGIN * n_falling
                and _run_from_an_end(_bridged(rising_bits[row]), first, last)):
            votes.append(1.0)
        elif (n_falling >= need and n_falling >= POLARITY_VOTE_MARGIN * n_rising
              and _run_from_an_end(_bridged(falling_bits[row]), first, last)):
            votes.append(-1.0)
        else:
            votes.append(0.0)
    return np.array(votes, dtype=np.float64)


class _RowBits:
    """The rows of a boolean array as Python ints (`bits[row]`: bit j is the row's value j),
    packed once, each row's int made when asked for (most rows fail the vote's counts first)."""

    def __init__(self, flags: NDArray[np.bool_]) -> None:
        packed = np.packbits(flags, axis=1, bitorder="little")
        self._data, self._size = packed.tobytes(), packed.shape[1]

    def __getitem__(self, row: int) -> int:
        start = row * self._size
        return int.from_bytes(self._data[start:start + self._size], "little")


def _bridged(bits: int) -> int:
    """`bits` (a row of points, bit j: point j) with each gap of one or two unset bits between
    set ones filled: a point or two of a dash's far end can show no clear step (the tape a few
    pixels wide there, a speck of noise) without breaking its run. A gap of three or more still
    breaks it (its middle point may be filled, its ends are not)."""
    before = (bits << 1) | (bits << 2)  # bit j: point j-1 or j-2 set
    after = (bits >> 1) | (bits >> 2)  # bit j: point j+1 or j+2 set (none beyond the row)
    return bits | (before & after)


def _run_from_an_end(bits: int, first: int, last: int) -> bool:
    """Whether all the bits of `first` (the row's first points), or all those of `last` (its last
    points), are set in `bits`."""
    return bits & first == first or bits & last == last


def _median(values: NDArray[np.int16]) -> FloatArray:
    """Per row, the median (exact in whole numbers: the middle two of the sorted values)."""
    ordered = np.sort(values, axis=1)
    m = ordered.shape[1]
    return np.asarray(0.5 * (ordered[:, (m - 1) // 2] + ordered[:, m // 2]), dtype=np.float64)


def _signs(median: FloatArray, threshold: float) -> FloatArray:
    """+1 above `threshold`, -1 below minus it, 0 between (the two tests' difference as floats:
    never -0.0)."""
    return np.subtract(median > threshold, median < -threshold, dtype=np.float64)


def line_angle_deg(ux: float, uy: float) -> float:
    """Angle (y up, degrees) of a unit direction in image coordinates."""
    return math.degrees(math.atan2(-uy, ux))
