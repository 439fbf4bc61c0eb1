"""The simulated world as data and geometry: the lane's centre line, tapes, floor and light.

World frame: x, y in metres on the floor, theta counter-clockwise from +x (the same frame as
`actuation.base.Pose2D`). The lane is a centre line sampled every `SAMPLE_STEP_M`; each tape is a
polyline offset from it by half the lane width (left tape to the left of the direction of travel),
present along the intervals of arc length that gaps, dashes and ends leave.

Pure: no pixels (see `scenarios.texture`), no clock, no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray

from lanewarden.actuation.base import Pose2D
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.spec import (
    FloorSpec,
    LightingSpec,
    ScenarioSpec,
    SegmentSpec,
    TapeSide,
    TapeSpec,
    color_bgr,
)

FloatArray = NDArray[np.float64]

#: Spacing of the centre-line samples, metres.
SAMPLE_STEP_M = 0.005
#: The robot's footprint (Kobuki: 0.35 m across).
ROBOT_RADIUS_M = 0.175
#: Largest floor a world may cover (its rendered extent, margins included), square metres: the
#: lecture's course is 170 m^2. Checked before the floor is painted (see `scenarios.texture`).
MAX_FLOOR_AREA_M2 = 300.0


@dataclass(frozen=True, eq=False)
class Centreline:
    """The lane's centre line: `points` (N, 2) world metres, arc length `s` (N,), `heading` (N,)
    radians (direction of travel)."""

    points: FloatArray
    s: FloatArray
    heading: FloatArray

    @property
    def length_m(self) -> float:
        return float(self.s[-1])

    def at(self, s: float) -> tuple[FloatArray, float]:
        """Point and heading at arc length `s` (clamped to the line)."""
        s = min(max(s, 0.0), self.length_m)
        x = float(np.interp(s, self.s, self.points[:, 0]))
        y = float(np.interp(s, self.s, self.points[:, 1]))
        return np.array([x, y]), float(np.interp(s, self.s, np.unwrap(self.heading)))

    def project(self, points: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """For world points (M, 2): arc length of the nearest centre-line point, signed lateral
        offset (metres, + to the left of the direction of travel) and the heading there."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        s_out = np.empty(len(pts))
        lateral = np.empty(len(pts))
        heading = np.empty(len(pts))
        for start, chunk, d2 in _vertex_distances_sq(pts, self.points):
            idx = d2.argmin(axis=1)
            h = self.heading[idx]
            tangent = np.column_stack([np.cos(h), np.sin(h)])
            rel = chunk - self.points[idx]
            along = (rel * tangent).sum(axis=1)
            done = slice(start, start + len(chunk))
            s_out[done] = self.s[idx] + along
            lateral[done] = tangent[:, 0] * rel[:, 1] - tangent[:, 1] * rel[:, 0]
            heading[done] = h
        return s_out, lateral, heading

    def offset(self, s_from: float, s_to: float, offset_m: float) -> FloatArray:
        """The polyline `offset_m` to the left of the centre line between two arc lengths."""
        inside = (self.s > s_from) & (self.s < s_to)
        s_values = np.concatenate([[s_from], self.s[inside], [s_to]])
        xs = np.interp(s_values, self.s, self.points[:, 0])
        ys = np.interp(s_values, self.s, self.points[:, 1])
        h = np.interp(s_values, self.s, np.unwrap(self.heading))
        return np.column_stack([xs - offset_m * np.sin(h), ys + offset_m * np.cos(h)])


def build_centreline(
    start: Pose2D, segments: list[SegmentSpec]
) -> tuple[Centreline, dict[str, float]]:
    """Sample the centre line of straight segments and arcs; also the arc length of each mark."""
    xs, ys, hs, ss = [start.x_m], [start.y_m], [start.theta_rad], [0.0]
    marks: dict[str, float] = {}
    for seg in segments:
        x, y, h, s = xs[-1], ys[-1], hs[-1], ss[-1]
        if seg.straight_m is not None:
            length = seg.straight_m
            n = max(1, math.ceil(length / SAMPLE_STEP_M))
            t = np.linspace(0.0, length, n + 1)[1:]
            xs.extend(x + t * math.cos(h))
            ys.extend(y + t * math.sin(h))
            hs.extend([h] * n)
        else:
            assert seg.arc_radius_m is not None and seg.turn_deg is not None
            radius = seg.arc_radius_m
            turn = math.radians(seg.turn_deg)
            length = radius * abs(turn)
            n = max(1, math.ceil(length / SAMPLE_STEP_M))
            side = 1.0 if turn > 0 else -1.0
            cx, cy = x - side * radius * math.sin(h), y + side * radius * math.cos(h)
            angles = h + np.linspace(0.0, turn, n + 1)[1:]
            xs.extend(cx + side * radius * np.sin(angles))
            ys.extend(cy - side * radius * np.cos(angles))
            hs.extend(angles)
        ss.extend(s + np.linspace(0.0, length, n + 1)[1:])
        if seg.mark is not None:
            if seg.mark in marks:
                raise ScenarioError(f"lane.segments: mark {seg.mark!r} used twice")
            marks[seg.mark] = ss[-1]
    points = np.column_stack([xs, ys])
    return Centreline(points, np.asarray(ss), np.asarray(hs)), marks


