"""Ground-truth metrics of one simulated run, measured against the world (not against perception).

Inputs are plain arrays per camera frame (time, true pose, supervisor state, halt reason, events)
plus the world and the camera; outputs are numbers for `metrics.json`. Definitions:

- cross-track error: distance from the robot's centre to the lane centre line, over the frames
  where the robot is alongside the marked lane (0 <= arc length <= end of the markings).
- heading error: robot heading minus the centre line's direction there, same frames.
- `distance_past_lane_end_m`: the robot's final centre, measured along the lane's final direction
  from the centre-line point where the markings end (the earlier tape end); negative before it;
  None when the lane never ends.
- `crossed_tape`: the robot's footprint (a 0.35 m disc) overlapped a tape in some frame.
- `lane_loss_to_halt_s`: first HALT time minus the lane-loss time, where lane loss is the first
  frame in which no tape lies inside the camera's region of interest (tape samples projected
  through the camera, tested against the ROI polygon). If the robot halted while tape was still
  in view, within `EXTRAPOLATE_LANE_LOSS_M` of the arc length where a centred robot would lose
  the tape, the loss time is extrapolated at the robot's speed before the halt
  (`lane_loss_estimated: true`). None when the lane never ends, the robot never halted, or it
  halted farther back (for another reason than the lane end).
- `halted`: the controller entered HALT after it had engaged (or never engaged at all).
- `halt_reason`: that HALT's reason; for a run that never engaged, the reason that still held it
  at its last frame (a lane edge inside the robot's footprint, say), as `lanewarden survey` says
  of a still that does not engage, not the "not engaged yet" every run starts with.
- `halt_position`: the true pose where that HALT began (x_m, y_m) and, like
  `distance_past_lane_end_m`, how far past the end of the markings it was; None if not halted.
- `turns_completed`: marks (A, B, ...) whose gate (the segment across the lane, tape to tape, at
  the end of the marked segment) the robot's centre crossed, in order.
- `motion_after_halt`: why a robot that halted did not stop (`motion_after_halt`, the rule the
  campaign's judge calls unsafe): a non-zero command after HALT, or still moving faster than
  `AT_REST_M_S` at the end of a run that went on `STOPPED_AFTER_S` or more after HALT (a base
  whose commands no longer arrive keeps driving its last one); None when it stopped or never
  halted.
- `fault_effects`: when each of the scenario's faults took effect (index, kind, camera frame,
  time); `fault_to_halt`: the last fault that took effect at or before the HALT and how long
  after it the HALT came (None: no fault before the halt, or no halt).
- `lane_not_visible_frames`: frames in which the camera did not show the lane (`LaneContrast`:
  some tape with no contrast the detector could use against the floor beside it, or not in its
  ROI); None when not measured.

`LaneContrast` measures, per delivered frame, the contrast the camera showed between each tape
and the floor beside it (ground truth: the world's tapes projected through the camera model into
the frame's pixels); the simulator records it in `RunTrace.lane_contrast` / `lane_visible`, and
the campaign judge reads it (a halt while the camera showed no lane is not a false halt).

Pure: no clock, no I/O, no rendering.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from lanewarden.actuation.base import Pose2D
from lanewarden.perception.detector import perception_gray
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.world import ROBOT_RADIUS_M, World

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

HALT_STATE = "HALT"
#: A halted robot must be at rest (below AT_REST_M_S) this long after HALT (it brakes in well
#: under a second from any speed it drives at).
STOPPED_AFTER_S = 1.5
AT_REST_M_S = 0.01
#: A halt this close before the point where the lane would leave the view counts as a response to
#: the lane end (lane_loss_to_halt_s is extrapolated); farther back it was about something else.
EXTRAPOLATE_LANE_LOSS_M = 1.0


@dataclass(frozen=True, eq=False)
class RunTrace:
    """What happened, frame by frame: `poses` (N, 3) x, y, theta of the TRUE robot pose."""

    time_s: FloatArray
    poses: FloatArray
    states: Sequence[str]
    halt_reasons: Sequence[str | None]
    events: Sequence[Sequence[str]]
    speed_m_s: FloatArray
    #: (N, tapes) `LaneContrast.measure` per frame, grey levels (NaN: that tape not in the ROI);
    #: None when not measured
    lane_contrast: FloatArray | None = None
    #: per frame: the camera showed the lane (`LaneContrast.visible`); None when not measured
    lane_visible: BoolArray | None = None


def footprint_clearance_m(world: World, poses: FloatArray) -> FloatArray:
    """Per pose (N, >= 2: x, y, ...): how far the robot's footprint is from the nearest tape
    edge, ground truth (m; negative: over it)."""
    return world.clearance_to_edges(np.asarray(poses)[:, :2]) - ROBOT_RADIUS_M


def points_in_polygon(points: FloatArray, polygon: FloatArray) -> BoolArray:
    """Even-odd rule, vectorised over points (N, 2) for one polygon (K, 2)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    poly = np.asarray(polygon, dtype=np.float64).reshape(-1, 2)
    inside = np.zeros(len(pts), dtype=bool)
    x, y = pts[:, 0], pts[:, 1]
    for (x0, y0), (x1, y1) in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        crosses = (y0 > y) != (y1 > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        inside ^= crosses & (x < x_at)
    return inside


def robot_frame(points: FloatArray, pose: Pose2D) -> tuple[FloatArray, FloatArray]:
    """World points (N, 2) in the robot's frame at `pose`: (forward, left), metres."""
    c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
    rel = points - (pose.x_m, pose.y_m)
    return rel[:, 0] * c + rel[:, 1] * s, -rel[:, 0] * s + rel[:, 1] * c


def convex_half_planes(polygon: FloatArray) -> FloatArray | None:
    """A convex polygon (K, 2) as half-planes: rows (a, b, c) with a*x + b*y + c >= 0 inside
    (one per edge, either winding); None when the polygon is not convex (or degenerate)."""
    poly = np.asarray(polygon, dtype=np.float64).reshape(-1, 2)
    edges = np.roll(poly, -1, axis=0) - poly
    keep = np.hypot(edges[:, 0], edges[:, 1]) > 1e-9
    poly, edges = poly[keep], edges[keep]
    if len(poly) < 3:
        return None
    turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(
        edges, -1, axis=0)[:, 0]
    turns = turns[np.abs(turns) > 1e-9]
    if len(turns) < 2 or not (np.all(turns > 0) or np.all(turns < 0)):
        return None
    sign = 1.0 if turns[0] > 0 else -1.0  # left of every edge (y up) is inside when turns > 0
    a, b = -edges[:, 1] * sign, edges[:, 0] * sign
    return np.column_stack([a, b, -(a * poly[:, 0] + b * poly[:, 1])])


def clip_convex(polygon: FloatArray, plane: FloatArray) -> FloatArray:
    """The part of a convex polygon (K, 2) where a*x + b*y + c >= 0 (`plane` (a, b, c))
    (Sutherland-Hodgman; (0, 2) when none of it is)."""
    a, b, c = plane
    kept: list[FloatArray] = []
    for p, q in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        fp, fq = a * p[0] + b * p[1] + c, a * q[0] + b * q[1] + c
        if fp >= 0.0:
            kept.append(p)
        if (fp >= 0.0) != (fq >= 0.0):
            kept.append(p + fp / (fp - fq) * (q - p))
    return np.array(kept, dtype=np.float64).reshape(-1, 2)


class FloorSamples:
    """Fixed floor points (N, 2, world metres: a tape's samples), and a circle around every run
    of `RUN` consecutive ones: `GroundRoi.inside` then tests only the points of the runs whose
    circle reaches the ROI (samples along a tape come in order, so a run is a short stretch of
    it), and finds the same indices as testing them all."""

    RUN = 32

    def __init__(self, points: FloatArray) -> None:
        self.points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        starts = np.arange(0, len(self.points), self.RUN)
        if len(starts):
            low = np.minimum.reduceat(self.points, starts, axis=0)
            high = np.maximum.reduceat(self.points, starts, axis=0)
        else:
            low = high = np.zeros((0, 2))
        self._centres = (low + high) / 2.0
        self._radii = np.hypot(high[:, 0] - low[:, 0], high[:, 1] - low[:, 1]) / 2.0

    def __len__(self) -> int:
        return len(self.points)

    def near(self, x_m: float, y_m: float, radius_m: float) -> NDArray[np.intp]:
        """The indices (in order) of the points in runs whose circle comes within `radius_m` of
        (x_m, y_m): every point that close, and some more."""
        reach = np.hypot(self._centres[:, 0] - x_m, self._centres[:, 1] - y_m)
        runs = reach <= self._radii + radius_m
        return np.nonzero(np.repeat(runs, self.RUN)[:len(self.points)])[0]


class GroundRoi:
    """Which floor points a camera at a pose sees inside perception's ROI.

    `roi_polygon_px` is in UNDISTORTED pixels of the camera's image (perception undistorts before
    applying its ROI); points are projected through the ground homography (the pinhole view),
    within `MAX_RANGE_M` of the robot and inside the image.

    For a convex ROI (the lecture's triangle, clipped to the image) every one of those tests is a
    half-plane in the robot's frame (a homography keeps a line a line in front of the camera), so
    a pose's test is one matrix product over the points in world metres; another polygon is
    tested point by point in pixels (`points_in_polygon`). Those half-planes bound a polygon in
    the robot's frame (a metre or two across, where the camera's ROI meets the floor): given
    `FloorSamples`, only the runs of points whose circle reaches that polygon's are tested.
    """

    MAX_RANGE_M = 8.0
    #: The circle around the ROI's polygon on the floor is this much wider than its corners
    #: (rounding in clipping the polygon must never leave a point out).
    REACH_MARGIN_M = 0.01

    def __init__(self, camera: CameraModel, roi_polygon_px: FloatArray) -> None:
        self._h = camera.ground_to_image_homography()
        self._roi = np.asarray(roi_polygon_px, dtype=np.float64).reshape(-1, 2)
        self._size = (camera.width_px, camera.height_px)
        roi = convex_half_planes(self._roi)
        self._robot_planes: FloatArray | None = None
        if roi is not None:
            w, h = self._size
            hz = self._h[2]
            r = self.MAX_RANGE_M
            # Columns over robot-frame (forward, left, 1): each > 0 inside (the boundary itself,
            # a set of no area, may fall either way).
            self._robot_planes = np.vstack([
                [1.0, 0.0, 0.0], [-1.0, 0.0, r], [0.0, 1.0, r], [0.0, -1.0, r],
                hz - np.array([0.0, 0.0, 1e-9]),  # in front of the camera
                self._h[0], (w - 1) * hz - self._h[0],  # 0 <= u <= w-1 (times z > 0)
                self._h[1], (h - 1) * hz - self._h[1],  # 0 <= v <= h-1
                roi @ self._h,  # inside the ROI
            ]).T
        #: robot-frame (forward, left) centre and radius of a circle holding the ROI on the floor
        self._reach: tuple[float, float, float] | None = None
        if self._robot_planes is not None:
            r = self.MAX_RANGE_M
            region = np.array([[0.0, -r], [r, -r], [r, r], [0.0, r]])
            for plane in self._robot_planes.T:
                region = clip_convex(region, plane)
            if len(region) >= 3:
                centre = (region.min(axis=0) + region.max(axis=0)) / 2.0
                radius = float(np.hypot(*(region - centre).T).max())
                self._reach = (float(centre[0]), float(centre[1]),
                               radius + self.REACH_MARGIN_M)

    def inside(self, pose: Pose2D, points: FloatArray | FloorSamples) -> NDArray[np.intp]:
        """The indices of `points` (N, 2, world metres, or `FloorSamples`) inside the ROI at
        `pose`, in order."""
        if len(points) == 0:
            return np.zeros(0, np.intp)
        runs: FloorSamples | None = None
        if isinstance(points, FloorSamples):
            runs, points = points, points.points
        if self._robot_planes is not None:
            c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
            robot_from_world = np.array([[c, s, -(pose.x_m * c + pose.y_m * s)],
                                         [-s, c, pose.x_m * s - pose.y_m * c],
                                         [0.0, 0.0, 1.0]])
            planes = robot_from_world.T @ self._robot_planes
            if runs is not None and self._reach is not None:
                forward, left, radius = self._reach
                near = runs.near(pose.x_m + c * forward - s * left,
                                 pose.y_m + s * forward + c * left, radius)
                # (The product is row by row: a row's values are the same as among all points.)
                values = runs.points[near] @ planes[:2] + planes[2]
                return near[(values > 0.0).all(axis=1)]
            values = np.asarray(points, dtype=np.float64) @ planes[:2] + planes[2]
            return np.nonzero((values > 0.0).all(axis=1))[0]
        fx, fy = robot_frame(points, pose)
        near = np.nonzero((fx > 0.0) & (fx < self.MAX_RANGE_M)
                          & (np.abs(fy) < self.MAX_RANGE_M))[0]
        hom = np.column_stack([fx[near], fy[near], np.ones(len(near))]) @ self._h.T
        ahead = hom[:, 2] > 1e-9
        near, hom = near[ahead], hom[ahead]
        uv = hom[:, :2] / hom[:, 2:3]
        w, h = self._size
        in_image = (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
        near, uv = near[in_image], uv[in_image]
        return near[points_in_polygon(uv, self._roi)]


class TapeVisibility:
    """Ground truth: is any tape inside the camera's ROI at a pose? (`GroundRoi`)"""

    def __init__(self, world: World, camera: CameraModel, roi_polygon_px: FloatArray) -> None:
        self._samples = FloorSamples(world.tape_samples)
        self._roi = GroundRoi(camera, roi_polygon_px)

    def visible(self, pose: Pose2D) -> bool:
        return self.visible_points(pose, self._samples)

    def visible_points(self, pose: Pose2D, samples: FloatArray | FloorSamples) -> bool:
        """Is any of `samples` (N, 2) world metres inside the ROI at `pose`?"""
        return len(self._roi.inside(pose, samples)) > 0

    def loss_arc_length(self, world: World, step_m: float = 0.01) -> float | None:
        """Arc length at which a robot centred on the lane, facing along it, first sees no tape
        in its ROI (searched from 1.5 m before the end of the markings); None if never."""
        if world.markings_end_s is None:
            return None
        s = max(0.0, world.markings_end_s - 1.5)
        end = world.centreline.length_m
        while s <= end:
            point, heading = world.centreline.at(s)
            if not self.visible(Pose2D(float(point[0]), float(point[1]), heading)):
                return s
            s += step_m
        return None


#: The floor beside a tape is read this many tape widths from its centre line, on both sides (half
#: a tape width of floor between the tape's edge and the sample: clear of the edge's blur).
FLOOR_OFFSET_WIDTHS = 1.0
#: Tape centre-line samples, metres apart, before the ROI is applied.
CONTRAST_STEP_M = 0.02
#: At most this many samples per tape and frame (evenly chosen among those inside the ROI).
CONTRAST_SAMPLES = 24
#: Fewer samples than this inside the ROI: the tape is not in view (its contrast is NaN).
MIN_CONTRAST_SAMPLES = 3


@lru_cache(maxsize=1024)
def _evenly_chosen(count: int) -> NDArray[np.intp]:
    """Which `CONTRAST_SAMPLES` of `count` samples (in order) a tape is read at, evenly spread;
    computed once per count (read-only)."""
    index = np.linspace(0, count - 1, CONTRAST_SAMPLES).round().astype(np.intp)
    index.setflags(write=False)
    return index


def _median(levels: list[int]) -> float:
    """np.median of a few integers, exactly (the mean of the middle two for an even count),
    without its overhead on arrays of two dozen values."""
    ordered = sorted(levels)
    middle = len(ordered) // 2
    if len(ordered) % 2:
        return float(ordered[middle])
    return (ordered[middle - 1] + ordered[middle]) / 2


def _gray_values(frame: NDArray[np.uint8], rows: NDArray[np.intp],
                 cols: NDArray[np.intp], yellow_boost: float = 0.0) -> NDArray[np.int16]:
    """Perception's gray levels (`perception_gray`: OpenCV's BGR->gray, and its
    `yellow_boost`) at a few pixels."""
    picked = frame[rows, cols]
    if picked.ndim == 2:  # colour: convert only the picked pixels, as perception would
        picked = perception_gray(np.ascontiguousarray(picked.reshape(1, -1, picked.shape[1])),
                                 yellow_boost=yellow_boost)
    return np.asarray(picked, dtype=np.int16).reshape(-1)


class LaneContrast:
    """Ground truth: the contrast between each tape and the floor beside it in a frame the camera
    delivered, and whether that shows the lane.

    Samples along each tape's centre line (world metres, `CONTRAST_STEP_M` apart) and on the
    floor `FLOOR_OFFSET_WIDTHS` tape widths to either side are moved into the robot's frame at the
    true pose and projected through the camera model (lens distortion included: the frame's own
    pixels); of those whose centre-line point lies inside perception's ROI (`GroundRoi`, in
    undistorted pixels), at most `CONTRAST_SAMPLES` are read in the frame's gray version. A
    sample's difference is the tape minus the floor on the side more like the tape, 0 when the
    two sides disagree in sign (the detector needs a tape darker, or lighter, than the floor on
    BOTH sides); a tape's contrast is the magnitude of the median difference (a ceiling light
    mirrored in glossy tape, a seam, noise: a minority of samples), NaN with fewer than
    `MIN_CONTRAST_SAMPLES` in the ROI.

    The lane is visible when every tape's contrast reaches `needed_levels`: the detector's
    `perception.tape.min_contrast_levels` divided by the largest stretch its contrast
    normalisation applies (`perception.contrast.max_gain`): a smaller step stays under the
    detector's threshold even after it stretches a flat frame as far as it ever does. A bound
    in the detector's favour (it blurs, and stretches a flat frame less when the frame varies),
    so "not visible" means no detector with these settings could have used the frame.
    Costs a few dozen pixel reads per frame.
    """

    def __init__(self, world: World, camera: CameraModel, roi_polygon_px: FloatArray,
                 needed_levels: float, yellow_boost: float = 0.0) -> None:
        self.needed_levels = needed_levels
        #: perception's `gray.yellow_boost`: the contrast is measured in its gray
        self.yellow_boost = yellow_boost
        self._camera = camera
        self._roi = GroundRoi(camera, roi_polygon_px)
        self._size = (camera.width_px, camera.height_px)
        centres, beside, owner = [], [], []
        for index, tape in enumerate(world.tapes):
            for piece in tape.pieces:
                seg = np.diff(piece, axis=0)
                s = np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])
                if s[-1] <= 0:
                    continue
                t = np.linspace(0.0, s[-1], max(2, math.ceil(s[-1] / CONTRAST_STEP_M) + 1))
                c = np.column_stack([np.interp(t, s, piece[:, 0]), np.interp(t, s, piece[:, 1])])
                d = np.gradient(c, axis=0)
                n = np.column_stack([-d[:, 1], d[:, 0]])
                n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
                centres.append(c)
                beside.append(FLOOR_OFFSET_WIDTHS * tape.width_m * n)
                owner.append(np.full(len(c), index))
        self.tapes = len(world.tapes)
        #: every tape's centre-line samples, the floor either side of each, the tape of each
        self._centre = np.vstack(centres) if centres else np.zeros((0, 2))
        offset = np.vstack(beside) if beside else np.zeros((0, 2))
        #: (3, N, 2): the centre-line samples, then the floor on one side and on the other (one
        #: index picks a sample's three points)
        self._points = np.stack([self._centre, self._centre + offset, self._centre - offset])
        self._tape_of = np.concatenate(owner) if owner else np.zeros(0, np.intp)
        self._centre_runs = FloorSamples(self._centre)

    def measure(self, frame: NDArray[np.uint8], pose: Pose2D) -> FloatArray:
        """Each tape's contrast in `frame` (gray HxW or BGR HxWx3) seen from `pose`, grey levels;
        NaN for a tape not in the ROI. (All tapes in one pass: a few small array operations.)"""
        out = np.full(self.tapes, np.nan)
        w, h = self._size
        in_roi = self._roi.inside(pose, self._centre_runs)
        tape_of = self._tape_of[in_roi]
        groups: list[tuple[int, NDArray[np.intp]]] = []
        for tape in range(self.tapes):
            chosen = in_roi[tape_of == tape]
            if len(chosen) < MIN_CONTRAST_SAMPLES:
                continue
            if len(chosen) > CONTRAST_SAMPLES:
                chosen = chosen[_evenly_chosen(len(chosen))]
            groups.append((tape, chosen))
        if not groups:
            return out
        picked = np.concatenate([chosen for _, chosen in groups])
        world_pts = self._points[:, picked].reshape(-1, 2)
        px = self._camera.project_ground(np.column_stack(robot_frame(world_pts, pose)))
        valid = np.asarray(np.isfinite(px).all(axis=1), dtype=bool)
        # A point not projected is read anywhere (its difference is 0 below).
        px[~valid] = 0.0
        pixel = np.clip(px + 0.5, 0, (w - 1, h - 1)).astype(np.intp)
        values = _gray_values(frame, pixel[:, 1], pixel[:, 0], self.yellow_boost)
        k = len(picked)
        da = values[:k] - values[k:2 * k]
        db = values[:k] - values[2 * k:]
        same = (np.sign(da) == np.sign(db)) & valid[:k] & valid[k:2 * k] & valid[2 * k:]
        diff = np.where(same, np.where(np.abs(da) < np.abs(db), da, db), 0).tolist()
        start = 0
        for tape, chosen in groups:
            out[tape] = abs(_median(diff[start:start + len(chosen)]))
            start += len(chosen)
        return out

    def visible(self, contrast: FloatArray) -> bool:
        """Did a frame with these per-tape contrasts show the lane? (every tape in the ROI with
        at least `needed_levels`; no tape at all: no)"""
        return bool(len(contrast)) and bool(np.all(contrast >= self.needed_levels))


