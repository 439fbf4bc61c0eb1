"""From Hough segments to candidate lines: drop flat segments, merge collinear ones, measure each
line's brightness polarity.

A `LineSet` holds every candidate line of one frame as parallel numpy arrays (struct of arrays, so
the per-frame work is a handful of vectorised operations rather than Python loops over segments).
With a few dozen segments and a few lines a frame, what those operations cost is numpy's price per
call, not the arithmetic: the numbers of each segment and of each line are kept as the rows of one
block, ordered so that the ones worked on together are adjacent and one call serves them all.
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
from typing import Any, NamedTuple, cast

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
        # Each row straight from its tuple of values (`tuple.__new__`, as `LineRow._make` does,
        # without the keyword-checking constructor: this runs on every frame).
        count = len(self.angle_deg)
        values = zip(range(count), *map(np.ndarray.tolist, columns), strict=True)
        return list(map(tuple.__new__, [LineRow] * count, values))


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


def _operand(value: float, dtype: type[np.generic] = np.float64) -> NDArray[Any]:
    """`value` as a read-only 0-d array, for a number that meets the frame's arrays on every
    frame: numpy converts a Python number operand on every call, a third of what a comparison
    or product on a few dozen values costs, and a 0-d array of the arrays' type gives the
    same results."""
    operand = np.array(value, dtype=dtype)
    operand.flags.writeable = False
    return operand


_HALF = _operand(0.5)
_ZERO = _operand(0.0)
#: `x_bottom` divides by uy, at most this (a line of uy 0 is flat, and flat ones are dropped).
_MAX_UY = _operand(-1e-9)


def empty_line_set(segment_count: int = 0) -> LineSet:
    e = _EMPTY_F
    return LineSet(
        angle_deg=e, cx=e, cy=e, ux=e, uy=e, near_x=e, near_y=e, far_x=e, far_y=e,
        support_px=e, polarity=e, x_bottom=e, near_fx=e, near_fy=e, far_fx=e, far_fy=e,
        segment_label=np.full(segment_count, -1, dtype=np.intp), contrast=e,
    )


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
    rows = _segment_rows(segments)
    angle = rows[_ANGLE]
    lowest, highest = _steep_enough(edges.min_angle_from_horizontal_deg)
    kept = ((angle >= lowest) & (angle <= highest)).nonzero()[0]
    count = len(angle)
    if len(kept) == 0:
        return empty_line_set(count)
    width = smooth_gray.shape[1]
    offset_tol = max(edges.cluster_offset_frac_of_width * width, 1.0)
    every = len(kept) == count
    pieces = _Pieces.measured(rows if every else rows.take(kept, axis=1))
    line_of, lines = _cluster_collinear(pieces, edges.cluster_angle_tol_deg, offset_tol)
    if every:
        label = line_of
    else:
        label = np.empty(count, dtype=np.intp)
        label.fill(-1)
        label[kept] = line_of
    fit, ends = _fit_lines(pieces, line_of, lines)
    cx, cy, ux, uy = fit[:4]
    x_bottom = cx + (y_bottom - cy) * ux / np.minimum(uy, _MAX_UY)
    polarity, contrast = _polarity_of(smooth_gray, ends, fit[_UX:_UY + 1], tape)
    # Every near end then every far end, x and y each one contiguous row: one projection.
    ends_x, ends_y = floor.to_floor_rows(ends.reshape(2, -1))
    return _line_set({
        "angle_deg": np.degrees(np.arctan2(-uy, ux)),
        "cx": cx,
        "cy": cy,
        "ux": ux,
        "uy": uy,
        "near_x": ends[0, 0],
        "near_y": ends[1, 0],
        "far_x": ends[0, 1],
        "far_y": ends[1, 1],
        "support_px": fit[_SUPPORT],
        "polarity": polarity,
        "x_bottom": x_bottom,
        "near_fx": ends_x[:lines],
        "near_fy": ends_y[:lines],
        "far_fx": ends_x[lines:],
        "far_fy": ends_y[lines:],
        "segment_label": label,
        "contrast": contrast,
    })


@functools.cache
def _steep_enough(min_angle_deg: float) -> tuple[FloatArray, FloatArray]:
    """The lowest and highest angle of a line that is not flat (`min_angle_deg` from the
    horizontal either way), as `_operand`s."""
    return _operand(min_angle_deg), _operand(180.0 - min_angle_deg)


def _line_set(fields: dict[str, Any]) -> LineSet:
    """`LineSet(**fields)` (`fields`: every one of its fields), made without the frozen
    dataclass's `__init__`, which sets the eighteen fields one `object.__setattr__` at a time
    (a tenth of the cost; `LineSet` has no defaults and no `__post_init__` to skip)."""
    line_set = object.__new__(LineSet)
    line_set.__dict__.update(fields)
    return line_set


def _oriented_segments(segments: NDArray[np.int32]) -> tuple[FloatArray, FloatArray]:
    """Segments (N, 4) as floats running near (bottom) -> far (top), and their angle from the
    image's x axis with y up, degrees in [0, 180] (`_segment_rows`, as (N, 4) and (N,))."""
    rows = _segment_rows(segments)
    return rows[_X1:_Y2 + 1].T, rows[_ANGLE]


