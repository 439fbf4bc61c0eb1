"""What one lane observation is worth: well-formed? usable? confident? which events it raises.

Per new frame:
- malformed (non-finite numbers, confidence outside [0, 1], slope sum inconsistent with the edges,
  or not the frame it claims to be): `observation_problem` says why (MALFORMED_OBSERVATION);
- no edge: BOTH_EDGES_LOST; one edge: ONE_EDGE_LOST;
- confidence below `confidence_usable_min`: LANE_UNTRUSTED (no usable lane);
- confidence below `confidence_degrade_below` for `low_confidence_degrade_frames` frames in a row:
  LANE_LOW_CONFIDENCE;
- a usable frame (below) whose left edge passes the robot's centre less than
  `lane_departure_clearance_m` to its left (or passes right of it), or whose right edge less
  than that to its right (or left of it), shows the robot leaving the lane:
  `lane_departure_frames` such frames in a row give LANE_DEPARTURE (HALT). The clearance is the
  footprint's radius and a margin to stop in: the rule must fire before the tape is under the
  robot, not at contact (the twentieth campaign's r00665 and r00910 halted 2 mm and 66 mm over
  the tape). Usable frames, not only confident ones: a robot drifting onto a tape is exactly
  when the lane's shape stops matching (r00665 had no confident frame in its last 0.5 s); a
  lane placed from one tape counts with its placed edge. Where an edge passes the robot comes
  from its near part on the floor (`LaneEdge`: a line through its nearest point seen, `near_m`
  ahead, to a farther point `far_m` ahead), read back from that point to `near_m x far_m /
  (near_m + far_m)` ahead on the robot's axis (`read_back_m`) and, where the edge closes in on
  the robot, measured square to it (`edge_passing_m`: a round footprint touches a tape at that
  distance; measured along the robot's y axis, a tape crossing its path at 25 degrees reads
  10% too far; an edge opening away is read along the y axis, its line read back cutting the
  corner of a tight bend). For a straight tape parallel to the robot any point of the line
  gives the same distance (one at an angle does not: closing in, it reads nearer the farther
  ahead it is read, below);
  for a bend's arc the line is a chord, and there it passes the arc's point at the robot to
  second order. (Until 2026-12-06 it was read half-way, `near_m / 2`, which is right for a
  tangent at the nearest point, the limit of a short chord; for a chord from 0.36 to 0.66 m
  in a 2 m bend it put the inner tape 16 mm too near and the outer 12 mm too far. Read farther
  ahead, a straight tape the robot closes in on at 10 degrees reads up to 20 mm nearer than it
  did: the rule anticipates an approach a little more.) An error in
  the measured direction counts with at most half the distance, which is why only an edge seen
  beginning within `lane_departure_view_m` ahead counts.
  Frames that are not usable neither count nor reset the streak.
- A departure must be reachable: the robot moves its centre at most `limiter_max_linear_m_s`
  (the gate's cap), so an edge line's distance from its centre (`LaneEdge.offset_m`, which
  turning in place does not change) can change by at most that speed times the time since the
  last usable frame that counted, plus `lane_departure_jump_m` of measurement noise. A
  usable frame whose edges moved further (perception jumped to a light slat or a seam beside
  the tape, a whole lane 0.10-0.16 m to one side, and back: the 1000-run campaigns' parquet
  LANE_DEPARTURE false halts) neither counts nor resets the streak, and is not the reference
  for the next frame. The bound grows with the time since the reference, so a reading that
  stays where it jumped to counts after at most (jump - lane_departure_jump_m) /
  limiter_max_linear_m_s seconds: it delays a departure that follows a jump, never hides one.
  Likewise an edge's direction turns at most `limiter_max_angular_rad_s` times that time, plus
  `lane_departure_turn_deg`: a frame whose edge turned further is a wrong line (seed 1's r00089:
  the right edge flickering between -7 and +-40 degrees on terrazzo, read square to it 0.18 m
  from a robot 7 cm clear of the tape).
"Usable" (resets the lane-lost timer): at least one edge and confidence >= the usable minimum.
"Confident" (counts towards engage/recover): both edges seen and confidence >=
`confidence_confident_min`. A lane perception placed from one tape while the other was out of
sight (`perception.one_side`: both edges, `sides_seen` 1) raises ONE_EDGE_LOST like a lone edge
(DEGRADED and its budget), is usable when its confidence is, is never confident (so it breaks a
run of confident frames, to engage or to recover, like any unconfident frame), and feeds the
slope filter; but not when its edges lie where the robot could not have brought them from the
departure's reference (`reachable`, above): such a placed lane is a slat or a seam taken for
the one tape it was placed from, jumping between two places from frame to frame, and it is
not usable (LANE_UNTRUSTED: it feeds no filter and does not reset the lane-lost timer). A lane
placed from the right tape, for the few frames a dash is missing or a tape is out of view,
stays where the last one was. (The twenty-seventh campaign's seed 1 r00278: at the lecture's
corner A on parquet, the white line out of view, the lane placed from a slat read its right
edge 0.11 and 0.21 m right of the robot by turns, the tape 0.30-0.39 m, and steering on it for
2 s the robot crossed the yellow tape; it now halts 16 mm before it.) Two-sided lanes that
jump stay usable: they are judged by their shape, and the departure rule alone sets them aside.
Pure; the only memory is the low-confidence and departure streaks and the reference for the
departure's reachability (the last usable frame that counted: its time and edge lines).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.supervisor.center_offset import lateral_offset_at, preview_heading
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import FrameInfo
from lanewarden.supervisor.events import Event


@dataclass(frozen=True)
class LaneAssessment:
    events: frozenset[Event]
    usable: bool
    confident: bool
    slope_sum: float | None
    """The measurement for the slope filter (None: predict only)."""
    departure: str | None = None
    """Which edge shows the robot leaving the lane, and where (None: none does)."""


def _finite(*values: float | None) -> bool:
    """Every value is None or a finite number."""
    for value in values:
        if value is not None and not (isinstance(value, int | float) and math.isfinite(value)):
            return False
    return True


def _edge_problem(name: str, edge: LaneEdge | None) -> str | None:
    if edge is None:
        return None
    if not _finite(edge.x1, edge.y1, edge.x2, edge.y2, edge.slope):
        return f"{name} edge has a non-finite coordinate or slope"
    return None


def observation_problem(observation: LaneObservation, frame: FrameInfo | None) -> str | None:
    """Why `observation` cannot be trusted as data (None: it is well-formed)."""
    obs = observation
    if not (_finite(obs.confidence) and 0.0 <= obs.confidence <= 1.0):
        return f"confidence {obs.confidence!r} is not in [0, 1]"
    if not _finite(obs.slope_sum):
        return f"slope_sum {obs.slope_sum!r} is not finite"
    if not _finite(obs.lane_offset_m, obs.lane_heading_rad):
        return (f"lane_offset_m {obs.lane_offset_m!r} / lane_heading_rad "
                f"{obs.lane_heading_rad!r} is not finite")
    if obs.both_edges != (obs.slope_sum is not None):
        return "slope_sum must be given exactly when both edges are"
    for name, edge in (("left", obs.left), ("right", obs.right)):
        problem = _edge_problem(name, edge)
        if problem:
            return problem
    if frame is not None and obs.frame_index != frame.index:
        return f"observation is for frame {obs.frame_index}, expected frame {frame.index}"
    return None


def read_back_m(near_m: float, far_m: float | None) -> float:
    """How far ahead of the robot's centre the departure rule reads an edge line measured from
    `near_m` to `far_m` ahead: near x far / (near + far). There the chord of a bend's arc (the
    line through its points at near and far) passes the arc's point at the robot, offset as the
    robot's heading offsets a straight tape, to second order: the arc c + t x + k x^2 / 2 and its
    chord differ by k (x - near)(x - far) / 2, which is k near far / 2 at the robot and the rest
    of the arc's own bend at near x far / (near + far). A chord as short as its tangent (far
    near `near_m`), or no far end: half-way, `near_m / 2`."""
    if far_m is None or not far_m > near_m or not near_m > 0.0:
        return near_m / 2
    return near_m * far_m / (near_m + far_m)


def edge_passing_m(offset_m: float, heading_rad: float, near_m: float, side: float,
                   far_m: float | None = None) -> float:
    """How far from the robot's centre an edge passes, signed (left +), as the departure rule
    reads it: the edge line's lateral position at the point of the robot's axis `read_back_m`
    ahead (between half-way to where the edge is seen nearest and that point), and, where the
    edge closes in on the robot ahead (`side` +1 for the left edge, -1 for the right: heading
    towards the robot's centre line), its distance square to the edge from that point. A round
    footprint touches a tape at its distance square to it: along the robot's y axis, a tape
    crossing its path at 25 degrees reads 10% too far (the twentieth campaign's r00665 stopped
    over the tape). An edge opening away from the robot is read along the y axis: its line
    read back behind where it is seen cuts the corner of a bend (the inner tape of the
    lecture's tight corners, its chord at 40-48 degrees, read square 0.17 m from a robot 7 cm
    clear of it: seed 1's r00623, r00932). There a bend's curvature cancels to second order
    (`read_back_m`)."""
    lateral = lateral_offset_at(offset_m, heading_rad, read_back_m(near_m, far_m))
    if side * heading_rad < 0.0:
        lateral *= math.cos(preview_heading(heading_rad))
    return lateral


def departure_of(observation: LaneObservation, clearance_m: float,
                 view_m: float) -> str | None:
    """The edge of `observation` that passes the robot nearer its centre than `clearance_m`
    on its own side (or on the other side; `edge_passing_m`), as text; None when neither does.
    Only edges measured on the floor and seen beginning within `view_m` ahead count."""
    for name, edge, sign in (("left", observation.left, 1.0), ("right", observation.right, -1.0)):
        if (edge is None or edge.offset_m is None or edge.heading_rad is None
                or edge.near_m is None or not edge.near_m <= view_m):
            continue
        passing = edge_passing_m(edge.offset_m, edge.heading_rad, edge.near_m, sign, edge.far_m)
        if sign * passing < clearance_m:
            return (f"{name} edge {abs(passing):.3f} m {'left' if passing > 0 else 'right'} of "
                    f"the robot's centre, {clearance_m:g} m at the least")
    return None


EdgeLine = tuple[float | None, float | None]
"""One edge's line on the floor: its signed distance from the robot's centre and its direction
(`LaneEdge.offset_m`, `LaneEdge.heading_rad`; None: no edge, or not measured on the floor)."""


def _edge_lines(observation: LaneObservation) -> tuple[EdgeLine, EdgeLine]:
    """The left and right edge lines (`EdgeLine`)."""
    left, right = observation.left, observation.right
    return ((None, None) if left is None else (left.offset_m, left.heading_rad),
            (None, None) if right is None else (right.offset_m, right.heading_rad))


def reachable(lines: tuple[EdgeLine, EdgeLine],
              reference: tuple[float, tuple[EdgeLine, EdgeLine]] | None,
              time_s: float, cfg: SupervisorConfig) -> bool:
    """Could the robot's own motion have carried the edges from `reference` (its time and
    edge lines) to `lines` at `time_s`? Each side measured in both may have moved by at most
    `limiter_max_linear_m_s` times the time between them, plus `lane_departure_jump_m`, and
    turned by at most `limiter_max_angular_rad_s` times that time, plus
    `lane_departure_turn_deg`. No reference: yes."""
    if reference is None:
        return True
    then, before = reference
    elapsed = max(0.0, time_s - then)
    moved = cfg.limiter_max_linear_m_s * elapsed + cfg.lane_departure_jump_m
    turned = cfg.limiter_max_angular_rad_s * elapsed + math.radians(cfg.lane_departure_turn_deg)
    return all(_within(now[0], old[0], moved) and _within(now[1], old[1], turned)
               for now, old in zip(lines, before, strict=True))


def _within(now: float | None, old: float | None, allowed: float) -> bool:
    return now is None or old is None or abs(now - old) <= allowed


def frame_grade(obs: LaneObservation, cfg: SupervisorConfig) -> tuple[bool, bool]:
    """(usable, confident) of one well-formed observation (module docstring): what
    `LaneEvidence.assess` judges it, and what a run's summary counts (scenarios.before_halt)."""
    edges = (obs.left is not None) + (obs.right is not None)
    usable = edges > 0 and obs.confidence >= cfg.confidence_usable_min
    confident = obs.sides_seen == 2 and obs.confidence >= cfg.confidence_confident_min
    return usable, confident


class LaneEvidence:
    def __init__(self, config: SupervisorConfig) -> None:
        self._config = config
        self._low_confidence_frames = 0
        self._departure_frames = 0
        self._reference: tuple[float, tuple[EdgeLine, EdgeLine]] | None = None

    def assess(self, observation: LaneObservation) -> LaneAssessment:
        """Events and flags for one well-formed observation of a new frame."""
        cfg = self._config
        obs = observation
        events: set[Event] = set()
        edges = (obs.left is not None) + (obs.right is not None)
        seen = obs.sides_seen
        if edges == 0:
            events.add(Event.BOTH_EDGES_LOST)
        elif seen == 1:
            events.add(Event.ONE_EDGE_LOST)
        trusted = obs.confidence >= cfg.confidence_usable_min
        if edges > 0 and not trusted:
            events.add(Event.LANE_UNTRUSTED)
        if obs.confidence < cfg.confidence_degrade_below:
            self._low_confidence_frames += 1
        else:
            self._low_confidence_frames = 0
        if self._low_confidence_frames >= cfg.low_confidence_degrade_frames:
            events.add(Event.LANE_LOW_CONFIDENCE)
        usable, confident = frame_grade(obs, cfg)
        departure = None
        lines = _edge_lines(obs)
        jumped = usable and not reachable(lines, self._reference, obs.time_s, cfg)
        if jumped and seen == 1 and edges == 2:
            # a lane placed from one tape that jumped: placed from a slat (module docstring)
            usable = trusted = False
            events.add(Event.LANE_UNTRUSTED)
        # only usable frames count towards a departure, or reset it, and only those the
        # robot's own motion could have brought there (module docstring)
        if usable and not jumped:
            self._reference = (obs.time_s, lines)
            departure = departure_of(obs, cfg.lane_departure_clearance_m,
                                     cfg.lane_departure_view_m)
            self._departure_frames = self._departure_frames + 1 if departure else 0
        if self._departure_frames >= cfg.lane_departure_frames:
            events.add(Event.LANE_DEPARTURE)
        measurement = obs.slope_sum if (edges == 2 and trusted) else None
        return LaneAssessment(frozenset(events), usable, confident, measurement, departure)
