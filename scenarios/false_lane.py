"""Ground truth for the lane the supervisor drove on: how far the edges perception reported lay
from the tapes really there, and how long the supervisor kept trusting a lane that was not the
lane (a floor pattern, a stray piece of tape or a shadow's edge taken for a tape).

Why: a run can end well by luck. In the twenty-fourth campaign run's r00322 (docs/campaigns.md)
the robot followed a "lane" of parquet slats at full confidence for 1.5 s while the real lane
bent away; the departure rule then halted it, but on a slat, not on the tape it was heading
for. Neither the outcome (safe halt) nor the closest approach says so; these numbers do.

Per step that judged a new frame while the supervisor was engaged and trusted that frame's lane
(`StepRecord.lane_trusted`):

- each reported edge's point in the middle of its near part (`LaneEdge.offset_m`, `heading_rad`,
  `near_m`: the line `offset_m` from the robot's centre at `heading_rad`, where it is `near_m`
  plus half of `perception.detector.EVIDENCE_MIN_M` ahead), moved to the world at the robot's
  true pose at the frame's time stamp (a frame whose stamp lies, frozen or from the future, is
  judged against the moment it claims to show, as the supervisor takes it);
- its error: the distance from that point to the nearest lane-edge tape, taken whole from its
  first piece to its last (a dashed line's gaps count as tape), less half the tape's width, 0
  on the tape; the frame's error is the larger of its two edges' (an edge without a floor
  position is not measured);
- the frame is on a false lane when its error exceeds `FALSE_LANE_TOLERANCE_M`.

Metrics: `max_edge_error_m` (largest frame error; None: no frame measured), `false_lane_frames`
(trusted frames on a false lane) and `false_lane_longest_s` (the longest stretch of them with
no trusted frame on the true lane between: last minus first frame time plus the median step
between records; 0.0 when none).

Pure: no clock, no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.detector import EVIDENCE_MIN_M
from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.scenarios.world import World, distance_to_polyline
from lanewarden.supervisor.state_machine import ENGAGED_STATES

FloatArray = NDArray[np.float64]

#: A reported edge farther than this from every tape (beyond the tape itself) is not on the lane.
#: The simulated camera is described exactly: on the library's scenarios a true edge lies within
#: 2.1 cm of its tape, 5.7 cm where the lecture's sharp corners curve the inner tape through 26
#: degrees along the 10 cm its near part is drawn straight over; the parquet slats taken for the
#: lane in r00322 and r00910 of seed 4 lay up to 28 and 37 cm off.
FALSE_LANE_TOLERANCE_M = 0.08
#: The supervisor's engaged states, by the names step records carry.
_ENGAGED = frozenset(state.value for state in ENGAGED_STATES)


class JudgedStep(Protocol):
    """What this needs of a step record (`supervisor.loop.StepRecord`)."""

    @property
    def state(self) -> str: ...

    @property
    def observation(self) -> LaneObservation | None: ...

    @property
    def lane_trusted(self) -> bool | None: ...


def edge_point_robot(edge: LaneEdge) -> tuple[float, float] | None:
    """The middle of the edge's near part (half `EVIDENCE_MIN_M` past where it begins), robot
    frame (x ahead, y left), or None unmeasured. The middle, not the start: in the lecture's
    sharp corners (a 0.22 m inner radius) the straight near part lies 5 cm off the curving tape
    at its ends, under a centimetre at its middle."""
    if edge.offset_m is None or edge.heading_rad is None or edge.near_m is None:
        return None
    cos_h, sin_h = math.cos(edge.heading_rad), math.sin(edge.heading_rad)
    if abs(cos_h) < 1e-6:
        return None
    # the line: foot of the perpendicular offset_m * (-sin h, cos h), direction (cos h, sin h);
    # the point of it `ahead` metres ahead (x = ahead)
    ahead = edge.near_m + EVIDENCE_MIN_M / 2.0
    along = (ahead + edge.offset_m * sin_h) / cos_h
    return (-edge.offset_m * sin_h + along * cos_h, edge.offset_m * cos_h + along * sin_h)


def _tape_lines(world: World) -> list[tuple[FloatArray, float]]:
    """Each lane-edge tape's centre line from its first piece to its last (gaps bridged), and
    its half width."""
    lines = []
    centre = world.centreline
    for tape in world.tapes:
        if not tape.is_edge or not tape.intervals:
            continue
        start = min(a for a, _ in tape.intervals)
        end = max(b for _, b in tape.intervals)
        lines.append((centre.offset(start, end, tape.offset_m), tape.width_m / 2.0))
    return lines


def frame_edge_errors(world: World, times: FloatArray, poses: FloatArray,
                      records: Sequence[JudgedStep]) -> FloatArray:
    """Per record: the error of the lane it trusted while engaged (module docstring), NaN where
    not measured (not engaged, not trusted, no observation, no edge measured)."""
    errors = np.full(len(records), np.nan)
    lines = _tape_lines(world)
    times = np.asarray(times, dtype=np.float64)
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if not lines or not len(times):
        return errors
    for i, record in enumerate(records):
        obs = record.observation
        if obs is None or not record.lane_trusted or record.state not in _ENGAGED:
            continue
        points = [p for p in (edge_point_robot(e) for e in (obs.left, obs.right)
                              if e is not None) if p is not None]
        if not points:
            continue
        k = min(int(np.searchsorted(times, obs.time_s - 1e-9)), len(times) - 1)
        x, y, theta = poses[k]
        cos_t, sin_t = math.cos(theta), math.sin(theta)
        world_points = np.array([(x + px * cos_t - py * sin_t, y + px * sin_t + py * cos_t)
                                 for px, py in points])
        nearest = np.full(len(world_points), np.inf)
        for line, half_width in lines:
            nearest = np.minimum(nearest, distance_to_polyline(world_points, line) - half_width)
        errors[i] = float(np.maximum(nearest, 0.0).max())
    return errors


def false_lane_metrics(times: FloatArray, errors: FloatArray,
                       tolerance_m: float = FALSE_LANE_TOLERANCE_M) -> dict[str, object]:
    """`max_edge_error_m`, `false_lane_frames`, `false_lane_longest_s` (module docstring) from
    the per-record times and `frame_edge_errors`."""
    times = np.asarray(times, dtype=np.float64)
    measured = np.flatnonzero(np.isfinite(errors))
    if not len(measured):
        return {"max_edge_error_m": None, "false_lane_frames": 0, "false_lane_longest_s": 0.0}
    wrong = errors[measured] > tolerance_m
    period = float(np.median(np.diff(times))) if len(times) > 1 else 0.0
    longest = 0.0
    since: float | None = None  # time of the first false-lane frame of the current stretch
    for index, false in zip(measured.tolist(), wrong.tolist(), strict=True):
        if not false:
            since = None
            continue
        since = float(times[index]) if since is None else since
        longest = max(longest, float(times[index]) - since + period)
    return {"max_edge_error_m": round(float(errors[measured].max()), 4),
            "false_lane_frames": int(wrong.sum()),
            "false_lane_longest_s": round(longest, 4)}