def _segment_rows(segments: NDArray[np.int32]) -> FloatArray:
    """A `_Pieces.rows` block for HoughLinesP's segments with their ends (as floats, running
    near (bottom) -> far (top)) and their angle (from the image's x axis with y up, degrees in
    [0, 180]) filled in; `_Pieces.measured` fills the rest. Worked row by row: x1, y1, x2 and y2
    each one contiguous row."""
    # HoughLinesP's ends as (end, x|y, segment), a view; with its ends swapped, the same view
    # read backwards along its first axis. Copied as they come, then swapped where the first
    # end is the far one: two copies that cast the ints as they go, no gathers.
    raw = segments.reshape(-1, 2, 2).transpose(1, 2, 0)
    count = raw.shape[2]
    rows = np.empty((14, count))
    ends = rows[_X1:_Y2 + 1]
    by_end = ends.reshape(2, 2, count)
    by_end[...] = raw
    np.copyto(by_end, raw[::-1], where=ends[1] < ends[3])
    np.degrees(np.arctan2(ends[1] - ends[3], ends[2] - ends[0]), out=rows[_ANGLE])
    return rows


#: The rows of `_Pieces.rows`, one (14, N) block, so that one numpy call serves several rows
#: where they are adjacent: the segment's ends (x1, y1, x2, y2); the five weights
#: `_fit_lines` sums per line; the three numbers `_compatible` compares and the two it
#: multiplies them by.
(_X1, _Y1, _X2, _Y2, _LENGTH, _DX, _DY, _MID_X_LENGTH, _MID_Y_LENGTH, _ANGLE, _MID_X, _MID_Y,
 _DIR_Y, _DIR_X) = range(14)


@dataclass(frozen=True)
class _Pieces:
    """The kept segments as the rows of one block (`rows`, see `_X1`...): their ends (oriented
    near -> far), run (dx, dy: pixels, y down), length, midpoint (also times the length), angle
    (degrees, y up) and unit direction (dir_y before dir_x: what a midpoint's x and y offsets
    across a line are multiplied by)."""

    rows: FloatArray

    @property
    def seg(self) -> FloatArray:
        """(N, 4): x1, y1, x2, y2 of each segment."""
        return self.rows[_X1:_Y2 + 1].T

    @property
    def angle(self) -> FloatArray:
        return self.rows[_ANGLE]

    @property
    def length(self) -> FloatArray:
        return self.rows[_LENGTH]

    @staticmethod
    def of(seg: FloatArray, angle: FloatArray) -> _Pieces:
        """The pieces of segments `seg` ((N, 4) floats, oriented) of angles `angle`."""
        rows = np.empty((14, len(angle)))
        rows[_X1:_Y2 + 1] = seg.T
        rows[_ANGLE] = angle
        return _Pieces.measured(rows)

    @staticmethod
    def measured(rows: FloatArray) -> _Pieces:
        """The pieces of a block whose ends and angles are filled in (`_segment_rows`): the
        rest of its rows filled in."""
        ends = rows[_X1:_Y2 + 1]
        run = np.subtract(ends[2:], ends[:2], out=rows[_DX:_DY + 1])  # (dx and dy, one step)
        dx, dy = run[0], run[1]
        length = np.hypot(dx, dy, out=rows[_LENGTH])
        mid = np.add(ends[:2], ends[2:], out=rows[_MID_X:_MID_Y + 1])
        mid *= _HALF
        np.multiply(mid[0], length, out=rows[_MID_X_LENGTH])
        np.multiply(mid[1], length, out=rows[_MID_Y_LENGTH])
        np.divide(dy, length, out=rows[_DIR_Y])
        np.divide(dx, length, out=rows[_DIR_X])
        return _Pieces(rows)