Interval = tuple[float, float]


def _subtract(intervals: list[Interval], cut: Interval) -> list[Interval]:
    out: list[tuple[float, float]] = []
    for a, b in intervals:
        if cut[1] <= a or cut[0] >= b:
            out.append((a, b))
            continue
        if cut[0] > a:
            out.append((a, cut[0]))
        if cut[1] < b:
            out.append((cut[1], b))
    return out


def _applies(side: TapeSide, tape: str) -> bool:
    return side == "both" or side == tape


@dataclass(frozen=True, eq=False)
class Tape:
    """One line of tape: `side` left or right (a lane edge) or centre (a single-line track).
    `pieces` are the tape's centre polylines (world metres) where it is present, `intervals` the
    matching arc-length intervals of the lane centre line; `look` its width, colour, sheen and
    damage (`TapeSpec` of its side); `end_cuts` the angle (radians from square) each piece's
    start and end are cut at."""

    side: str
    offset_m: float
    width_m: float
    color_bgr: tuple[int, int, int]
    intervals: tuple[tuple[float, float], ...]
    pieces: tuple[FloatArray, ...]
    look: TapeSpec = field(default_factory=TapeSpec)
    end_cuts: tuple[tuple[float, float], ...] = ()

    @property
    def is_edge(self) -> bool:
        """A lane edge (the robot must stay between the edges), not a centre line."""
        return self.side != "centre"

    def outlines(self) -> list[FloatArray]:
        """Each piece as a closed ribbon polygon (left edge then the right edge reversed), its
        ends cut at `end_cuts`."""
        out = []
        half = self.width_m / 2.0
        for i, piece in enumerate(self.pieces):
            d = np.gradient(piece, axis=0)
            tangent = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
            n = np.column_stack([-tangent[:, 1], tangent[:, 0]])
            left, right = piece + half * n, piece - half * n
            if i < len(self.end_cuts):
                # A cut at angle a moves the left corner along the tape by +half tan a and the
                # right one by -half tan a (start and end alike).
                for end, angle in ((0, self.end_cuts[i][0]), (-1, self.end_cuts[i][1])):
                    shift = half * math.tan(angle) * tangent[end]
                    left[end] = left[end] + shift
                    right[end] = right[end] - shift
            out.append(np.vstack([left, right[::-1]]))
        return out

    def surface_samples(self, step_m: float = 0.01) -> FloatArray:
        """Points covering the tape (its centre line and both edges), (N, 2) world metres."""
        pts = []
        for piece in self.pieces:
            seg = np.diff(piece, axis=0)
            lengths = np.hypot(seg[:, 0], seg[:, 1])
            s = np.concatenate([[0.0], np.cumsum(lengths)])
            if s[-1] <= 0:
                continue
            t = np.linspace(0.0, s[-1], max(2, math.ceil(s[-1] / step_m) + 1))
            cx, cy = np.interp(t, s, piece[:, 0]), np.interp(t, s, piece[:, 1])
            d = np.gradient(np.column_stack([cx, cy]), axis=0)
            n = np.column_stack([-d[:, 1], d[:, 0]])
            n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
            centre = np.column_stack([cx, cy])
            for k in (-0.45, 0.0, 0.45):
                pts.append(centre + k * self.width_m * n)
        return np.vstack(pts) if pts else np.zeros((0, 2))