def _wrap(angle: FloatArray) -> FloatArray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


def _segments_cross(p1: FloatArray, p2: FloatArray, a: FloatArray, b: FloatArray) -> BoolArray:
    """Do segments p1[i]->p2[i] cross segment a->b? (vectorised over i)."""

    def orient(p: FloatArray, q: FloatArray, r: FloatArray) -> FloatArray:
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (
            q[..., 1] - p[..., 1]
        ) * (r[..., 0] - p[..., 0])

    d1 = orient(a, b, p1)
    d2 = orient(a, b, p2)
    d3 = orient(p1, p2, a)
    d4 = orient(p1, p2, b)
    return ((d1 > 0) != (d2 > 0)) & ((d3 > 0) != (d4 > 0))


def turns_completed(world: World, poses: FloatArray) -> list[str]:
    """Marks whose gate the robot's centre crossed, ordered by when it first crossed."""
    if len(poses) < 2:
        return []
    p1, p2 = poses[:-1, :2], poses[1:, :2]
    crossings = []
    for name in world.marks:
        a, b = world.gate(name)
        hits = np.nonzero(_segments_cross(p1, p2, a, b))[0]
        if len(hits):
            crossings.append((int(hits[0]), name))
    return [name for _, name in sorted(crossings)]


def _first(mask: BoolArray) -> int | None:
    idx = np.nonzero(mask)[0]
    return int(idx[0]) if len(idx) else None