def _cluster_collinear(pieces: _Pieces, angle_tol_deg: float,
                       offset_tol_px: float) -> tuple[NDArray[np.intp], int]:
    """Greedy leader clustering, longest segment first: the line index of every segment, and
    the number of lines. A
    segment joins the leader's line when its direction is within `angle_tol_deg` and its
    midpoint within `offset_tol_px` of the leader's line (a precomputed compatibility matrix).

    The greedy pass runs on Python ints used as bit sets (bit j: segment j), one per segment
    for the segments compatible with it, plus the set of segments still free: a few dozen
    segments make a few lines, and this saves the few numpy calls per line the pass needed."""
    count = pieces.rows.shape[1]
    compatible_with: list[int]
    if count <= _DENSE_UP_TO:  # each row's bits as one 64-bit word: one product for all rows
        compatible_with = (_compatible_dense(pieces, angle_tol_deg, offset_tol_px)
                           @ _bit_values(count)).tolist()
    else:  # few pairs are compatible: each row's bits set one by one
        compatible_with = [0] * count
        rows, columns = _compatible_pairs(pieces, angle_tol_deg, offset_tol_px)
        for row, column in zip(rows.tolist(), columns.tolist(), strict=True):
            compatible_with[row] |= 1 << column
    line_of = [-1] * count
    free = (1 << count) - 1
    lines = 0
    for leader in (-pieces.length).argsort(kind="stable").tolist():
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


@functools.cache
def _bit_values(count: int) -> NDArray[np.uint64]:
    """2**j for j < `count` (at most 64): a boolean row times these, summed, is its bits as one
    word (integer products and sums: exact)."""
    values = np.left_shift(np.uint64(1), np.arange(count, dtype=np.uint64))
    values.flags.writeable = False
    return values


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
    i's and its midpoint within `offset_tol_px` of segment i's line.

    Angle and midpoint are adjacent rows of `pieces.rows`, as are the direction's y and x: the
    differences of all three are one subtraction, their products one multiplication. The
    offset across then takes the midpoints' x difference's place, beside the angle difference:
    both are made absolute and compared with their tolerances in one call each."""
    rows = pieces.rows
    compared = rows[_ANGLE:_MID_Y + 1]
    diff = _on_last_axis(compared, j) - _on_last_axis(compared, i)  # angle, mid_x, mid_y
    across = diff[1:] * _on_last_axis(rows[_DIR_Y:_DIR_X + 1], i)
    measured = diff[:2]  # the angle difference, and (below) the offset across
    np.subtract(across[0], across[1], out=measured[1])
    np.abs(measured, out=measured)
    within = measured <= _tolerances(angle_tol_deg, offset_tol_px, measured.ndim)
    return within[0] & within[1]


@functools.cache
def _tolerances(angle_tol_deg: float, offset_tol_px: float, ndim: int) -> FloatArray:
    """The two tolerances `_compatible` compares with, shaped to broadcast against its
    (angle|offset, ...) block of `ndim` dimensions."""
    tolerances = np.array((angle_tol_deg, offset_tol_px)).reshape((2,) + (1,) * (ndim - 1))
    tolerances.flags.writeable = False
    return tolerances


def _on_last_axis(rows: FloatArray, which: _Which) -> FloatArray:
    """`rows[:, which]`: `which` (an index array or index expression) applied to the last axis
    (an index array through `take`, whose result, unlike fancy indexing's, is C-contiguous:
    the thousands of pairs of a textured floor are then worked on row by row)."""
    if isinstance(which, tuple):
        return rows[(Ellipsis, *which)]
    return np.asarray(rows.take(which, axis=-1))


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


#: The rows of `_fit_lines`' per-line block: centre, unit direction (pixels, y down, pointing
#: far), support (total segment length).
_CX, _CY, _UX, _UY, _SUPPORT = range(5)
#: `_fit_lines`' rows beside a segment's ends (x1, y1, x2, y2): the centre's x and y twice,
#: then the direction's, so that the ends' offsets and their products are steps of like
#: shapes (a broadcast costs numpy about what two calls do).
_BESIDE_ENDS = np.array([_CX, _CY, _CX, _CY, _UX, _UY, _UX, _UY], dtype=np.intp)
_BESIDE_ENDS.flags.writeable = False


@functools.cache
def _weight_bins(lines: int) -> IntArray:
    """Where each of the five weights' per-line sums starts among `_fit_lines`' bincount bins,
    shaped (5, 1) to add to the segments' line indices."""
    offsets = (np.arange(5) * lines).reshape(5, 1)
    offsets.flags.writeable = False
    return offsets


