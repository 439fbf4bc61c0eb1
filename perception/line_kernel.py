"""The per-segment and per-sample arithmetic of `perception.lines`, compiled (numba).

From HoughLinesP's segments to candidate lines: orient each segment near -> far and drop the flat
ones, cluster collinear ones greedily (longest first), fit each line, and read the brightness on
both sides of it at a few points along it. A frame has a few dozen segments and a few lines, so
written as numpy this was forty-odd calls whose cost was numpy's price per call, not the
arithmetic (about 0.2 ms a frame at 320x240 on a desktop core, a fifth of perception's whole
time); compiled loops do it in a few microseconds. The lines' ends are projected on the floor
here too (`floor_points`: `FloorView.to_floor`'s arithmetic, held to it by a test). The
polarity rules that read a line's whole row of steps stay in `perception.lines`.

Why numba: it compiles these plain loops over numpy arrays to machine code with no build step
(the compiled code is cached beside this file, in `__pycache__`, on the first run: a few seconds
once, on a Raspberry Pi longer). Where numba has no wheels (32-bit ARM: a 32-bit Raspberry Pi
OS), pyproject does not ask for it and the same loops run interpreted: the same results, slower.
The arithmetic is the C library's (`math.atan2`, `math.hypot`), in the order written here, so the
results are the same compiled or not, on every machine; numpy's own `arctan2` and `hypot` differ
from it in the last bit on some CPUs (its SIMD versions).

Every function is pure: arrays in, new arrays out. Pixels: x right, y down. `ready` has the
compiled code ready before the first frame and says so when it must compile.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numpy as np

try:
    import numba
    import numba.core.event
except ImportError:  # (none for this machine: pyproject asks for it where numba has wheels)
    HAVE_NUMBA = False
else:
    HAVE_NUMBA = True

_DEGREES = 180.0 / math.pi

#: The rows of a pieces block (`segment_pieces`), one column per kept segment: its ends oriented
#: near (larger y) -> far, its angle (degrees from the image's x axis with y up, 0..180), length,
#: midpoint and unit direction (y before x).
(X1, Y1, X2, Y2, ANGLE, LENGTH, MID_X, MID_Y, DIR_Y, DIR_X) = range(10)
PIECE_ROWS = 10

#: The rows of a fit block (`fit_lines`), one column per line: centre, unit direction (pixels,
#: y down, pointing far: uy <= 0), support (total segment length), where it crosses the
#: ROI's bottom row, and its angle (degrees, y up).
(CX, CY, UX, UY, SUPPORT, X_BOTTOM, ANGLE_DEG) = range(7)
FIT_ROWS = 7

#: A line's `x_bottom` divides by uy, at most this (a line of uy 0 is flat: dropped before).
MAX_UY = -1e-9

_Function = TypeVar("_Function", bound=Callable[..., Any])


def _compiled(function: _Function) -> _Function:
    """`function` compiled by numba (cached beside this file); where numba is not installed,
    `function` itself: the same loops interpreted, the same results, slower (the lines of a
    320x240 frame about 0.8 ms instead of 0.06 on a desktop core)."""
    if not HAVE_NUMBA:
        return function
    try:
        compiled = numba.njit(cache=True, nogil=True, error_model="numpy")(function)
    except RuntimeError:  # nowhere writable to cache it (read-only install and home): compiled
        compiled = numba.njit(cache=False, nogil=True, error_model="numpy")(function)  # each run
    # (numba's Dispatcher is called as `function` is: typed as it, not as the dispatcher)
    return cast(_Function, compiled)


@_compiled
def segment_pieces(segments: np.ndarray, lowest_deg: float,
                   highest_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """HoughLinesP's segments ((N, 4) ints) as a pieces block (rows `X1`...,
    one column per segment whose angle lies within [lowest_deg, highest_deg]: the not-flat
    ones), and the index of each kept segment among the N."""
    count = segments.shape[0]
    flat = segments.reshape(count, 4)
    rows = np.empty((PIECE_ROWS, count))
    kept = np.empty(count, dtype=np.intp)
    n = 0
    for s in range(count):
        x1, y1 = float(flat[s, 0]), float(flat[s, 1])
        x2, y2 = float(flat[s, 2]), float(flat[s, 3])
        if y1 < y2:  # the first end is the far one: swap
            x1, y1, x2, y2 = x2, y2, x1, y1
        angle = math.atan2(y1 - y2, x2 - x1) * _DEGREES
        if not lowest_deg <= angle <= highest_deg:
            continue
        dx, dy = x2 - x1, y2 - y1
        length = math.hypot(dx, dy)
        rows[X1, n], rows[Y1, n], rows[X2, n], rows[Y2, n] = x1, y1, x2, y2
        rows[ANGLE, n] = angle
        rows[LENGTH, n] = length
        rows[MID_X, n] = (x1 + x2) * 0.5
        rows[MID_Y, n] = (y1 + y2) * 0.5
        rows[DIR_Y, n] = dy / length
        rows[DIR_X, n] = dx / length
        kept[n] = s
        n += 1
    return rows[:, :n].copy(), kept[:n].copy()


@_compiled
def cluster_collinear(pieces: np.ndarray, angle_tol_deg: float,
                      offset_tol_px: float) -> tuple[np.ndarray, int]:
    """Greedy leader clustering, longest piece first (ties: the earlier one): the line index of
    every piece, and the number of lines. A piece still free joins the leader's line when its
    direction is within `angle_tol_deg` of the leader's and its midpoint within
    `offset_tol_px` of the leader's line (measured across it)."""
    count = pieces.shape[1]
    line_of = np.full(count, -1, dtype=np.intp)
    lines = 0
    for leader in np.argsort(-pieces[LENGTH], kind="mergesort"):
        if line_of[leader] >= 0:
            continue
        angle, mid_x, mid_y = pieces[ANGLE, leader], pieces[MID_X, leader], pieces[MID_Y, leader]
        dir_y, dir_x = pieces[DIR_Y, leader], pieces[DIR_X, leader]
        line_of[leader] = lines
        for j in range(count):
            if (line_of[j] < 0
                    and abs(pieces[ANGLE, j] - angle) <= angle_tol_deg
                    and abs((pieces[MID_X, j] - mid_x) * dir_y
                            - (pieces[MID_Y, j] - mid_y) * dir_x) <= offset_tol_px):
                line_of[j] = lines
        lines += 1
    return line_of, lines


