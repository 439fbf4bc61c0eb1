"""What a ground model means for the lane detector, in numbers and in a picture.

- `summarize_ground`: the horizon row, the look-ahead row and the floor distance it looks at, the
  size of a pixel on the floor there (mm per pixel, across and along), and the strongest slope
  sum this camera sees driving into and through a 90° bend of radius 0.5 m and 1 m
  (`bend_slope_sum`), so the lecture's ±6 turn threshold can be chosen knowingly.
- `draw_ground_check`: the floor grid (every 0.1 m), the horizon, the look-ahead row, an ideal
  straight lane and, for a chessboard calibration, the detected corners against where the solved
  pose puts them, drawn over the undistorted photo (or a blank frame).

The bend slope sum is computed the way the detector measures a lane edge (see
`perception.geometry` and `perception.edge_choice`): each tape's INNER edge, from where it enters
the image to where it crosses the look-ahead row (or its last visible point), with the lecture's
bounded, side-aware slope. The robot drives along the lane's centre line, heading along it, from
1.5 m before the bend to its end; the reported value is the strongest sum over the poses where
both edges are measured (a camera that loses the inner edge in the bend never reports it there).
Lane and tape widths are the lecture's defaults unless given.

Pure: a model and numbers in, numbers or an image out; no files, no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.geometry import Side, edge_slope
from lanewarden.perception.ground import GroundModel
from lanewarden.perception.size_setup import resolved_look_ahead_m

FloatArray = NDArray[np.float64]

#: Bend radii whose slope sums `calibrate ground` reports.
REPORTED_BEND_RADII_M = (0.5, 1.0)

Turn = Literal["left", "right"]


@dataclass(frozen=True)
class BendSlopeSums:
    """The strongest slope sum driving through a 90° bend of `radius_m` (lane centre line),
    turning right and left (None where the camera never measures both edges)."""

    radius_m: float
    right: float | None
    left: float | None


@dataclass(frozen=True)
class GroundSummary:
    """- `horizon_y_px`: the horizon's row at the image centre (negative: above the image).
    - `look_ahead_y_px`: the row where lane edges are measured; `look_ahead_m`: the forward
      distance (robot frame) of the floor seen there (NaN if at or above the horizon).
    - `mm_per_px_across/along_at_look_ahead`: floor size of one pixel at that row's centre.
    - `bends`: slope sums in bends (`REPORTED_BEND_RADII_M`) on a lane `lane_width_m` between
      tape centres, tape `tape_width_m` wide (perception's config)."""

    horizon_y_px: float
    look_ahead_y_px: float
    look_ahead_m: float
    mm_per_px_across_at_look_ahead: float
    mm_per_px_along_at_look_ahead: float
    bends: tuple[BendSlopeSums, ...]
    lane_width_m: float
    tape_width_m: float

    def as_json(self) -> dict[str, object]:
        return {
            "horizon_y_px": round(self.horizon_y_px, 1),
            "look_ahead_y_px": round(self.look_ahead_y_px, 1),
            "look_ahead_m": _rounded(self.look_ahead_m, 3),
            "mm_per_px_at_look_ahead": _rounded(self.mm_per_px_across_at_look_ahead, 2),
            "mm_per_px_along_at_look_ahead": _rounded(self.mm_per_px_along_at_look_ahead, 2),
            "bend_slope_sums": [
                {"radius_m": b.radius_m, "right": _rounded(b.right, 2),
                 "left": _rounded(b.left, 2)} for b in self.bends],
        }


def _rounded(value: float | None, digits: int) -> float | None:
    return None if value is None or not math.isfinite(value) else round(value, digits)


def look_ahead_row(model: GroundModel, perception: PerceptionConfig) -> float:
    """The image row where the detector measures lane edges: `edges.look_ahead_m` ahead of the
    robot's centre on this camera, or the distance `auto` chooses for it
    (`perception.size_setup.resolved_look_ahead_m`); nan when that floor line is out of view or
    auto finds none."""
    distance = resolved_look_ahead_m(model, perception)
    return math.nan if math.isnan(distance) else model.row_at_distance(distance)


def summarize_ground(model: GroundModel, perception: PerceptionConfig) -> GroundSummary:
    """What this camera sees with this perception config (the bends on a lane of
    `perception.lane.width_m` between tape centres, tape `perception.tape.width_m`)."""
    lane_width_m, tape_width_m = perception.lane.width_m, perception.tape.width_m
    row = look_ahead_row(model, perception)
    u = model.image_size[0] / 2.0
    max_slope = perception.edges.max_abs_slope
    bends = tuple(
        BendSlopeSums(radius, *(bend_slope_sum(model, radius, turn, row, max_slope,
                                               lane_width_m, tape_width_m)
                                for turn in ("right", "left")))
        for radius in REPORTED_BEND_RADII_M)
    return GroundSummary(
        horizon_y_px=model.horizon_v(),
        look_ahead_y_px=row,
        look_ahead_m=model.distance_at_row(row),
        mm_per_px_across_at_look_ahead=1000.0 * model.metres_per_px_across(u, row),
        mm_per_px_along_at_look_ahead=1000.0 * model.metres_per_px_along(u, row),
        bends=bends,
        lane_width_m=lane_width_m,
        tape_width_m=tape_width_m,
    )


#: The bend the slope sums are reported for: a straight, a 90 degree arc, a straight.
_BEND_TURN_RAD = 0.5 * math.pi
_LEG_M = 2.0
#: The robot drives along the centre line from this far before the arc to the arc's end.
_APPROACH_M = 1.5
_POSE_STEP_M = 0.02
_EDGE_STEP_M = 0.004
#: Wider bends are followed for this arc length only (no camera sees farther).
_ARC_CAP_M = 3.0


def inner_edge_points(radius_m: float, turn: Turn, side: Side, lane_width_m: float,
                      tape_width_m: float) -> FloatArray:
    """(N, 2) points along one tape's INNER edge of a lane that runs straight along +x up to
    the origin, bends by 90 degrees with `radius_m` (centre line) and runs straight again, in
    driving order (world frame, metres). Empty when the bend is too sharp for that edge."""
    inner = lane_width_m / 2.0 - tape_width_m / 2.0  # centre line -> inner edge
    offset = inner if side == "left" else -inner  # to the left of the centre line
    sign = -1.0 if turn == "right" else 1.0  # +1: the bend's centre lies to the left (y > 0)
    radius = radius_m - sign * offset
    if radius <= 0:
        return np.zeros((0, 2))
    before = np.arange(-_LEG_M, 0.0, _EDGE_STEP_M)
    straight_in = np.column_stack([before, np.full_like(before, offset)])
    turn_rad = min(_BEND_TURN_RAD, _ARC_CAP_M / radius_m)
    phi = np.linspace(0.0, turn_rad, max(8, int(radius * turn_rad / _EDGE_STEP_M)))
    arc = np.column_stack([radius * np.sin(phi), sign * (radius_m - radius * np.cos(phi))])
    if turn_rad < _BEND_TURN_RAD:
        return np.vstack([straight_in, arc])
    after = np.arange(_EDGE_STEP_M, _LEG_M, _EDGE_STEP_M)
    end = arc[-1]
    straight_out = np.column_stack([np.full_like(after, end[0]), end[1] + sign * after])
    return np.vstack([straight_in, arc, straight_out])


def centre_line_poses(radius_m: float, turn: Turn) -> FloatArray:
    """(M, 3) robot poses (x, y, heading) on the centre line of that lane, from `_APPROACH_M`
    before the bend to its end (at most `_APPROACH_M` into it), every 2 cm."""
    sign = -1.0 if turn == "right" else 1.0
    approach = np.arange(-_APPROACH_M, 0.0, _POSE_STEP_M)
    straight = np.column_stack([approach, np.zeros_like(approach), np.zeros_like(approach)])
    turn_rad = min(_BEND_TURN_RAD, _APPROACH_M / radius_m)
    phi = np.arange(0.0, turn_rad + 1e-9, _POSE_STEP_M / radius_m)
    arc = np.column_stack([radius_m * np.sin(phi), sign * radius_m * (1.0 - np.cos(phi)),
                           sign * phi])
    return np.vstack([straight, arc])


def visible_chord(px: FloatArray, image_size: tuple[int, int],
                  look_ahead_v: float) -> tuple[float, float, float, float] | None:
    """(x1, y1, x2, y2) pixels: an edge's nearest visible point (where it enters the image)
    and where it then crosses the look-ahead row (or its last visible point), for the edge's
    pixels `px` (N, 2; NaN behind the camera) in driving order; None when fewer than two points
    are seen or the edge first appears above the look-ahead row."""
    width, height = image_size
    right, bottom = width - 1.0, height - 1.0
    finite = np.asarray(np.isfinite(px).all(axis=1), dtype=bool)
    seen = finite & (px[:, 0] >= 0) & (px[:, 0] <= right) & (px[:, 1] >= 0) & (
        px[:, 1] <= bottom)
    index = np.flatnonzero(seen)
    if len(index) < 2:
        return None
    start = int(index[0])
    gone = np.flatnonzero(~seen[start:])
    run = px[start:start + int(gone[0])] if len(gone) else px[start:]
    if len(run) < 2:
        return None
    x1, y1 = run[0]
    if start > 0 and finite[start - 1]:  # move the near end onto the image border
        (xa, ya), (xb, yb) = px[start - 1], run[0]
        t = 0.0
        for a, b, low, high in ((xa, xb, 0.0, right), (ya, yb, 0.0, bottom)):
            if a < low:
                t = max(t, (low - a) / (b - a))
            elif a > high:
                t = max(t, (high - a) / (b - a))
        x1, y1 = xa + t * (xb - xa), ya + t * (yb - ya)
    crossing = np.flatnonzero(run[:, 1] <= look_ahead_v)
    if len(crossing) and crossing[0] > 0:
        k = int(crossing[0])
        (xa, ya), (xb, yb) = run[k - 1], run[k]
        t = (ya - look_ahead_v) / max(ya - yb, 1e-12)
        x2, y2 = xa + t * (xb - xa), look_ahead_v
    elif len(crossing):
        return None  # the edge is first seen above the look-ahead row: not measured
    else:
        x2, y2 = run[-1]
    return float(x1), float(y1), float(x2), float(y2)


def bend_slope_sum(model: GroundModel, radius_m: float, turn: Turn, look_ahead_v: float,
                   max_abs_slope: float, lane_width_m: float,
                   tape_width_m: float) -> float | None:
    """The strongest slope sum (most negative for a right bend, most positive for a left one)
    while the robot drives along the centre line into and through a 90 degree bend of
    `radius_m`, over the poses where both inner edges are measured; None when there is none."""
    edges = {side: inner_edge_points(radius_m, turn, side, lane_width_m, tape_width_m)
             for side in ("left", "right")}
    if any(len(points) == 0 for points in edges.values()):
        return None
    homogeneous = {side: np.column_stack([p, np.ones(len(p))]) for side, p in edges.items()}
    sums: list[float] = []
    for x, y, heading in centre_line_poses(radius_m, turn):
        c, s_ = math.cos(heading), math.sin(heading)
        world_to_robot = np.array([[c, s_, -(c * x + s_ * y)], [-s_, c, s_ * x - c * y],
                                   [0.0, 0.0, 1.0]])
        h = model.floor_to_image_h @ world_to_robot
        total = 0.0
        for side, points in homogeneous.items():
            hom = points @ h.T
            with np.errstate(divide="ignore", invalid="ignore"):
                px = np.where(hom[:, 2:3] > 1e-12, hom[:, :2] / hom[:, 2:3], np.nan)
            chord = visible_chord(px, model.image_size, look_ahead_v)
            if chord is None:
                break
            total += edge_slope(*chord, "left" if side == "left" else "right", max_abs_slope)
        else:
            sums.append(total)
    if not sums:
        return None
    return min(sums) if turn == "right" else max(sums)


# ------------------------------------------------------------------------------- check picture

_GRID_STEP_M = 0.1
_GRID_FAR_M = 4.0
_GRID_HALF_WIDTH_M = 1.5


def _polyline(model: GroundModel, floor_points: FloatArray) -> list[NDArray[np.int32]]:
    """The image polylines (pieces in front of the camera and inside a sane pixel range)."""
    px = model.floor_to_image(floor_points)
    ok = np.asarray(np.isfinite(px).all(axis=1) & (np.abs(px) < 1e5).all(axis=1), dtype=bool)
    pieces: list[NDArray[np.int32]] = []
    current: list[FloatArray] = []
    for good, point in zip(ok, px, strict=True):
        if good:
            current.append(point)
        elif current:
            pieces.append(np.rint(np.array(current)).astype(np.int32))
            current = []
    if current:
        pieces.append(np.rint(np.array(current)).astype(np.int32))
    return [p for p in pieces if len(p) >= 2]


def draw_ground_check(
    image: np.ndarray | None,
    model: GroundModel,
    lines: list[str],
    *,
    look_ahead_v: float | None = None,
    corners_px: FloatArray | None = None,
    corners_floor: FloatArray | None = None,
    lane_width_m: float,
) -> NDArray[np.uint8]:
    """A BGR picture: `image` (undistorted; None: a blank frame of the model's size) with the
    floor grid every 0.1 m (thicker every 0.5 m, labelled with the forward distance), the
    horizon (red), the look-ahead row (yellow), an ideal straight lane's tape centres (green)
    and, when given, the detected board corners (green circles) against the solved projection
    of their true floor positions (red crosses). `lines`: the caption, in the top-left corner
    or wherever it leaves the look-ahead row in sight (`caption_top`)."""
    width, height = model.image_size
    canvas: NDArray[np.uint8]
    if image is None:
        canvas = np.full((height, width, 3), 60, np.uint8)
    elif image.ndim == 2:
        canvas = np.asarray(cv2.cvtColor(image, cv2.COLOR_GRAY2BGR), dtype=np.uint8)
    else:
        canvas = np.ascontiguousarray(image[:, :, :3], dtype=np.uint8).copy()
    near = max(0.0, model.pose.forward_m)
    xs = np.arange(0.0, _GRID_FAR_M + 1e-9, _GRID_STEP_M)
    ys = np.arange(-_GRID_HALF_WIDTH_M, _GRID_HALF_WIDTH_M + 1e-9, _GRID_STEP_M)
    dense_y = np.linspace(-_GRID_HALF_WIDTH_M, _GRID_HALF_WIDTH_M, 121)
    dense_x = np.linspace(near, _GRID_FAR_M, 161)
    for x in xs:
        if x < near:
            continue
        major = abs(x / 0.5 - round(x / 0.5)) < 1e-6
        for piece in _polyline(model, np.column_stack([np.full_like(dense_y, x), dense_y])):
            cv2.polylines(canvas, [piece], False, (255, 255, 255) if major else (170, 170, 170),
                          2 if major else 1, cv2.LINE_AA)
        if major and x > 0:
            u, v = model.pixel_at(float(x), model.pose.lateral_m)
            if math.isfinite(u) and 0 <= v < height and 0 <= u < width:
                cv2.putText(canvas, f"{x:.1f} m", (int(u) + 4, int(v) - 4),
                            cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    for y in ys:
        major = abs(y / 0.5 - round(y / 0.5)) < 1e-6
        for piece in _polyline(model, np.column_stack([dense_x, np.full_like(dense_x, y)])):
            cv2.polylines(canvas, [piece], False, (255, 255, 255) if major else (170, 170, 170),
                          2 if major else 1, cv2.LINE_AA)
    for y in (lane_width_m / 2.0, -lane_width_m / 2.0):
        for piece in _polyline(model, np.column_stack([dense_x, np.full_like(dense_x, y)])):
            cv2.polylines(canvas, [piece], False, (60, 200, 60), 2, cv2.LINE_AA)
    h_left, h_right = model.horizon_v(0.0), model.horizon_v(float(width))
    if all(math.isfinite(v) and abs(v) < 1e5 for v in (h_left, h_right)):
        cv2.line(canvas, (0, round(h_left)), (width - 1, round(h_right)), (40, 40, 230), 2,
                 cv2.LINE_AA)
    if corners_px is not None:
        for u, v in np.asarray(corners_px, dtype=np.float64).reshape(-1, 2):
            cv2.circle(canvas, (round(u), round(v)), 4, (60, 220, 60), 1, cv2.LINE_AA)
    if corners_floor is not None:
        for piece in model.floor_to_image(np.asarray(corners_floor).reshape(-1, 2)):
            if np.all(np.isfinite(piece)) and np.all(np.abs(piece) < 1e5):
                cv2.drawMarker(canvas, (round(piece[0]), round(piece[1])), (40, 40, 230),
                               cv2.MARKER_CROSS, 7, 1, cv2.LINE_AA)
    texts = [t.replace("°", " deg").encode("ascii", "replace").decode()  # Hershey: ASCII
             for t in lines]
    sizes = [cv2.getTextSize(t, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1) for t in texts]
    block_px = 0 if not sizes else _CAPTION_LINE_PX * (len(sizes) - 1) + max(
        h + base + 4 for (_, h), base in sizes)
    row = look_ahead_v if look_ahead_v is not None and math.isfinite(look_ahead_v) else None
    first = caption_top(height, block_px, row)
    for i, (text, ((w, h), base)) in enumerate(zip(texts, sizes, strict=True)):
        top = first + _CAPTION_LINE_PX * i
        cv2.rectangle(canvas, (4, top), (12 + w, top + h + base + 4), (0, 0, 0), cv2.FILLED)
        cv2.putText(canvas, text, (8, top + h + 2), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                    (255, 255, 255), 1, cv2.LINE_AA)
    if row is not None:  # last: nothing is drawn over it
        cv2.line(canvas, (0, round(row)), (width - 1, round(row)), (0, 220, 240), 1, cv2.LINE_AA)
    return canvas


#: The caption's line pitch and its clearance from the image's edge and the look-ahead row, px.
_CAPTION_LINE_PX = 18
_CAPTION_MARGIN_PX = 4


def caption_top(height_px: int, block_px: int, look_ahead_v: float | None) -> int:
    """The first row of the check picture's caption, a block `block_px` tall: the top-left
    corner, unless it would cover the look-ahead row (a steep camera looks ahead near the top
    of its image, row 31 for one), then the bottom-left corner, then just below or above the
    row. An image too short for any of these gets the top (the row is drawn over it)."""
    margin = _CAPTION_MARGIN_PX
    places = [margin, height_px - margin - block_px]
    if look_ahead_v is not None:
        places += [round(look_ahead_v) + margin, round(look_ahead_v) - margin - block_px]
    for top in places:
        inside = 0 <= top and top + block_px <= height_px
        if inside and (look_ahead_v is None
                       or not top - margin < look_ahead_v < top + block_px + margin):
            return top
    return margin