@functools.cache
def _no_extent(lines: int) -> FloatArray:
    """(2, lines): where the lowest projections start (inf), and the highest (-inf)."""
    start = np.array([[np.inf], [-np.inf]]).repeat(lines, axis=1)
    start.flags.writeable = False
    return start


def _fit_lines(pieces: _Pieces, line_of: NDArray[np.intp],
               lines: int) -> tuple[FloatArray, FloatArray]:
    """Each of the `lines` lines from its member segments (oriented near -> far): direction and
    centre weighted by length; its extent is the lowest and highest projection of its members'
    ends on it (all members run near -> far within a few degrees of the line). Returned: the
    (5, lines) block of `_CX`... and the lines' ends, (x|y, near|far, line).

    The five per-line sums (length, dx, dy, midpoint x and y times length) are one bincount:
    weight w of segment i counts in bin w * lines + line_of[i]; bincount adds each bin's
    weights in index order, as one bincount per weight would."""
    sums = np.bincount((line_of + _weight_bins(lines)).ravel(),
                       weights=pieces.rows[_LENGTH:_MID_Y_LENGTH + 1].ravel(),
                       minlength=5 * lines).reshape(5, lines)
    fit = np.empty((5, lines))
    support = sums[0]
    fit[_SUPPORT] = support
    np.divide(sums[3:5], support, out=fit[_CX:_CY + 1])  # sum(mid * length) / support
    norm = np.hypot(sums[1], sums[2])  # of sum(unit * length)
    np.divide(sums[1:3], norm, out=fit[_UX:_UY + 1])
    # Each segment's line's centre and direction beside its ends (`_BESIDE_ENDS`, one gather
    # each way), then both ends' projections on it: (x - cx) * ux + (y - cy) * uy.
    beside = fit.take(_BESIDE_ENDS, axis=0).take(line_of, axis=1)
    terms = pieces.rows[_X1:_Y2 + 1] - beside[:4]
    terms *= beside[4:]
    near, far = terms[0] + terms[1], terms[2] + terms[3]
    extent = _no_extent(lines).copy()  # per line: the lowest projection, the highest
    np.minimum.at(extent[0], line_of, np.minimum(near, far))
    np.maximum.at(extent[1], line_of, np.maximum(near, far))
    ends = fit[_CX:_CY + 1, None] + extent * fit[_UX:_UY + 1, None]
    return fit, ends


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


@functools.cache
def _side_offsets(offset: float) -> FloatArray:
    """What (uy, ux) are multiplied by for the steps from a line to the points right of it and
    left of it, shaped (x|y, right|left, 1): right is (-uy, ux) * offset (the normal pointing
    to +x, "right of the line", since uy <= 0), left the opposite (negating a product is
    exact: the same steps as negating a factor)."""
    steps = np.array(((-offset, offset), (offset, -offset))).reshape(2, 2, 1)
    steps.flags.writeable = False
    return steps


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
    """(polarity, contrast) of each line (`_polarity_of`, the ends given one by one)."""
    ends = np.array(((near_x, far_x), (near_y, far_y)), dtype=np.float64)
    return _polarity_of(gray, ends, np.array((ux, uy), dtype=np.float64), tape)