@_compiled
def fit_lines(pieces: np.ndarray, line_of: np.ndarray, lines: int,
              y_bottom: float) -> tuple[np.ndarray, np.ndarray]:
    """Each line from its member pieces: centre and direction weighted by length (sums in piece
    order), its extent the lowest and highest projection of its members' ends on it. Returned:
    the fit block ((FIT_ROWS, lines), rows `CX`...) and the lines' ends, (x|y, near|far, line)."""
    sums = np.zeros((5, lines))  # length, dx, dy, mid_x * length, mid_y * length
    for t in range(pieces.shape[1]):
        line = line_of[t]
        length = pieces[LENGTH, t]
        sums[0, line] += length
        sums[1, line] += pieces[X2, t] - pieces[X1, t]
        sums[2, line] += pieces[Y2, t] - pieces[Y1, t]
        sums[3, line] += pieces[MID_X, t] * length
        sums[4, line] += pieces[MID_Y, t] * length
    fit = np.empty((FIT_ROWS, lines))
    for line in range(lines):
        support = sums[0, line]
        norm = math.hypot(sums[1, line], sums[2, line])
        cx, cy = sums[3, line] / support, sums[4, line] / support
        ux, uy = sums[1, line] / norm, sums[2, line] / norm
        fit[CX, line], fit[CY, line], fit[UX, line], fit[UY, line] = cx, cy, ux, uy
        fit[SUPPORT, line] = support
        fit[X_BOTTOM, line] = cx + (y_bottom - cy) * ux / min(uy, MAX_UY)
        fit[ANGLE_DEG, line] = math.atan2(-uy, ux) * _DEGREES
    lowest = np.full(lines, np.inf)
    highest = np.full(lines, -np.inf)
    for t in range(pieces.shape[1]):
        line = line_of[t]
        cx, cy, ux, uy = fit[CX, line], fit[CY, line], fit[UX, line], fit[UY, line]
        near = (pieces[X1, t] - cx) * ux + (pieces[Y1, t] - cy) * uy
        far = (pieces[X2, t] - cx) * ux + (pieces[Y2, t] - cy) * uy
        lowest[line] = min(lowest[line], near, far)
        highest[line] = max(highest[line], near, far)
    ends = np.empty((2, 2, lines))
    for line in range(lines):
        cx, cy, ux, uy = fit[CX, line], fit[CY, line], fit[UX, line], fit[UY, line]
        ends[0, 0, line] = cx + lowest[line] * ux
        ends[1, 0, line] = cy + lowest[line] * uy
        ends[0, 1, line] = cx + highest[line] * ux
        ends[1, 1, line] = cy + highest[line] * uy
    return fit, ends