def first_halt_index(states: Sequence[str]) -> int | None:
    """Index of the first HALT after the controller engaged (every controller starts in HALT,
    waiting for start); 0 if it never engaged at all; None if it never halted."""
    engaged = False
    for i, state in enumerate(states):
        if state != HALT_STATE:
            engaged = True
        elif engaged:
            return i
    return 0 if states and not engaged else None


def motion_after_halt(times: Sequence[float] | FloatArray, states: Sequence[str],
                      commands_nonzero: Sequence[bool], final_speed_m_s: float) -> str | None:
    """Why a robot that halted (after engaging) did not stop, in one line: a non-zero command
    at or after the HALT, or still moving faster than AT_REST_M_S when the run ended
    STOPPED_AFTER_S or more after it. None when it stopped, never halted, or the run ended
    sooner (still braking)."""
    halt = first_halt_index(states)
    if not halt:  # never halted, or never engaged (it never moved)
        return None
    after = [i for i in range(halt, len(states)) if commands_nonzero[i]]
    if after:
        return (f"non-zero command at {float(times[after[0]]):.3f} s after HALT at "
                f"{float(times[halt]):.3f} s")
    settled = float(times[-1]) - float(times[halt]) >= STOPPED_AFTER_S
    if settled and final_speed_m_s > AT_REST_M_S:
        return f"still moving at {final_speed_m_s:.2f} m/s {STOPPED_AFTER_S:g} s or more after HALT"
    return None


