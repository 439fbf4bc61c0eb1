"""From Hough segments to candidate lines: drop flat segments, merge collinear ones, measure each
line's brightness polarity.

A `LineSet` holds every candidate line of one frame as parallel numpy arrays (struct of arrays).
The arithmetic per segment and per brightness sample (orienting, clustering, fitting, reading
both sides of each line) is compiled loops in `perception.line_kernel`: with a few dozen
segments and a few lines a frame, numpy's price per call was what it cost, not the arithmetic.
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

Pure functions of their inputs: never draws.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from lanewarden.perception import line_kernel
from lanewarden.perception.config import EdgesConfig
from lanewarden.perception.floor_config import TapeConfig
from lanewarden.perception.floor_view import MIN_SCALE, FloorView

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


_ZERO = _operand(0.0)


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
    model of this image size (undistorted pixels). The arithmetic per segment and per sample
    is compiled (`perception.line_kernel`, the floor positions of the ends too); the polarity
    rules that read a line's whole row of steps are here.
    """
    if segments is None or len(segments) == 0:
        return empty_line_set()
    width = smooth_gray.shape[1]
    lowest, highest = _steep_enough(edges.min_angle_from_horizontal_deg)
    label, fit, ends, on_floor, samples = line_kernel.measure_lines(
        np.ascontiguousarray(segments, dtype=np.int32).reshape(-1, 4), smooth_gray, lowest,
        highest,
        float(edges.cluster_angle_tol_deg),
        max(float(edges.cluster_offset_frac_of_width) * width, 1.0), float(y_bottom),
        *_sample_setup(tape, width), floor.image_to_floor_flat, floor.below_sign, MIN_SCALE,
    )
    lines = fit.shape[1]
    if lines == 0:
        return empty_line_set(len(label))
    polarity, contrast = _polarity_of_samples(*samples, tape)
    return _line_set({
        "angle_deg": fit[line_kernel.ANGLE_DEG],
        "cx": fit[line_kernel.CX],
        "cy": fit[line_kernel.CY],
        "ux": fit[line_kernel.UX],
        "uy": fit[line_kernel.UY],
        "near_x": ends[0, 0],
        "near_y": ends[1, 0],
        "far_x": ends[0, 1],
        "far_y": ends[1, 1],
        "support_px": fit[line_kernel.SUPPORT],
        "polarity": polarity,
        "x_bottom": fit[line_kernel.X_BOTTOM],
        "near_fx": on_floor[0, 0],
        "near_fy": on_floor[1, 0],
        "far_fx": on_floor[0, 1],
        "far_fy": on_floor[1, 1],
        "segment_label": label,
        "contrast": contrast,
    })


@functools.cache
def _steep_enough(min_angle_deg: float) -> tuple[float, float]:
    """The lowest and highest angle of a line that is not flat (`min_angle_deg` from the
    horizontal either way)."""
    return float(min_angle_deg), 180.0 - min_angle_deg


def _sample_setup(tape: TapeConfig, width: int) -> tuple[int, float, float, int, int]:
    """How `line_kernel.side_samples` reads beside the lines of an image `width` px wide: how
    many points along each (k), how far beside it (pixels, at least 1.5), what a step is clear
    beyond (the threshold, and its whole part for whole-number steps), and `_quarter(k)`."""
    k = POLARITY_SAMPLE_FACTOR * int(tape.polarity_samples)
    threshold = float(tape.min_contrast_levels)
    return (k, max(float(tape.polarity_offset_frac_of_width) * width, 1.5), threshold,
            math.floor(threshold), _quarter(k))