@_compiled
def _pixel_index(value: float, largest: float) -> int:
    """A sample's coordinate rounded to its pixel and kept within [0, largest] (NaN: 0)."""
    value += 0.5
    if not value >= 0.0:
        return 0
    return int(min(value, largest))


@_compiled
def _median_and_sign(ordered: np.ndarray, threshold: float) -> tuple[float, float]:
    """The median of a sorted row of whole-number steps (the mean of the middle two: exact) and
    its sign: +1 above `threshold`, -1 below minus it, 0 between (never -0.0)."""
    k = ordered.shape[0]
    middle = (int(ordered[(k - 1) // 2]) + int(ordered[k // 2])) * 0.5
    return middle, (1.0 if middle > threshold else (-1.0 if middle < -threshold else 0.0))


@_compiled
def median_signs(steps: np.ndarray, threshold: float) -> np.ndarray:
    """Per row of whole-number steps ((rows, n) int16), the sign of its median as
    `side_samples` reads a line's (`_median_and_sign`)."""
    signs = np.empty(steps.shape[0])
    for row in range(steps.shape[0]):
        signs[row] = _median_and_sign(np.sort(steps[row]), threshold)[1]
    return signs


@_compiled
def side_samples(
    gray: np.ndarray, ends: np.ndarray, unit: np.ndarray, k: int, offset_px: float,
    threshold: float, whole_threshold: int, quarter: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The brightness right and left of each line ((2, 2, lines) ends as `fit_lines` gives,
    (2, lines) unit directions (ux, uy)) at the middles of `k` equal parts of it, `offset_px`
    across it (right: the normal (-uy, ux), towards +x since uy <= 0), and what
    `perception.lines` reads off its steps first. Returned, per line: the steps (right - left,
    int16, (lines, k)); the right and left values (uint8, (lines, k)); the median step
    (`contrast`: the mean of the middle two); its sign (+1 above `threshold`, -1 below minus
    it, 0 between); whether the `quarter`-th lowest step is below -`whole_threshold` (at least
    `quarter` points step clearly down) and whether the `quarter`-th highest is above it."""
    largest_x, largest_y = gray.shape[1] - 1.0, gray.shape[0] - 1.0
    lines = unit.shape[1]
    step = np.empty((lines, k), dtype=np.int16)
    right = np.empty((lines, k), dtype=np.uint8)
    left = np.empty((lines, k), dtype=np.uint8)
    contrast = np.empty(lines)
    sign = np.empty(lines)
    quarter_down = np.empty(lines, dtype=np.bool_)
    quarter_up = np.empty(lines, dtype=np.bool_)
    for line in range(lines):
        near_x, near_y = ends[0, 0, line], ends[1, 0, line]
        run_x, run_y = ends[0, 1, line] - near_x, ends[1, 1, line] - near_y
        ux, uy = unit[0, line], unit[1, line]
        right_x, right_y = uy * -offset_px, ux * offset_px
        left_x, left_y = uy * offset_px, ux * -offset_px
        for q in range(k):
            fraction = (q + 0.5) / k
            x, y = run_x * fraction + near_x, run_y * fraction + near_y
            on_right = gray[_pixel_index(y + right_y, largest_y),
                            _pixel_index(x + right_x, largest_x)]
            on_left = gray[_pixel_index(y + left_y, largest_y),
                           _pixel_index(x + left_x, largest_x)]
            right[line, q], left[line, q] = on_right, on_left
            step[line, q] = np.int16(on_right) - np.int16(on_left)
        ordered = np.sort(step[line])
        contrast[line], sign[line] = _median_and_sign(ordered, threshold)
        quarter_down[line] = ordered[quarter - 1] < -whole_threshold
        quarter_up[line] = ordered[k - quarter] > whole_threshold
    return step, right, left, contrast, sign, quarter_down, quarter_up


@_compiled
def floor_points(ends: np.ndarray, image_to_floor: np.ndarray, below_sign: float,
                 min_scale: float) -> np.ndarray:
    """The lines' ends ((2, 2, lines) pixels) on the floor through the homography
    `image_to_floor` (9 values, row by row): (x|y, near|far, line), metres; NaN where the
    homogeneous scale times `below_sign` is at most `min_scale` (at or above the horizon). The
    arithmetic of `FloorView.to_floor`, in its order."""
    h = image_to_floor
    floor = np.empty_like(ends)
    for end in range(2):
        for line in range(ends.shape[2]):
            u, v = ends[0, end, line], ends[1, end, line]
            w = h[6] * u + h[7] * v + h[8]
            if w * below_sign <= min_scale:
                floor[0, end, line] = floor[1, end, line] = np.nan
            else:
                floor[0, end, line] = (h[0] * u + h[1] * v + h[2]) / w
                floor[1, end, line] = (h[3] * u + h[4] * v + h[5]) / w
    return floor


@_compiled
def measure_lines(
    segments: np.ndarray, gray: np.ndarray, lowest_deg: float, highest_deg: float,
    angle_tol_deg: float, offset_tol_px: float, y_bottom: float, k: int, offset_px: float,
    threshold: float, whole_threshold: int, quarter: int, image_to_floor: np.ndarray,
    below_sign: float, min_scale: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[
        np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """The whole compiled part of `perception.lines.build_line_set`, one call: each segment's
    line (-1: dropped as flat), the fit block, the lines' ends in pixels and on the floor
    (`floor_points`), and `side_samples`."""
    pieces, kept = segment_pieces(segments, lowest_deg, highest_deg)
    line_of, lines = cluster_collinear(pieces, angle_tol_deg, offset_tol_px)
    label = np.full(segments.shape[0], -1, dtype=np.intp)
    label[kept] = line_of
    fit, ends = fit_lines(pieces, line_of, lines, y_bottom)
    return (label, fit, ends, floor_points(ends, image_to_floor, below_sign, min_scale),
            side_samples(gray, ends, fit[UX:UY + 1], k, offset_px, threshold, whole_threshold,
                         quarter))


#: What `ready` says when the kernel must be compiled (not loaded from numba's cache)...
COMPILING = ("perception: compiling its line kernel (numba) for this machine: a few seconds, "
             "longer on a Raspberry Pi; once, later runs load it from the cache")
#: ...and where numba is not installed.
INTERPRETED = ("perception: numba is not installed (it has no wheels for this machine), so "
               "perception's line kernel runs as plain Python: slower, the same results")


def _compile_listener(notice: Callable[[str], None]) -> Any:
    """A numba event listener that tells `notice` `COMPILING` once, when numba starts compiling
    (a cache hit compiles nothing)."""

    class CompileNotice(numba.core.event.Listener):  # type: ignore[misc]
        def __init__(self) -> None:
            self.notice: Callable[[str], None] | None = notice

        def on_start(self, event: numba.core.event.Event) -> None:
            if self.notice is not None:
                told, self.notice = self.notice, None
                told(COMPILING)

        def on_end(self, event: numba.core.event.Event) -> None:
            pass

    return CompileNotice()


_made_ready = False


def ready(notice: Callable[[str], None] | None = None) -> None:
    """Have `measure_lines` and `median_signs` ready for the argument types perception passes
    them (`lines.build_line_set`), so that the first frame does not wait: loaded from numba's
    cache, or compiled, and then `notice` (by default a warning through `logging`: one line on
    stderr where nothing else is set up) is told once, before the wait; where numba is not
    installed, `notice` is told so (`INTERPRETED`). Once per process; a command that starts worker
    processes calls it first, so that a compile happens (and is said) once, not once a worker
    (forked workers inherit the compiled code, spawned ones load the cache)."""
    global _made_ready
    if _made_ready:
        return
    tell = logging.getLogger(__name__).warning if notice is None else notice
    if not HAVE_NUMBA:
        tell(INTERPRETED)
    else:
        # The types `build_line_set` passes, exactly (numba compiles once per set of types:
        # segments (N, 4) int32, the blurred frame, the ground model's read-only homography).
        homography = np.eye(3).ravel()
        homography.flags.writeable = False
        with numba.core.event.install_listener("numba:compile", _compile_listener(tell)):
            measure_lines(np.zeros((1, 4), dtype=np.int32), np.zeros((2, 2), dtype=np.uint8),
                          10.0, 170.0, 5.0, 1.0, 1.0, 3, 1.5, 1.0, 1, 1, homography, 1.0, 1e-12)
            # the least-lit half's steps (`lines._polarity`: int16 rows picked along each row,
            # a new C-ordered array) and the threshold as a float
            median_signs(np.take_along_axis(np.zeros((1, 2), dtype=np.int16),
                                            np.zeros((1, 1), dtype=np.intp), axis=1), 1.0)
    _made_ready = True