@dataclass(frozen=True, eq=False)
class World:
    """Everything the renderer draws and the metrics measure against."""

    name: str
    floor: FloorSpec
    lighting: LightingSpec
    centreline: Centreline
    lane_width_m: float
    tapes: tuple[Tape, ...]
    marks: Mapping[str, float]
    #: Arc length where the markings end (the earlier tape end); None: the lane never ends.
    markings_end_s: float | None
    start_pose: Pose2D
    #: The rendered extent (x_min, y_min, x_max, y_max), metres.
    bounds: tuple[float, float, float, float]
    tape_samples: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))

    def gate(self, name: str) -> tuple[FloatArray, FloatArray]:
        """The segment across the lane, tape centre to tape centre, at mark `name`."""
        point, heading = self.centreline.at(self.marks[name])
        normal = np.array([-math.sin(heading), math.cos(heading)])
        half = self.lane_width_m / 2.0
        return point - half * normal, point + half * normal

    def lane_end(self) -> tuple[FloatArray, float] | None:
        """Centre-line point and heading where the markings end, or None."""
        if self.markings_end_s is None:
            return None
        return self.centreline.at(self.markings_end_s)

    def distance_to_tape(self, points: FloatArray) -> FloatArray:
        """Distance from each point (M, 2) to the nearest tape centre line (inf without tape)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        best = np.full(len(pts), np.inf)
        for tape in self.tapes:
            for piece in tape.pieces:
                best = np.minimum(best, distance_to_polyline(pts, piece))
        return best

    def clearance_to_edges(self, points: FloatArray) -> FloatArray:
        """Distance from each point (M, 2) to the nearest lane edge (a tape's near side: its
        centre line minus half its width; inf without edges). A single-line track's edges are
        the lane's sides, `lane_width_m` apart, where nothing is taped."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        best = np.full(len(pts), np.inf)
        for tape in self.tapes:
            if tape.is_edge:
                for piece in tape.pieces:
                    best = np.minimum(best, distance_to_polyline(pts, piece) - tape.width_m / 2)
        if not any(tape.is_edge for tape in self.tapes) and self.tapes:
            c = self.centreline
            for offset in (self.lane_width_m / 2.0, -self.lane_width_m / 2.0):
                best = np.minimum(best, distance_to_polyline(
                    pts, c.offset(0.0, c.length_m, offset)))
        return best

    def inside_bounds(self, x: float, y: float, margin_m: float = 0.0) -> bool:
        x0, y0, x1, y1 = self.bounds
        return x0 + margin_m <= x <= x1 - margin_m and y0 + margin_m <= y <= y1 - margin_m


#: Points measured together against a polyline: small enough that the (points x vertices) work
#: arrays stay in the CPU cache (larger blocks run several times slower).
_POINTS_PER_BLOCK = 32


def _vertex_distances_sq(points: FloatArray,
                        line: FloatArray) -> Iterator[tuple[int, FloatArray, FloatArray]]:
    """Blocks of `points` (M, 2) with their squared distances to every vertex of `line` (N, 2):
    yields (index of the block's first point, block (B, 2), squared distances (B, N))."""
    vx, vy = np.ascontiguousarray(line[:, 0]), np.ascontiguousarray(line[:, 1])
    for start in range(0, len(points), _POINTS_PER_BLOCK):
        block = points[start:start + _POINTS_PER_BLOCK]
        sq = block[:, 0:1] - vx
        sq *= sq
        dy = block[:, 1:2] - vy
        dy *= dy
        sq += dy
        yield start, block, sq


def distance_to_polyline(points: FloatArray, line: FloatArray) -> FloatArray:
    """Exact distance from each point (M, 2) to the polyline (N, 2). Only the segments that can
    be nearest are measured: the nearest vertex bounds the distance from above, and a segment
    is no nearer than its start vertex's distance minus its length."""
    a = line[:-1]
    ab = line[1:] - a
    length_sq = (ab**2).sum(axis=1)
    length = np.sqrt(length_sq)
    out = np.empty(len(points))
    for start, block, sq in _vertex_distances_sq(points, line):
        reach = np.sqrt(sq.min(axis=1))[:, None] + length[None]
        rows, cols = np.nonzero(sq[:, :-1] <= reach * reach * (1.0 + 1e-9) + 1e-12)
        p = block[rows]
        t = np.clip(((p - a[cols]) * ab[cols]).sum(axis=1)
                    / np.maximum(length_sq[cols], 1e-18), 0.0, 1.0)
        d = np.sqrt(((p - (a[cols] + t[:, None] * ab[cols])) ** 2).sum(axis=1))
        nearest = np.full(len(block), np.inf)
        np.minimum.at(nearest, rows, d)
        out[start:start + len(block)] = nearest
    return out