def fault_to_halt(effects: Sequence[tuple[int, str, float]],
                  halt_time_s: float | None) -> dict[str, object] | None:
    """The last fault (index, kind, time it took effect) that took effect at or before the HALT,
    and the HALT's delay after it; None without a halt or without such a fault."""
    if halt_time_s is None:
        return None
    before = [e for e in effects if e[2] <= halt_time_s + 1e-9]
    if not before:
        return None
    index, kind, took_effect_s = max(before, key=lambda e: (e[2], e[0]))
    return {"index": index, "kind": kind, "took_effect_s": round(took_effect_s, 4),
            "to_halt_s": round(halt_time_s - took_effect_s, 4)}


def compute_metrics(
    world: World,
    trace: RunTrace,
    tape_in_roi: BoolArray | None,
    loss_arc_length_m: float | None,
) -> dict[str, object]:
    """The ground-truth numbers of one run (see the module docstring for each definition)."""
    poses = np.asarray(trace.poses, dtype=np.float64).reshape(-1, 3)
    times = np.asarray(trace.time_s, dtype=np.float64)
    n = len(poses)
    out: dict[str, object] = {}
    centre = world.centreline
    s, lateral, lane_heading = centre.project(poses[:, :2]) if n else (
        np.zeros(0), np.zeros(0), np.zeros(0))
    lane_stop = world.markings_end_s if world.markings_end_s is not None else centre.length_m
    alongside = (s >= 0.0) & (s <= lane_stop)
    cte = np.abs(lateral[alongside])
    heading_err = np.degrees(np.abs(_wrap(poses[alongside, 2] - lane_heading[alongside])))
    out["max_cross_track_error_m"] = round(float(cte.max()), 4) if len(cte) else None
    out["mean_cross_track_error_m"] = round(float(cte.mean()), 4) if len(cte) else None
    out["max_heading_error_deg"] = round(float(heading_err.max()), 2) if len(cte) else None
    steps = np.hypot(np.diff(poses[:, 0]), np.diff(poses[:, 1])) if n > 1 else np.zeros(0)
    out["distance_travelled_m"] = round(float(steps.sum()), 4)

    halted_idx = first_halt_index(trace.states)
    out["engaged"] = any(st != HALT_STATE for st in trace.states)
    out["halted"] = halted_idx is not None
    # A run that never engaged (`first_halt_index` 0): what still held it at the end (module
    # docstring).
    reason_idx = -1 if halted_idx == 0 else halted_idx
    out["halt_reason"] = None if reason_idx is None else trace.halt_reasons[reason_idx]
    out["halt_time_s"] = None if halted_idx is None else round(float(times[halted_idx]), 4)
    out["final_state"] = trace.states[-1] if n else None
    visited: list[str] = []
    for st in trace.states:
        if st not in visited:
            visited.append(st)
    out["states_visited"] = visited

    final = poses[-1] if n else np.array([world.start_pose.x_m, world.start_pose.y_m, 0.0])
    end = world.lane_end()

    def past_lane_end(pose: FloatArray) -> float | None:
        if end is None:
            return None
        point, heading = end
        along = (pose[0] - point[0]) * math.cos(heading) + (pose[1] - point[1]) * math.sin(
            heading)
        return round(float(along), 4)

    out["distance_past_lane_end_m"] = past_lane_end(final)
    out["halt_position"] = None if halted_idx is None or not n else {
        "x_m": round(float(poses[halted_idx, 0]), 4),
        "y_m": round(float(poses[halted_idx, 1]), 4),
        "past_lane_end_m": past_lane_end(poses[halted_idx]),
    }
    clearance = footprint_clearance_m(world, poses)
    out["crossed_tape"] = bool(n and np.any(clearance < 0.0))
    finite = clearance[np.isfinite(clearance)]
    out["min_tape_clearance_m"] = round(float(finite.min()), 4) if len(finite) else None
    out["turns_completed"] = turns_completed(world, poses)

    loss_time: float | None = None
    estimated = False
    if world.markings_end_s is not None and tape_in_roi is not None and n:
        loss_idx = _first(~np.asarray(tape_in_roi, dtype=bool))
        if loss_idx is not None:
            loss_time = float(times[loss_idx])
        elif halted_idx is not None and loss_arc_length_m is not None:
            window = (times > times[halted_idx] - 1.0) & (times <= times[halted_idx])
            speed = float(np.mean(trace.speed_m_s[window])) if window.any() else 0.0
            remaining = loss_arc_length_m - float(s[halted_idx])
            if speed > 1e-3 and 0 < remaining <= EXTRAPOLATE_LANE_LOSS_M:
                loss_time = float(times[halted_idx]) + remaining / speed
                estimated = True
    out["lane_loss_time_s"] = None if loss_time is None else round(loss_time, 4)
    out["lane_loss_estimated"] = estimated
    if loss_time is None or halted_idx is None:
        out["lane_loss_to_halt_s"] = None
    else:
        out["lane_loss_to_halt_s"] = round(float(times[halted_idx]) - loss_time, 4)

    out["stop_pose"] = {
        "x_m": round(float(final[0]), 4),
        "y_m": round(float(final[1]), 4),
        "theta_deg": round(math.degrees(float(final[2])), 2),
    }
    out["stop_lane_s_m"] = round(float(s[-1]), 4) if n else None
    event_counts: dict[str, int] = {}
    for frame_events in trace.events:
        for event in frame_events:
            event_counts[event] = event_counts.get(event, 0) + 1
    out["event_counts"] = event_counts
    out["lane_not_visible_frames"] = None if trace.lane_visible is None else int(
        np.count_nonzero(~np.asarray(trace.lane_visible, dtype=bool)))
    return out
