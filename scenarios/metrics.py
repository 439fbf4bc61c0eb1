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
- `halt_position`: the true pose where that HALT began (x_m, y_m) and, like
  `distance_past_lane_end_m`, how far past the end of the markings it was; None if not halted.
- `turns_completed`: marks (A, B, ...) whose gate (the segment across the lane, tape to tape, at
  the end of the marked segment) the robot's centre crossed, in order.

Pure: no clock, no I/O, no rendering.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lanewarden.actuation.base import Pose2D
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.world import ROBOT_RADIUS_M, World

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

HALT_STATE = "HALT"
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


class TapeVisibility:
    """Ground truth: is any tape inside the camera's ROI at a pose?

    `roi_polygon_px` is in UNDISTORTED pixels of the camera's image (perception undistorts before
    applying its ROI); it is clipped to the image.
    """

    def __init__(self, world: World, camera: CameraModel, roi_polygon_px: FloatArray) -> None:
        self._samples = world.tape_samples
        self._h = camera.ground_to_image_homography()
        self._roi = np.asarray(roi_polygon_px, dtype=np.float64).reshape(-1, 2)
        self._size = (camera.width_px, camera.height_px)
        self._max_range_m = 8.0

    def visible(self, pose: Pose2D) -> bool:
        return self.visible_points(pose, self._samples)

    def visible_points(self, pose: Pose2D, samples: FloatArray) -> bool:
        """Is any of `samples` (N, 2) world metres inside the ROI at `pose`?"""
        if len(samples) == 0:
            return False
        c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
        rel = samples - (pose.x_m, pose.y_m)
        fx = rel[:, 0] * c + rel[:, 1] * s
        fy = -rel[:, 0] * s + rel[:, 1] * c
        near = (fx > 0.0) & (fx < self._max_range_m) & (np.abs(fy) < self._max_range_m)
        if not near.any():
            return False
        pts = np.column_stack([fx[near], fy[near], np.ones(int(near.sum()))])
        hom = pts @ self._h.T
        ok = hom[:, 2] > 1e-9
        uv = hom[ok, :2] / hom[ok, 2:3]
        w, h = self._size
        in_image = (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
        if not in_image.any():
            return False
        return bool(points_in_polygon(uv[in_image], self._roi).any())

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
    out["halt_reason"] = None if halted_idx is None else trace.halt_reasons[halted_idx]
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
    clearance = world.clearance_to_edges(poses[:, :2]) - ROBOT_RADIUS_M
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
    return out