def tape_intervals(spec: ScenarioSpec, side: str, length_m: float) -> list[tuple[float, float]]:
    """Arc-length intervals where the `side` tape is present (`centre`: a single-line track's
    line, which ends where the first of `lane.ends` says and takes the gaps and dashes of
    `both`)."""
    if side == "centre":
        ends = [e for e in (spec.lane.ends.left_m, spec.lane.ends.right_m) if e is not None]
        end = min(ends) if ends else None
    else:
        end = getattr(spec.lane.ends, f"{side}_m")
    stop = length_m if end is None else min(end, length_m)
    intervals = [(0.0, stop)]
    for gap in spec.lane.gaps:
        if _applies(gap.tape, side):
            intervals = _subtract(intervals, (gap.from_m, gap.to_m))
    dashes = spec.lane.dashes
    if dashes is not None and _applies(dashes.tape, side):
        period = dashes.on_m + dashes.off_m
        dash_end = stop if dashes.to_m is None else min(dashes.to_m, stop)
        s = dashes.from_m + dashes.on_m
        while s < dash_end:
            intervals = _subtract(intervals, (s, min(s + dashes.off_m, dash_end)))
            s += period
    return [(a, b) for a, b in intervals if b - a > 1e-6]


def build_world(spec: ScenarioSpec, margin_m: float = 2.5) -> World:
    """The world a scenario describes. `margin_m`: rendered floor beyond the lane on every side."""
    lane = spec.lane
    start = Pose2D(lane.start.x_m, lane.start.y_m, math.radians(lane.start.heading_deg))
    half = lane.width_m / 2.0
    widest = max(spec.tape.side(side).width_m for side in ("left", "right"))
    for i, seg in enumerate(lane.segments):
        if seg.arc_radius_m is not None and seg.arc_radius_m <= half + widest:
            raise ScenarioError(
                f"{spec.name}: lane.segments.{i}.arc_radius_m = {seg.arc_radius_m}: expected more "
                f"than half the lane width plus the tape width ({half + widest:.3f} m)"
            )
    centre, marks = build_centreline(start, lane.segments)
    length = centre.length_m
    for key in ("left_m", "right_m"):
        end = getattr(lane.ends, key)
        if end is not None and end > length + 1e-9:
            raise ScenarioError(
                f"{spec.name}: lane.ends.{key} = {end}: expected at most the lane length "
                f"({length:.3f} m)"
            )
    sides = (("left", half), ("right", -half)) if lane.lines == "edges" else (("centre", 0.0),)
    tapes = []
    for index, (side, offset) in enumerate(sides):
        look = spec.tape.side(side)
        intervals = tape_intervals(spec, side, length)
        pieces = tuple(centre.offset(a, b, offset) for a, b in intervals)
        # Each end cut at up to end_angle_deg, the same for every run of the scenario.
        cut_rng = np.random.default_rng([index, 0xC07])
        limit = math.radians(look.end_angle_deg)
        cuts = tuple((float(cut_rng.uniform(-limit, limit)), float(cut_rng.uniform(-limit, limit)))
                     for _ in pieces)
        tapes.append(Tape(side, offset, look.width_m, color_bgr(look.color), tuple(intervals),
                          pieces, look, cuts))
    ends = [e for e in (lane.ends.left_m, lane.ends.right_m) if e is not None]
    markings_end = min(ends) if ends else None
    robot_heading = start.theta_rad + math.radians(spec.robot.heading_deg)
    robot = Pose2D(
        start.x_m - spec.robot.offset_m * math.sin(start.theta_rad),
        start.y_m + spec.robot.offset_m * math.cos(start.theta_rad),
        robot_heading,
    )
    pts = centre.points
    bounds = (
        float(pts[:, 0].min() - half - margin_m),
        float(pts[:, 1].min() - half - margin_m),
        float(pts[:, 0].max() + half + margin_m),
        float(pts[:, 1].max() + half + margin_m),
    )
    area = (bounds[2] - bounds[0]) * (bounds[3] - bounds[1])
    if area > MAX_FLOOR_AREA_M2:
        raise ScenarioError(
            f"{spec.name}: the lane and its {margin_m:g} m margins cover "
            f"{bounds[2] - bounds[0]:.1f} x {bounds[3] - bounds[1]:.1f} m = {area:.0f} m^2 of "
            f"floor, expected at most {MAX_FLOOR_AREA_M2:g} m^2 (a more compact lane, or a "
            "smaller simulation.world_margin_m)"
        )
    samples = [t.surface_samples() for t in tapes]
    return World(
        name=spec.name,
        floor=spec.floor,
        lighting=spec.lighting,
        centreline=centre,
        lane_width_m=lane.width_m,
        tapes=tuple(tapes),
        marks=MappingProxyType(dict(marks)),
        markings_end_s=markings_end,
        start_pose=robot,
        bounds=bounds,
        tape_samples=np.vstack(samples) if samples else np.zeros((0, 2)),
    )