def _polarity_of(
    gray: NDArray[np.uint8],
    ends: FloatArray,
    unit: FloatArray,
    tape: TapeConfig,
) -> tuple[FloatArray, FloatArray]:
    """(polarity, contrast) of each line, from its ends ((x|y, near|far, line), as
    `_fit_lines` gives them) and its unit direction ((ux, uy), line). Its contrast: the median
    of (right side - left side) brightness over a few points sampled along it. Its polarity:
    the sign of that median (0 when it is within `min_contrast_levels`), or the sign of the
    median over the least-lit half of them (the half whose darker side is darkest) when that
    is a clear step of the other sign, or of any sign where the median and the vote said none
    and the steps show a mirrored light along a tape (see below)."""
    height, width = gray.shape[:2]
    k = POLARITY_SAMPLE_FACTOR * tape.polarity_samples
    offset = max(tape.polarity_offset_frac_of_width * width, 1.5)
    # The sample points, x and y stacked (2, n, k): near + (far - near) * fraction (stacked, the
    # dozen numpy calls of the two coordinates are half as many: this runs on every frame).
    start = ends[:, 0]
    points = (ends[:, 1] - start)[:, :, None] * _sample_fractions(k)
    points += start[:, :, None]
    # Beside each point, right of its line and left of it, (x|y, right|left, n, k): one gather
    # for both sides, rows 0..n-1 right of the lines, n..2n-1 left of them.
    normals = unit[::-1, None, :] * _side_offsets(offset)
    sides = (points[:, None] + normals[:, :, :, None]).reshape(2, -1, k)
    sides += _HALF
    np.maximum(sides, _ZERO, out=sides)
    np.minimum(sides, _image_limits(width, height), out=sides)
    pixel = sides.astype(np.intp)
    values = gray[pixel[1], pixel[0]]
    n = unit.shape[1]
    right, left = values[:n], values[n:]
    # (Widened first, then subtracted: two plain loops, cheaper than one that casts as it goes.)
    wide = values.astype(np.int16)
    step = wide[:n] - wide[n:]
    threshold = tape.min_contrast_levels
    # (For whole-number steps, step > t exactly when step > floor(t): compared as ints, twice
    # as fast as against a float.)
    limits = _step_limits(threshold)
    whole_threshold = limits.whole
    # The median step, not the mean: a ceiling light mirrored in glossy tape makes a few samples
    # of its edges brighter on the tape's side than the floor by far more than the tape is darker
    # elsewhere, and their mean says "no contrast" (or the wrong sign).
    # (Sorted once, kept: the quarters below are read off it too.)
    ordered = step.copy()
    ordered.sort(axis=1)
    contrast = _middle(ordered)
    whole = _signs(contrast, limits)
    # Where a tape has a gap (a worn patch, a dash gap, the gap of a broken line coming into
    # view), the points in it show no step at all, and the median says "no contrast" once the
    # gap covers half the line. There, the sign that a quarter of the points in a row show
    # clearly, with at least twice as many points as show the other sign, is the line's.
    unclear = (whole == _ZERO).nonzero()[0]
    if unclear.size:
        whole[unclear] = _vote(step[unclear], whole_threshold)
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
    # (At least `quarter` points step clearly down exactly when the quarter-th lowest step
    # does, and up when the quarter-th highest does: read off the sorted steps, no counting.
    # A rising line is read where a quarter step down, a falling one where a quarter step up.
    # A line the median says falls has at least half its points step clearly down, one the
    # vote says falls at least `_vote_need(k)` of them, no fewer than `quarter` (for the vote's
    # share of a quarter; the test below keeps this true for any): either way a quarter step
    # down, so "falling or a quarter down" is "a quarter down"; the same rising.)
    half = k // 2
    quarter = (half - 1) // 2 + 1
    quarter_down = ordered[:, quarter - 1] < limits.whole_below
    quarter_up = ordered[:, k - quarter] > limits.whole_above
    against = quarter_down & quarter_up
    if _vote_need(k) < quarter:
        against = (quarter_down | (whole < 0.0)) & (quarter_up | (whole > 0.0))
    rows = against.nonzero()[0]
    if rows.size:
        least_lit = np.argsort(np.minimum(right[rows], left[rows]), axis=1,
                               kind="stable")[:, :half]
        unlit = _signs(_median(np.take_along_axis(step[rows], least_lit, axis=1)), limits)
        was = whole[rows]
        up, down = step[rows] > whole_threshold, step[rows] < -whole_threshold
        same = np.where((unlit > 0.0)[:, None], up, down)
        unlit_same = np.take_along_axis(same, least_lit, axis=1).sum(axis=1)
        mirrored = ((was == 0.0) & (unlit != 0.0)
                    & (4 * unlit_same >= 3 * half)
                    & same[:, :half].any(axis=1) & same[:, half:].any(axis=1))
        whole[rows] = np.where((was * unlit < 0.0) | mirrored, unlit, was)
    return whole, contrast


