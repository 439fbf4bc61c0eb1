"""The rules that tell a tape from a floor seam. The robot's safety rests on them: once the tape
ends, the lecture's pipeline follows tile seams; these rules are what refuse the seams.

1. Width on the floor (`tape_width_score`): the distance between a candidate's two edges,
   projected onto the floor through the ground model, against two hypotheses at the spot where it
   is measured (`WidthHypotheses`): a seam measures at most `tape.seam_width_m` or the thinnest
   line the image can show (`tape.min_gap_px` pixels), a tape at least `width_m` less its
   tolerance; both widened by `width_error_px` pixels of measurement error, converted to metres
   with the pixel size there. 0 up to the widest seam, 1 from the narrowest tape, linear between,
   falling back to 0 above the widest tape. Where the two hypotheses overlap (far away, coarse
   pixels) nothing scores: the camera cannot tell, so nothing passes as tape.
2. Band (`band_is_tape`): between the two edges a uniform band, darker (or lighter) than the floor
   beyond BOTH edges by more than half what those two floor samples differ from each other (one
   floor, shaded: `FLOOR_SHADE`). A band with a tape edge inside it fails (not uniform), so does
   a floor strip with tape on one side and floor on the other. (A light strip between a dark
   tape and a wide seam does look like a light tape: the choice of tapes rejects it, both tapes
   of a lane being of one kind.)
3. Profile of a lone edge (`tape_profile_fraction`): an edge whose partner Hough missed is
   checked by the brightness across it, where the tape's other side would be on the floor
   (`width_m` outwards). It can make the edge a tape edge, never a verified tape: only a pair
   (1 and 2) verifies a tape, and a lane needs one verified tape to be confident (`verified_tape`
   in `perception.confidence`). None when that side is outside the image (unverifiable).

Pure functions of pixels, lines, the floor view and the config: no state, no clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.floor_config import TapeConfig
from lanewarden.perception.floor_view import FloorView, Point, column_at
from lanewarden.perception.geometry import Side
from lanewarden.perception.kept import KeptPerObject
from lanewarden.perception.lines import LineRow

#: A lone edge's profile is only read where the tape spans at least this many pixels.
MIN_PROFILE_TAPE_PX = 3.0

#: One floor, shaded: the floor on the two sides of a tape may differ by up to this many times
#: the tape's own step from the floor. A real camera's picture darkens towards its sides
#: (vignetting, light falling off towards the walls): the JetBot set's left tape reads 32-58 grey
#: levels between a floor of 71-79 outside the lane and 97-131 inside it; of the dark-band
#: samples a rule of one unshaded floor (a factor of 1) refused there for the floors alone, 86%
#: had floors less than twice the step apart. Past twice the step, the band is a dark strip
#: between two floors (a baseboard between a wall and the floor, a dark plank between two
#: others). The allowance has a cost (docs/campaigns.md, the ninth run): a light parquet slat
#: between two differently shaded slats passes as a light tape more often.
FLOOR_SHADE = 2.0


@dataclass(frozen=True)
class WidthHypotheses:
    """What a seam and a tape measure, in metres, where one pixel covers `m_per_px` of floor
    across the line: a seam at most `seam_max_m`, a tape between `tape_min_m` and `tape_max_m`;
    `error_m` is the measurement error there."""

    m_per_px: float
    error_m: float
    seam_max_m: float
    tape_min_m: float
    tape_max_m: float

    @property
    def resolvable(self) -> bool:
        """Whether a tape and a seam measure apart here by more than the measurement error (the
        ramp between the two hypotheses is wider than one error unit)."""
        return math.isfinite(self.m_per_px) and self.tape_min_m - self.seam_max_m > self.error_m


def width_hypotheses(m_per_px: float, tape: TapeConfig) -> WidthHypotheses:
    """The seam and tape hypotheses where one pixel covers `m_per_px` metres across a line."""
    return WidthHypotheses(m_per_px, *_hypotheses(m_per_px, width_terms(tape)))


class WidthTerms(NamedTuple):
    """What the width hypotheses take from a tape config (`width_hypotheses`): the error in
    pixels, the widest seam and thinnest line (pixels), and the tape's narrowest and widest
    width before the error."""

    error_px: float
    seam_m: float
    min_gap_px: float
    tape_lo_m: float
    tape_hi_m: float


def _derive_width_terms(tape: TapeConfig) -> WidthTerms:
    return WidthTerms(
        error_px=tape.width_error_px,
        seam_m=tape.seam_width_m,
        min_gap_px=tape.min_gap_px,
        tape_lo_m=tape.width_m * (1.0 - tape.width_tolerance_fraction),
        tape_hi_m=tape.width_m * (1.0 + tape.width_tolerance_fraction),
    )


#: What the width hypotheses take from a tape config (`tape_width_score`), kept per config
#: object (a config's properties cost more than the score's arithmetic, and the score is taken
#: for every candidate pair of every frame); a caller scoring many widths of one side takes
#: them once (`width_score`).
width_terms: KeptPerObject[TapeConfig, WidthTerms] = KeptPerObject(_derive_width_terms)


def _hypotheses(m_per_px: float, terms: WidthTerms) -> tuple[float, float, float, float]:
    """(error, widest seam, narrowest tape, widest tape) in metres where one pixel covers
    `m_per_px`."""
    error = terms.error_px * m_per_px
    return (error, max(terms.seam_m, terms.min_gap_px * m_per_px) + error,
            terms.tape_lo_m - error, terms.tape_hi_m + error)


def tape_width_score(width_m: float, m_per_px: float, tape: TapeConfig) -> float:
    """How tape-like a band `width_m` wide on the floor is, measured where one pixel covers
    `m_per_px` metres across it: 0 at or below the widest seam, 1 from the narrowest to the
    widest tape, linear between, falling to 0 at 1.5x the widest tape. 0 where the hypotheses
    do not separate (nothing there can be told from a seam) and for non-finite input."""
    return width_score(width_m, m_per_px, width_terms(tape))


def width_score(width_m: float, m_per_px: float, terms: WidthTerms) -> float:
    """`tape_width_score` with the config's `width_terms` taken already."""
    if not (math.isfinite(width_m) and math.isfinite(m_per_px)) or m_per_px <= 0.0:
        return 0.0
    error, seam_max, tape_min, tape_max = _hypotheses(m_per_px, terms)
    if not tape_min - seam_max > error:  # not `WidthHypotheses.resolvable`
        return 0.0
    if width_m <= seam_max:
        return 0.0
    if width_m < tape_min:
        return (width_m - seam_max) / (tape_min - seam_max)
    if width_m <= tape_max:
        return 1.0
    return max(0.0, 1.0 - (width_m - tape_max) / (0.5 * tape_max))