def _quarter(k: int) -> int:
    """A quarter of `k` points, rounded up, as a count within the lower half: the
    least-lit-half reading's "a quarter" (see `_polarity_of_samples`)."""
    return (k // 2 - 1) // 2 + 1


def _line_set(fields: dict[str, Any]) -> LineSet:
    """`LineSet(**fields)` (`fields`: every one of its fields), made without the frozen
    dataclass's `__init__`, which sets the eighteen fields one `object.__setattr__` at a time
    (a tenth of the cost; `LineSet` has no defaults and no `__post_init__` to skip)."""
    line_set = object.__new__(LineSet)
    line_set.__dict__.update(fields)
    return line_set


def pairs_within_angle(angle: FloatArray, tol_deg: float) -> tuple[IntArray, IntArray]:
    """The index pairs (i, j), i < j, whose `angle`s (finite) differ by at most `tol_deg`, each
    once, found through a window over the sorted angles, so without looking at the others. The
    window is a hair wider than `tol_deg` (callers check each pair exactly), so no pair within it
    is ever missed."""
    count = len(angle)
    order = np.argsort(angle, kind="stable")
    ordered = angle[order]
    reach = tol_deg * (1.0 + 1e-9) + 1e-9
    hi = np.searchsorted(ordered, ordered + reach, side="right")
    lo = np.arange(1, count + 1)
    width = hi - lo
    first = np.repeat(np.arange(count), width)
    starts = np.cumsum(width) - width
    second = lo[first] + (np.arange(int(width.sum())) - np.repeat(starts, width))
    i, j = order[first], order[second]
    return np.minimum(i, j), np.maximum(i, j)


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
    """(polarity, contrast) of each line given by its ends and unit direction (as
    `build_line_set` measures them, without the clustering)."""
    ends = np.array(((near_x, far_x), (near_y, far_y)), dtype=np.float64)
    samples = line_kernel.side_samples(np.ascontiguousarray(gray), ends,
                                       np.array((ux, uy), dtype=np.float64),
                                       *_sample_setup(tape, gray.shape[1]))
    return _polarity_of_samples(*samples, tape)


def _polarity_of_samples(
    step: NDArray[np.int16],
    right: NDArray[np.uint8],
    left: NDArray[np.uint8],
    contrast: FloatArray,
    median_sign: FloatArray,
    quarter_down: NDArray[np.bool_],
    quarter_up: NDArray[np.bool_],
    tape: TapeConfig,
) -> tuple[FloatArray, FloatArray]:
    """(polarity, contrast) of each line from the brightness read beside it and what was read
    off it first (`line_kernel.side_samples`: the steps right - left at k points along it, the
    right and left values, the median step and its sign, whether a quarter of the points step
    clearly down and whether a quarter step clearly up). Its contrast: the median step. Its
    polarity: the sign of that median (0 when it is within `min_contrast_levels`), or the sign
    of the median over the least-lit half of them (the half whose darker side is darkest) when
    that is a clear step of the other sign, or of any sign where the median and the vote said
    none and the steps show a mirrored light along a tape (see below).

    The median step, not the mean: a ceiling light mirrored in glossy tape makes a few samples
    of its edges brighter on the tape's side than the floor by far more than the tape is darker
    elsewhere, and their mean says "no contrast" (or the wrong sign). Whole-number steps are
    compared with the threshold's whole part: step > t exactly when step > floor(t)."""
    k = step.shape[1]
    whole_threshold = math.floor(tape.min_contrast_levels)
    whole = median_sign
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
    # (`side_samples` read the quarters off the sorted steps: `_quarter(k)`.)
    half = k // 2
    quarter = _quarter(k)
    against = quarter_down & quarter_up
    if _vote_need(k) < quarter:
        against = (quarter_down | (whole < 0.0)) & (quarter_up | (whole > 0.0))
    rows = against.nonzero()[0]
    if rows.size:
        least_lit = np.argsort(np.minimum(right[rows], left[rows]), axis=1,
                               kind="stable")[:, :half]
        unlit = line_kernel.median_signs(np.take_along_axis(step[rows], least_lit, axis=1),
                                         float(tape.min_contrast_levels))
        was = whole[rows]
        up, down = step[rows] > whole_threshold, step[rows] < -whole_threshold
        same = np.where((unlit > 0.0)[:, None], up, down)
        unlit_same = np.take_along_axis(same, least_lit, axis=1).sum(axis=1)
        mirrored = ((was == 0.0) & (unlit != 0.0)
                    & (4 * unlit_same >= 3 * half)
                    & same[:, :half].any(axis=1) & same[:, half:].any(axis=1))
        whole[rows] = np.where((was * unlit < 0.0) | mirrored, unlit, was)
    return whole, contrast


@functools.cache
def _bit_values(count: int) -> NDArray[np.uint64]:
    """2**j for j < `count` (at most 64): a boolean row times these, summed, is its bits as one
    word (integer products and sums: exact)."""
    values = np.left_shift(np.uint64(1), np.arange(count, dtype=np.uint64))
    values.flags.writeable = False
    return values


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


def line_angle_deg(ux: float, uy: float) -> float:
    """Angle (y up, degrees) of a unit direction in image coordinates."""
    return math.degrees(math.atan2(-uy, ux))