#: A row of steps times these: the steps themselves, then negated ((2, 1, 1) int16: exact), so
#: that "steps clearly up" and "steps clearly down" are one comparison.
_UP_DOWN = np.array((1, -1), dtype=np.int16).reshape(2, 1, 1)
_UP_DOWN.flags.writeable = False


def _vote_need(k: int) -> int:
    """How many of a line's `k` points must step clearly one way for `_vote` to say so."""
    return math.ceil(POLARITY_VOTE_SHARE * k)


def _vote(step: NDArray[np.int16], whole_threshold: int) -> FloatArray:
    """Per row of steps `step` (points along a line, whole grey levels), from which points
    step clearly up (beyond `whole_threshold`) and which clearly down: +1
    where at least `POLARITY_VOTE_SHARE` of the points step up, in one run from one end of the
    line unbroken but for gaps of one or two points (`_bridged`), and at least
    `POLARITY_VOTE_MARGIN` times as many points step up as down; -1 the other way round; 0
    otherwise. (A run from an end: a gap leaves the rest of a tape in one piece that runs to the
    line's end, while on a speckled floor, or across a patchy one where a stretch of lighter
    slats or chips happens to line up mid-line, a line of no contrast has no such run.)

    Each row's points as the bits of a Python int (bit j: point j): the few rows this is asked
    about cost a few integer operations each (how many points step each way: the count of its
    bits), where the same on boolean arrays took twenty-odd numpy calls. Up to 64 points, the
    ints of both ways come from one comparison and one product with 2**j (`_bit_values`)."""
    k = step.shape[1]
    if k <= 64:  # (each row's bits one 64-bit word)
        ups, downs = ((step * _UP_DOWN > whole_threshold) @ _bit_values(k)).tolist()
    else:
        ups, downs = _row_bits(step > whole_threshold), _row_bits(step < -whole_threshold)
    need = _vote_need(k)
    first = (1 << need) - 1  # the first `need` points
    last = first << (k - need)  # the last `need` points
    votes = []
    for rising, falling in zip(ups, downs, strict=True):
        n_rising, n_falling = rising.bit_count(), falling.bit_count()
        if (n_rising >= need and n_rising >= POLARITY_VOTE_MARGIN * n_falling
                and _run_from_an_end(_bridged(rising), first, last)):
            votes.append(1.0)
        elif (n_falling >= need and n_falling >= POLARITY_VOTE_MARGIN * n_rising
              and _run_from_an_end(_bridged(falling), first, last)):
            votes.append(-1.0)
        else:
            votes.append(0.0)
    return np.array(votes, dtype=np.float64)


def _row_bits(flags: NDArray[np.bool_]) -> list[int]:
    """The rows of a boolean array as Python ints (bit j: the row's value j), packed at once."""
    packed = np.packbits(flags, axis=1, bitorder="little")
    data, size = packed.tobytes(), packed.shape[1]
    return [int.from_bytes(data[start:start + size], "little")
            for start in range(0, len(data), size)]


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
    return _middle(np.sort(values, axis=1))


def _middle(ordered: NDArray[np.int16]) -> FloatArray:
    """Per row of values sorted along it, their median (the mean of the middle two)."""
    m = ordered.shape[1]
    return cast(FloatArray, (ordered[:, (m - 1) // 2] + ordered[:, m // 2]) * _HALF)


class _StepLimits(NamedTuple):
    """What a step is clear beyond (`tape.min_contrast_levels`): the threshold and minus it,
    and for whole-number steps its whole part (`whole`) and the same as int16, as `_operand`s."""

    above: FloatArray
    below: FloatArray
    whole: int
    whole_above: NDArray[np.int16]
    whole_below: NDArray[np.int16]


@functools.cache
def _step_limits(threshold: float) -> _StepLimits:
    whole = math.floor(threshold)
    return _StepLimits(_operand(threshold), _operand(-threshold), whole,
                       _operand(whole, np.int16), _operand(-whole, np.int16))


def _signs(median: FloatArray, limits: _StepLimits) -> FloatArray:
    """+1 above `limits.above`, -1 below `limits.below`, 0 between (the two tests' difference as
    floats: never -0.0)."""
    return np.subtract(median > limits.above, median < limits.below, dtype=np.float64)


def line_angle_deg(ux: float, uy: float) -> float:
    """Angle (y up, degrees) of a unit direction in image coordinates."""
    return math.degrees(math.atan2(-uy, ux))