def band_is_tape(
    smooth_gray: NDArray[np.uint8],
    a: LineRow,
    b: LineRow,
    y_lo: float,
    y_hi: float,
    tape: TapeConfig,
) -> bool:
    """Whether the band between lines a and b (image rows y_lo..y_hi) looks like tape: along
    enough of it, the band (at a quarter, half and three quarters across) is darker (or
    lighter) than the floor beyond BOTH edges by more than `min_contrast_levels`; the band
    varies across by less than that step, and the floor differs between its two sides by less
    than `FLOOR_SHADE` times it (one floor, shaded). The floor beyond each edge is read 0.3 and
    0.6 band widths out and the more floor-like of the two counts (the lighter one beside a dark
    band), so a seam running close beside a tape does not hide the floor. Samples whose outside
    points are all outside the image don't count against it; at least `min_band_fraction` of the
    others must look like tape.

    Plain Python on a handful of pixels (`ndarray.item`: ints, so every difference is exact),
    which is several times faster than numpy on arrays this small."""
    height, width = smooth_gray.shape[:2]
    pixel = smooth_gray.item
    last_row, last_col, right_limit = height - 1, width - 1, width - 1.0
    n = tape.polarity_samples
    c = tape.min_contrast_levels
    a_cx, a_cy, a_ux, a_uy = a.cx, a.cy, a.ux, a.uy
    b_cx, b_cy, b_ux, b_uy = b.cx, b.cy, b.ux, b.uy
    needed = tape.min_band_fraction
    seen = 0
    tape_like = 0
    # (Comparisons written out rather than min() and max(): the check runs on a few candidate
    # tapes of every frame, and this takes a third off its time.)
    for k in range(1, n + 1):
        y = y_lo + (y_hi - y_lo) * k / (n + 1)
        r = int(y + 0.5)
        r = 0 if r < 0 else last_row if r > last_row else r
        xa = a_cx + (y - a_cy) * a_ux / a_uy  # LineRow.x_at
        xb = b_cx + (y - b_cy) * b_ux / b_uy
        lo, hi = (xa, xb) if xa < xb else (xb, xa)
        w = hi - lo
        # The band at a quarter, half and three quarters across (clipped to the image).
        col = int(lo + 0.25 * w + 0.5)
        band_1 = pixel(r, 0 if col < 0 else last_col if col > last_col else col)
        col = int(lo + 0.5 * w + 0.5)
        band_2 = pixel(r, 0 if col < 0 else last_col if col > last_col else col)
        col = int(lo + 0.75 * w + 0.5)
        band_3 = pixel(r, 0 if col < 0 else last_col if col > last_col else col)
        # Each side's (lighter, darker) floor point 0.3 and 0.6 band widths beyond its edge
        # (-1, -1: neither inside the image).
        left_light, left_dark = _floor_beside(pixel, r, lo - 0.3 * w, lo - 0.6 * w, right_limit)
        right_light, right_dark = _floor_beside(pixel, r, hi + 0.3 * w, hi + 0.6 * w,
                                                right_limit)
        if left_light < 0:  # no floor point inside the image on the left
            if right_light < 0:
                continue
            left_light, left_dark = right_light, right_dark
        elif right_light < 0:
            right_light, right_dark = left_light, left_dark
        seen += 1
        band_min = band_1 if band_1 < band_2 else band_2
        band_min = band_min if band_min < band_3 else band_3
        band_max = band_1 if band_1 > band_2 else band_2
        band_max = band_max if band_max > band_3 else band_3
        spread = band_max - band_min
        # Beside a dark band the lighter floor point of each side counts, beside a light band
        # the darker one; the floor on both sides must be one floor, shaded at most FLOOR_SHADE.
        step = (left_light if left_light < right_light else right_light) - band_max
        dark_step = band_min - (left_dark if left_dark > right_dark else right_dark)
        if step > c and spread < step and abs(left_light - right_light) < FLOOR_SHADE * step:
            tape_like += 1
        elif (dark_step > c and spread < dark_step
              and abs(left_dark - right_dark) < FLOOR_SHADE * dark_step):
            tape_like += 1
        else:
            continue
        # Settled once the samples left could not bring the share below the minimum even if
        # all of them were seen and none looked like tape (the answer is the same as at the end).
        if tape_like >= needed * (seen + n - k):
            return True
    return seen > 0 and tape_like >= needed * seen


def _floor_beside(pixel: Callable[[int, int], int], r: int, x_near: float, x_far: float,
                  right_limit: float) -> tuple[int, int]:
    """(lighter, darker) of the floor points at columns `x_near` and `x_far` of row `r` that
    lie inside the image (columns 0..`right_limit`; both the one inside where only one is),
    (-1, -1) when neither does."""
    near = pixel(r, int(x_near + 0.5)) if 0.0 <= x_near <= right_limit else -1
    far = pixel(r, int(x_far + 0.5)) if 0.0 <= x_far <= right_limit else -1
    if near < 0:
        return far, far
    if far < 0:
        return near, near
    return (near, far) if near >= far else (far, near)


def outward_normal(direction: Point, side: Side) -> Point:
    """The floor normal pointing away from the lane centre for an edge on `side` running along
    `direction` (away from the robot): left of the direction for a left edge, right for a
    right one."""
    dx, dy = direction
    return (-dy, dx) if side == "left" else (dy, -dx)


def tape_profile_fraction(
    smooth_gray: NDArray[np.uint8],
    rows: list[LineRow],
    chain: tuple[int, ...],
    side: Side,
    view: FloorView,
    tape: TapeConfig,
) -> float | None:
    """Fraction of the points sampled along an edge where the brightness across it looks like
    the INNER edge of a tape: a quarter, half and three quarters of a tape width outwards (on
    the floor, left for a left edge) the brightness is uniform and differs, in the same
    direction, from both the lane floor half a width inwards and the floor 1.75 widths outwards,
    by more than half what those two floor samples differ from each other (`FLOOR_SHADE`). A
    seam fails (the floor just beyond it is floor again), so does, mostly, a boundary between two
    floor shades. Points where the tape would span fewer than MIN_PROFILE_TAPE_PX pixels are
    skipped. None when most samples fall outside the image (a tape at the image border: its far
    side cannot be seen)."""
    height, width = smooth_gray.shape[:2]
    pixel, last_row, kind = smooth_gray.item, height - 1, tape.kind
    c = tape.min_contrast_levels
    near_y = rows[chain[0]].near_y
    far_y = rows[chain[-1]].far_y
    n = tape.polarity_samples
    seen = hidden = tape_like = 0
    member = -1
    outer: tuple[float, float, float, float] | None = None  # in the image (`image_line`)
    for i in range(n):
        y = near_y + (far_y - near_y) * (i + 0.5) / n
        k = member
        while k < len(chain) - 1 and (k < 0 or rows[chain[k]].far_y > y):
            k += 1
        if k != member:
            member = k
            floor_line = _outer_line(rows[chain[member]], side, view, tape.width_m)
            outer = None if floor_line is None else view.image_line(*floor_line)
        if outer is None:
            continue
        line = rows[chain[member]]
        x = line.x_at(y)
        x_tape = column_at(outer, y)
        w = x_tape - x  # signed: outwards in the image
        if not math.isfinite(w) or abs(w) < MIN_PROFILE_TAPE_PX:
            continue
        lo, hi = x - 0.5 * w, x + 1.75 * w
        if min(lo, hi) < 0.0 or max(lo, hi) > width - 1.0:
            hidden += 1
            continue
        # (Pixels as ints through `ndarray.item`, comparisons written out: several times
        # cheaper than numpy scalars and min()/max(), and every difference is exact.)
        r = int(y + 0.5)
        r = 0 if r < 0 else last_row if r > last_row else r
        inner = pixel(r, int(lo + 0.5))
        beyond = pixel(r, int(hi + 0.5))
        b1 = pixel(r, int(x + 0.25 * w + 0.5))
        b2 = pixel(r, int(x + 0.5 * w + 0.5))
        b3 = pixel(r, int(x + 0.75 * w + 0.5))
        seen += 1
        floor_min, floor_max = (inner, beyond) if inner < beyond else (beyond, inner)
        band_min = b1 if b1 < b2 else b2
        band_min = band_min if band_min < b3 else b3
        band_max = b1 if b1 > b2 else b2
        band_max = band_max if band_max > b3 else b3
        darker = floor_min - band_max
        lighter = band_min - floor_max
        step = (darker if kind == "dark" else lighter if kind == "light"
                else darker if darker > lighter else lighter)
        spread = band_max - band_min
        if step > c and spread < step and abs(inner - beyond) < FLOOR_SHADE * step:
            tape_like += 1
    if seen == 0 or hidden > seen:
        return None if hidden else 0.0
    return tape_like / seen


def _outer_line(line: LineRow, side: Side, view: FloorView,
                width_m: float) -> tuple[Point, Point] | None:
    """Two floor points of the line `width_m` outwards of `line` on the floor (where the other
    side of its tape would be), or None when the line has no floor position."""
    a = (line.near_fx, line.near_fy)
    b = (line.far_fx, line.far_fy)
    if not math.isfinite(a[0] + a[1] + b[0] + b[1]):
        return None
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = math.hypot(dx, dy)
    if n < 1e-12:
        return None
    ox, oy = outward_normal((dx / n, dy / n), side)
    return (a[0] + width_m * ox, a[1] + width_m * oy), (b[0] + width_m * ox, b[1] + width_m * oy)
