"""The tape-vs-seam rules one by one, each with cases that fail if the rule is replaced by a
constant: the width on the floor (`tape_width_score`, `measure_pair`), the band between two edges
(`band_is_tape`), the lone edge's profile and the image border (`tape_profile_fraction`, the
`verified_tape` gate), the choice of tapes (closeness to the tape's width, the lane's width, the
same kind of tape on both sides), and the start-up refusal of a camera that cannot tell a tape
from a seam at the look-ahead.

Lines and pictures are made on the floor and projected through the default camera's ground model
(`default_ground_model`, 640x480: 0.40 m high, 35 deg down, 70 deg lens, 0.15 m ahead of the
robot's centre), so each case states its geometry in metres.
"""

from __future__ import annotations

import dataclasses
import math
from functools import cache

import cv2
import numpy as np
import pytest

from lanewarden.perception.confidence import EdgeEvidence, combine, lane_components
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.edge_choice import (
    TapeCandidate,
    follow_edge,
    measure_pair,
    pick_tapes,
    verified_tapes,
)
from lanewarden.perception.errors import PerceptionConfigError
from lanewarden.perception.floor_config import TapeConfig
from lanewarden.perception.floor_view import FloorView
from lanewarden.perception.ground import CameraPose, GroundModel, default_ground_model
from lanewarden.perception.lines import LineRow
from lanewarden.perception.tape_rules import band_is_tape, tape_profile_fraction, tape_width_score

CONFIG = PerceptionConfig()
TAPE = CONFIG.tape  # 48 mm, seams up to 24 mm
GROUND = default_ground_model((640, 480))
VIEW = FloorView(GROUND)
FLOOR, DARK = 180, 45


def floor_line(a: tuple[float, float], b: tuple[float, float], polarity: float,
               support: float = 150.0, line_id: int = 0) -> LineRow:
    """The candidate line the detector would build for the floor line from a to b."""
    (ua, va), (ub, vb) = VIEW.to_image(*a), VIEW.to_image(*b)
    if va < vb:  # near end (larger image row) first
        (ua, va, a), (ub, vb, b) = (ub, vb, b), (ua, va, a)
    n = math.hypot(ub - ua, vb - va)
    ux, uy = (ub - ua) / n, (vb - va) / n
    cx, cy = 0.5 * (ua + ub), 0.5 * (va + vb)
    return LineRow(
        line_id=line_id, angle_deg=math.degrees(math.atan2(va - vb, ub - ua)), cx=cx, cy=cy,
        ux=ux, uy=uy, near_x=ua, near_y=va, far_x=ub, far_y=vb, support_px=support,
        polarity=polarity, x_bottom=cx + (480.0 - cy) * ux / uy,
        near_fx=a[0], near_fy=a[1], far_fx=b[0], far_fy=b[1],
    )


def along(y: float, polarity: float, x0: float = 0.55, x1: float = 1.2, **kw: float) -> LineRow:
    """A line running straight ahead at lateral position y (metres, left +)."""
    return floor_line((x0, y), (x1, y), polarity, **kw)  # type: ignore[arg-type]


@cache
def floor_at_pixels(ground: GroundModel) -> np.ndarray:
    """(H, W, 2): the floor point (robot x ahead, y left, metres) seen at every pixel (NaN
    above the horizon)."""
    width, height = ground.image_size
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    pixels = np.column_stack([u.ravel(), v.ravel()])
    return ground.image_to_floor(pixels).reshape(height, width, 2)


def _lateral_m(ground: GroundModel) -> np.ndarray:
    """The floor's lateral position (robot y, metres) seen at every pixel (NaN above the
    horizon)."""
    return floor_at_pixels(ground)[:, :, 1]


def floor_picture(bands: list[tuple[float, float, int]]) -> np.ndarray:
    """Gray (480, 640) picture of a floor of level FLOOR with bands running straight ahead
    between lateral positions (lo, hi) metres, of the given levels, lightly blurred."""
    y = _lateral_m(GROUND)
    image = np.full((480, 640), FLOOR, np.uint8)
    for lo, hi, level in bands:
        image[(y >= lo) & (y < hi)] = level
    return np.asarray(cv2.GaussianBlur(image, (5, 5), 0), dtype=np.uint8)


# ---- 1. the width on the floor ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("width_m", "m_per_px", "tape", "expected"),
    [
        # 2 mm per pixel: a seam measures at most 24 + 2 = 26 mm, a tape 40.8 - 2 = 38.8 mm on.
        (0.048, 0.002, TAPE, 1.0),  # the tape
        (0.024, 0.002, TAPE, 0.0),  # the widest seam
        (0.004, 0.002, TAPE, 0.0),  # tile grout
        (0.0324, 0.002, TAPE, 0.5),  # halfway between the two hypotheses
        (0.0572, 0.002, TAPE, 1.0),  # the widest tape, 55.2 + 2 mm
        (0.0858, 0.002, TAPE, 0.0),  # 1.5x that: a floor strip, not tape
        # 6 mm per pixel: a seam may measure 36 mm, a tape 34.8 mm: no tape can be told apart
        (0.048, 0.006, TAPE, 0.0),
        # thin seams (4 mm) but coarse pixels (4 mm): two edges less than min_gap_px (5) apart,
        # 20 mm + 4 mm error, may be one thin line
        (0.022, 0.004, TapeConfig(max_seam_width_m=0.004), 0.0),
        (0.048, 0.004, TapeConfig(max_seam_width_m=0.004), 1.0),
        # a 19 mm tape (seams up to 9.5 mm) at 1.5 mm per pixel
        (0.019, 0.0015, TapeConfig(width_m=0.019), 1.0),
        (0.0095, 0.0015, TapeConfig(width_m=0.019), 0.0),
        (math.nan, 0.002, TAPE, 0.0),
    ],
)
def test_width_score_tells_tape_from_seam_in_metres(
    width_m: float, m_per_px: float, tape: TapeConfig, expected: float
) -> None:
    assert tape_width_score(width_m, m_per_px, tape) == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize(
    ("inner_y", "outer_y", "at_m", "width_m", "score"),
    [
        (0.276, 0.324, (0.55, 1.2), 0.048, 1.0),  # a 48 mm tape, 0.3 m left of the centre
        (-0.276, -0.324, (0.55, 1.2), 0.048, 1.0),  # the right one
        (0.300, 0.318, (0.55, 1.2), 0.018, 0.0),  # an 18 mm seam
        (0.276, 0.300, (0.55, 1.2), 0.024, 0.0),  # a 24 mm seam: the widest allowed
        # the same tape seen only 2.6-3.0 m ahead (about 8 mm per pixel there): unresolvable
        (0.276, 0.324, (2.6, 3.0), 0.048, 0.0),
    ],
)
def test_a_pair_is_measured_on_the_floor(
    inner_y: float, outer_y: float, at_m: tuple[float, float], width_m: float, score: float
) -> None:
    side = "left" if inner_y > 0 else "right"
    pol = 1.0 if side == "left" else -1.0  # dark tape: the inner edge goes dark -> light inwards
    inner = along(inner_y, pol, *at_m, line_id=0)
    outer = along(outer_y, -pol, *at_m, line_id=1)
    measured = measure_pair(outer, inner, side, VIEW, CONFIG)
    assert measured is not None
    got_inner, got_outer, got_score, got_width, _ = measured
    assert (got_inner.line_id, got_outer.line_id) == (0, 1)
    assert got_width == pytest.approx(width_m, abs=5e-4)
    assert got_score == pytest.approx(score, abs=1e-9)


# ---- 2. the band between the edges -----------------------------------------------------------


@pytest.mark.parametrize(
    ("bands", "lines", "expected"),
    [
        # a dark tape, 0.276..0.324 m left, and its two edges
        ([(0.276, 0.324, DARK)], (0.276, 0.324), True),
        # a light tape on the same floor
        ([(0.276, 0.324, 250)], (0.276, 0.324), True),
        # a 12 mm seam runs 14 mm beside the tape: the floor beyond the seam still counts
        ([(0.250, 0.262, 90), (0.276, 0.324, DARK)], (0.276, 0.324), True),
        # the floor strip between a 4 mm seam (0.220..0.224) and the tape: tape on one side,
        # floor on the other
        ([(0.220, 0.224, 90), (0.276, 0.324, DARK)], (0.224, 0.276), False),
        # the floor strip beside the tape, nothing on its other side
        ([(0.276, 0.324, DARK)], (0.224, 0.276), False),
        # a band with the tape's edge inside it (not uniform)
        ([(0.276, 0.324, DARK)], (0.250, 0.300), False),
        # too little contrast (5 grey levels, min_contrast_levels 8)
        ([(0.276, 0.324, FLOOR - 5)], (0.276, 0.324), False),
    ],
)
def test_band_between_the_edges_must_look_like_tape(
    bands: list[tuple[float, float, int]], lines: tuple[float, float], expected: bool
) -> None:
    picture = floor_picture(bands)
    a, b = along(lines[0], 1.0), along(lines[1], -1.0)
    y_lo, y_hi = max(a.far_y, b.far_y), min(a.near_y, b.near_y)
    assert band_is_tape(picture, a, b, y_lo, y_hi, TAPE) is expected


def test_the_detector_band_checks_the_tape_it_chooses() -> None:
    """A tape-wide band (0.276..0.324 m left) whose halves differ (45 and 130 grey levels), and a
    real tape on the right: the left pair has a tape's width but not a tape's band, so it is not
    a verified tape; the right one is."""
    picture = floor_picture([(0.276, 0.300, DARK), (0.300, 0.324, 130), (-0.324, -0.276, DARK)])
    _, debug = LaneDetector(CONFIG).detect_debug(picture, 0, 0.0)
    assert debug.right is not None and debug.right.verified
    assert debug.left is not None and not debug.left.verified and debug.left.partner is None


# ---- 3. a lone edge, and the image border ----------------------------------------------------


def test_lone_edge_profile_sees_a_tape_beyond_it_but_not_a_seam() -> None:
    edge = along(0.276, 1.0)
    tape = tape_profile_fraction(floor_picture([(0.276, 0.324, DARK)]), [edge], (0,), "left",
                                 VIEW, TAPE)
    seam = tape_profile_fraction(floor_picture([(0.276, 0.282, DARK)]), [edge], (0,), "left",
                                 VIEW, TAPE)
    wide_seam = tape_profile_fraction(floor_picture([(0.276, 0.300, DARK)]), [edge], (0,),
                                      "left", VIEW, TAPE)
    assert tape == 1.0
    assert seam == 0.0 and wide_seam == 0.0


def test_lone_edge_at_the_image_border_cannot_be_verified() -> None:
    """The floor 1.75 tape widths beyond an edge along the image's left border is outside the
    image: nothing to check it against (None: unverifiable)."""
    # The floor line seen along column 12 from row 470 up to row 250.
    a = VIEW.to_floor(12.0, 470.0)
    b = VIEW.to_floor(12.0, 250.0)
    edge = floor_line(a, b, 1.0)
    picture = floor_picture([(a[1], a[1] + 0.048, DARK)])
    assert tape_profile_fraction(picture, [edge], (0,), "left", VIEW, TAPE) is None


def _edge(verified: bool, score: float, y: float, *, polarity: float | None = None,
          dark: bool = True, lines: tuple[int, ...] = ()) -> EdgeEvidence:
    """A reported edge on the floor at lateral `y`; by default the inner edge of a dark tape
    (the floor, lighter, on its inner side: +1 on the left, -1 on the right)."""
    if polarity is None:
        polarity = 1.0 if y > 0 else -1.0
    ids = lines or ((1,) if y > 0 else (2,))
    return EdgeEvidence(point=(0.6, y), direction=(1.0, 0.0), support_px=200.0,
                        tape_score=score, verified=verified, dark=dark if verified else None,
                        polarity=polarity, line_ids=frozenset(ids))


def test_a_confident_lane_needs_a_verified_tape() -> None:
    """Two edges nobody could check (both at the border, unverifiable_score 0.6 each) once
    made a confident lane (0.6 > the old min_confidence 0.5) out of tile seams. Now confidence
    is 0 without at least one verified tape; with one, the other side may be unverifiable."""
    unverified = lane_components(height_px=480, left=_edge(False, 0.6, 0.276),
                                 right=_edge(False, 0.6, -0.276), config=CONFIG)
    assert unverified["verified_tape"] == 0.0
    assert unverified["lane_width"] == 1.0 and unverified["parallel"] == 1.0
    assert combine({**unverified, "consistency": 1.0}, CONFIG) == 0.0
    one = lane_components(height_px=480, left=_edge(True, 1.0, 0.276),
                          right=_edge(False, 0.6, -0.276), config=CONFIG)
    assert one["verified_tape"] == 1.0
    assert combine({**one, "consistency": 1.0}, CONFIG) == pytest.approx(0.6**0.5)


@pytest.mark.parametrize(
    ("left", "right", "why"),
    [
        # The lane between two dark tapes: floor (lighter) inside both edges.
        (_edge(True, 1.0, 0.276), _edge(False, 0.6, -0.276), None),
        (_edge(True, 1.0, 0.276, polarity=-1.0, dark=False),
         _edge(False, 0.6, -0.276, polarity=1.0), None),  # two light tapes: floor darker inside
        # One dark tape's two edges: darker inside (left edge -1, right edge +1).
        (_edge(True, 1.0, 0.024, polarity=-1.0), _edge(False, 0.6, -0.024, polarity=1.0),
         "the inside is tape"),
        # The right edge is a dark tape's outer edge (floor beyond it, tape inside).
        (_edge(True, 1.0, 0.276), _edge(False, 0.6, -0.276, polarity=1.0), "right edge reversed"),
        # A light floor strip verified as a light tape on the left, a dark tape on the right.
        (_edge(True, 1.0, 0.276, polarity=-1.0, dark=False), _edge(True, 1.0, -0.276),
         "two kinds of tape"),
        # Both reported edges lines of one tape (the chain of one is the partner of the other).
        (_edge(True, 1.0, 0.276, lines=(1, 2)), _edge(False, 0.6, -0.276, lines=(2,)),
         "one tape"),
        # An edge whose brightness says nothing.
        (_edge(True, 1.0, 0.276), _edge(False, 0.6, -0.276, polarity=0.0), "polarity 0"),
    ],
)
def test_a_lane_encloses_floor_not_a_tape(left: EdgeEvidence, right: EdgeEvidence,
                                         why: str | None) -> None:
    """`floor_between` is a full gate: the two reported edges must put the floor between them
    (each edge's polarity, for the verified tapes' kind), and be lines of two tapes."""
    comps = lane_components(height_px=480, left=left, right=right, config=CONFIG)
    assert comps["floor_between"] == (1.0 if why is None else 0.0)
    confidence = combine({**comps, "consistency": 1.0}, CONFIG)
    if why is None:
        assert confidence > 0.7
    else:
        assert confidence == 0.0


@pytest.mark.parametrize(("heading_deg", "lane"), [
    (0.0, True), (25.0, True), (-44.0, True), (46.0, False), (-48.6, False), (60.0, False)])
def test_a_lane_seen_across_the_view_is_no_lane(heading_deg: float, lane: bool) -> None:
    """`heading` is a full gate: a lane running more than `lane.max_heading_deg` (45) from the
    robot's heading is not one to steer along. The real JetBot frame this comes from: a tape
    in front at 48.6 degrees, paired with a sliver of the other line at the border, "straight"
    at 0.39. The simulator's courses stay within 25 degrees."""
    turn = math.radians(heading_deg)
    c, s_ = math.cos(turn), math.sin(turn)

    def turned(edge: EdgeEvidence) -> EdgeEvidence:
        (x, y), (dx, dy) = edge.point, edge.direction
        return dataclasses.replace(edge, point=(c * x - s_ * y, s_ * x + c * y),
                                   direction=(c * dx - s_ * dy, s_ * dx + c * dy))

    comps = lane_components(height_px=480, left=turned(_edge(True, 1.0, 0.276)),
                            right=turned(_edge(True, 1.0, -0.276)), config=CONFIG)
    assert comps["lane_width"] == 1.0 and comps["parallel"] == 1.0
    assert comps["floor_between"] == 1.0
    assert comps["heading"] == (1.0 if lane else 0.0)
    assert combine({**comps, "consistency": 1.0}, CONFIG) == (1.0 if lane else 0.0)


def test_border_edges_alone_give_no_confidence_in_a_frame() -> None:
    """A steep camera (0.30 m high, 80 deg down) sees a patch of floor about 0.4 m wide: a lane
    whose inner edges run 1 cm inside the image's side borders, the tapes beyond them out of
    view. Both edges are strong and in lane position, neither tape can be checked
    (unverifiable_score 0.6 each): this made a 'confident' lane of 0.6 before; now 0."""
    ground = GroundModel.from_fov(70.0, (640, 480),
                                  CameraPose(height_m=0.30, pitch_deg=80.0, forward_m=0.15))
    y = _lateral_m(ground)
    image = np.where(np.abs(y) < 0.19, FLOOR, DARK).astype(np.uint8)
    config = PerceptionConfig.model_validate(
        {"lane": {"width_m": 0.428}, "edges": {"look_ahead_m": 0.2}})
    obs = LaneDetector(config, ground=ground).detect(cv2.GaussianBlur(image, (5, 5), 0), 0, 0.0)
    assert obs.left is not None and obs.right is not None
    assert obs.left.offset_m == pytest.approx(0.19, abs=0.005)
    assert obs.components["tape_pair_left"] == 0.6
    assert obs.components["tape_pair_right"] == 0.6
    assert obs.components["lane_width"] == 1.0 and obs.components["parallel"] == 1.0
    assert obs.components["verified_tape"] == 0.0
    assert obs.confidence == 0.0


# ---- 4. which tapes --------------------------------------------------------------------------


def test_tapes_are_ranked_by_closeness_to_the_tape_width_not_by_length() -> None:
    """Two dark bands on the left: the 48 mm tape (short Hough support) and a 35 mm band
    (four times the support). Both pass as tape (35 mm scores 0.69); the 48 mm one comes
    first."""
    picture = floor_picture([(0.276, 0.324, DARK), (0.400, 0.435, DARK)])
    lines = [
        along(0.276, 1.0, support=60.0, line_id=0), along(0.324, -1.0, support=60.0, line_id=1),
        along(0.400, 1.0, support=240.0, line_id=2), along(0.435, -1.0, support=240.0, line_id=3),
    ]
    found = verified_tapes(lines, picture, "left", VIEW, CONFIG, 0.87)
    assert [(t.inner.line_id, t.outer.line_id) for t in found] == [(0, 1), (2, 3)]
    assert found[0].score == 1.0 and found[1].score == pytest.approx(0.69, abs=0.02)


@pytest.mark.parametrize(
    ("band", "at_m", "found"),
    [
        ((0.276, 0.324), (0.55, 0.85), True),  # 48 mm, measured 0.55 m ahead
        # 30 mm: nearer the widest seam (24 mm + error) than the tape: width score 0.35, no tape
        ((0.276, 0.306), (0.55, 0.85), False),
        # the 48 mm tape seen only 0.95-1.5 m ahead, beyond the look-ahead (0.87 m): the start-up
        # check only guarantees tape and seam apart up to there
        ((0.276, 0.324), (0.95, 1.5), False),
    ],
)
def test_a_tape_is_verified_only_when_measured_clearly_and_near_enough(
    band: tuple[float, float], at_m: tuple[float, float], found: bool
) -> None:
    picture = floor_picture([(band[0], band[1], DARK)])
    lines = [along(band[0], 1.0, *at_m, line_id=0), along(band[1], -1.0, *at_m, line_id=1)]
    assert bool(verified_tapes(lines, picture, "left", VIEW, CONFIG, 0.87)) is found


def test_an_edge_continues_forwards_not_sideways_onto_a_seam() -> None:
    """Hough pieces of one edge are chained across gaps; a piece of a seam 3 cm beside the edge,
    whose end lies within the gap (29 px from the edge's near end), is not the same edge."""
    edge = floor_line((0.60, 0.30), (1.60, 0.32), 1.0, line_id=0)
    nearer_piece = floor_line((0.40, 0.296), (0.52, 0.298), 1.0, line_id=1)
    seam_beside = floor_line((0.45, 0.27), (0.55, 0.27), 1.0, line_id=2)
    assert follow_edge([edge, nearer_piece], 0, (640, 480), CONFIG) == (1, 0)
    assert follow_edge([edge, seam_beside], 0, (640, 480), CONFIG) == (0,)


def image_line(near: tuple[float, float], far: tuple[float, float], contrast: float,
               line_id: int) -> LineRow:
    """A candidate line of polarity +1 made in image pixels (nothing on the floor), with its
    brightness step across (`LineRow.contrast`)."""
    n = math.hypot(far[0] - near[0], far[1] - near[1])
    nan = math.nan
    return LineRow(
        line_id=line_id, angle_deg=math.degrees(math.atan2(near[1] - far[1], far[0] - near[0])),
        cx=0.5 * (near[0] + far[0]), cy=0.5 * (near[1] + far[1]),
        ux=(far[0] - near[0]) / n, uy=(far[1] - near[1]) / n, near_x=near[0], near_y=near[1],
        far_x=far[0], far_y=far[1], support_px=n, polarity=1.0, x_bottom=nan,
        near_fx=nan, near_fy=nan, far_fx=nan, far_fy=nan, contrast=contrast)


def test_a_seam_crossing_a_bending_edge_does_not_continue_it() -> None:
    """Simulated parquet at 320x240 (campaign seed 0, r00562): a glossy tape bends across the
    image's left corner. A Hough piece of its edge ends at row 167, where a plank seam crossing
    the tape starts 3 px away and runs off at 30 degrees; the edge's next piece starts 8 px away
    and steps as strongly (106 grey levels against the piece's 100; the seam 30). The chain takes
    the edge's piece. With no such piece the seam still continues the chain (nothing better), and
    with nothing measured about contrast the nearest line does, as before."""
    edge = image_line((7.0, 239.0), (30.0, 167.0), 100.0, 0)
    seam = image_line((29.0, 170.0), (174.0, 39.0), 30.0, 1)
    next_piece = image_line((32.0, 159.0), (36.0, 130.0), 106.0, 2)
    assert follow_edge([edge, seam, next_piece], 0, (320, 240), CONFIG) == (0, 2)
    assert follow_edge([edge, seam], 0, (320, 240), CONFIG) == (0, 1)
    unmeasured = [line._replace(contrast=math.nan) for line in (edge, seam, next_piece)]
    assert follow_edge(unmeasured, 0, (320, 240), CONFIG) == (0, 1)


def test_measured_at_the_same_spot_the_width_closest_to_the_tape_wins() -> None:
    """Grout running along a tape's inner edge: the tape (48 mm) and the tape with the grout
    (54 mm, still within the tape's tolerance, score 1) are measured at the same spot; the
    tape's own width wins, on either side, with or without a tape on the other side."""
    with_grout, tape = _tape(0.270, 0.324), _tape(0.276, 0.324)
    assert with_grout.score == tape.score == 1.0
    assert pick_tapes([with_grout, tape], [], CONFIG)[0] is tape
    right, right_with_grout = _tape(-0.276, -0.324), _tape(-0.270, -0.324)
    assert pick_tapes([with_grout, tape], [right, right_with_grout], CONFIG) == (tape, right)


def test_among_equally_good_tapes_the_nearest_measurement_wins() -> None:
    """Two pieces of one bending tape, both 48 mm: the one measured 0.45 m ahead (where the
    edge's chain starts) before the one measured 0.9 m ahead."""
    far, near = _tape(0.276, 0.324, at_m=(0.9, 1.3)), _tape(0.276, 0.324, at_m=(0.45, 0.8))
    assert far.score == near.score == 1.0
    assert pick_tapes([far, near], [], CONFIG)[0] is near
    right = _tape(-0.276, -0.324)
    assert pick_tapes([far, near], [right], CONFIG)[0] is near


def _tape(inner_y: float, outer_y: float, dark: bool = True,
          at_m: tuple[float, float] = (0.55, 1.2)) -> TapeCandidate:
    side = "left" if inner_y > 0 else "right"
    measured = measure_pair(along(inner_y, 1.0, *at_m), along(outer_y, -1.0, *at_m), side, VIEW,
                            CONFIG)
    assert measured is not None
    inner, outer, score, width_m, at = measured
    return TapeCandidate(inner, outer, score, width_m, dark, at, tape_width_m=CONFIG.tape.width_m)


def test_tapes_are_paired_by_the_lane_width() -> None:
    """Two 48 mm tapes on the left, one where the lane's left tape belongs (inner edge 0.276 m)
    and one 12 cm further out; the right tape at -0.276 m: the lane is 0.60 m wide."""
    too_far, lane = _tape(0.396, 0.444), _tape(0.276, 0.324)
    right = _tape(-0.276, -0.324)
    left, chosen_right = pick_tapes([too_far, lane], [right], CONFIG)
    assert left is lane and chosen_right is right
    # With a 0.72 m lane the other one fits.
    wide = PerceptionConfig.model_validate({"lane": {"width_m": 0.72}})
    assert pick_tapes([too_far, lane], [right], wide)[0] is too_far


def _slanted_tape(near: tuple[float, float], angle_deg: float, length_m: float = 0.5,
                  width_m: float = 0.048) -> TapeCandidate:
    """A dark left tape whose inner edge starts at `near` on the floor and runs `angle_deg`
    towards the lane's centre (to the right), `width_m` wide across its own direction."""
    a = math.radians(angle_deg)
    d, n = (math.cos(a), -math.sin(a)), (math.sin(a), math.cos(a))  # along, and out (left)
    far = (near[0] + length_m * d[0], near[1] + length_m * d[1])
    out = (width_m * n[0], width_m * n[1])
    measured = measure_pair(floor_line(near, far, 1.0),
                            floor_line((near[0] + out[0], near[1] + out[1]),
                                       (far[0] + out[0], far[1] + out[1]), -1.0),
                            "left", VIEW, CONFIG)
    assert measured is not None
    inner, outer, score, width_m, at = measured
    return TapeCandidate(inner, outer, score, width_m, True, at, tape_width_m=CONFIG.tape.width_m)


def test_the_lanes_tapes_run_parallel() -> None:
    """Light tape on parquet (campaign runs r00377 and r00671 of seed 4, s-curve at 320x240):
    on the left a strip between slats verifies as a tape 25 degrees across the lane, and where
    it is measured, nearer than the lane's own left tape, it lies exactly the lane's width from
    the right tape. Two tapes of one lane run parallel: the lane's own left tape is taken (the
    strip gave every other frame a lane refused as not parallel, and the robot halted
    LANE_LOST on a good lane)."""
    lane, strip = _tape(0.276, 0.324), _slanted_tape((0.45, 0.276), 25.0)
    right = _tape(-0.276, -0.324)
    assert strip.score == lane.score == 1.0
    assert strip.at[0] < lane.at[0]  # measured nearer: the tie-break would take it
    # ...and lies the lane's free width (0.60 - 0.048 m) from the right tape's inner edge there,
    # well within the tolerance (0.09 m)
    assert strip.at[1] - right.at[1] == pytest.approx(0.552, abs=0.025)
    assert pick_tapes([strip, lane], [right], CONFIG) == (lane, right)
    # Within the parallel tolerance (12 degrees) a bending tape is still a lane's tape.
    bending = _slanted_tape((0.45, 0.276), 8.0)
    assert pick_tapes([bending, lane], [right], CONFIG) == (bending, right)


def test_both_tapes_are_the_same_kind() -> None:
    """A light 'tape' (a floor strip between two dark lines) 48 mm wide where the lane's tape
    belongs, and a dark band 34 mm wide 5 cm off (width score 0.63); the right tape is dark: the
    two dark tapes make the lane."""
    strip, dark = _tape(0.276, 0.324, dark=False), _tape(0.326, 0.360, dark=True)
    assert dark.score == pytest.approx(0.63, abs=0.03)
    right = _tape(-0.276, -0.324, dark=True)
    assert pick_tapes([strip, dark], [right], CONFIG)[0] is dark
    # Without a right tape there is nothing to compare kinds with: the best width wins.
    assert pick_tapes([strip, dark], [], CONFIG)[0] is strip



def test_the_tapes_taken_are_the_pair_that_ranked_best() -> None:
    """Parquet (campaign run r00000, which never engaged): light slats between dark joints
    measure as light tapes beside the dark lane tapes. The lane's two dark tapes rank first; the
    right slat fails its band check. The choice is the lane's tapes, not one of them paired with
    a slat of the other kind (the ranking's tie-break indices were once used unnegated, picking
    other tapes than the ranked pair: a dark tape with a light slat, floor_between 0)."""
    lane_left, slat_left = _tape(0.276, 0.324), _tape(0.336, 0.384, dark=False)
    stray = _tape(-0.100, -0.148, dark=False)
    lane_right, slat_right = _tape(-0.276, -0.324), _tape(-0.336, -0.384, dark=False)
    chosen = pick_tapes([lane_left, slat_left], [stray, lane_right, slat_right], CONFIG,
                        lambda tape: tape is not slat_right)
    assert chosen == (lane_left, lane_right)

# ---- 5. the camera must resolve them at the look-ahead ---------------------------------------


def test_the_default_camera_resolves_the_tape_at_the_look_ahead() -> None:
    setup = LaneDetector(CONFIG).setup_for(640, 480)
    hyp = setup.at_look_ahead
    assert hyp.m_per_px == pytest.approx(0.0021, abs=5e-5)
    assert (hyp.seam_max_m, hyp.tape_min_m) == pytest.approx((0.0261, 0.0387), abs=5e-4)
    assert setup.look_ahead_row == pytest.approx(192.4, abs=0.1)


@pytest.mark.parametrize(
    ("size", "overrides", "message", "suggested"),
    [
        # 8.5 mm per pixel at 0.87 m: refused, 0.47 m would do
        ((160, 120), {"edges": {"look_ahead_m": 0.87}}, "perception.edges.look_ahead_m = 0.87: "
         "at 160x120 one pixel covers 8.5 mm of floor across the tape there, too coarse to tell "
         "the 48 mm tape (tape.width_m) from seams up to 24 mm (with a pixel of measuring error "
         "either way a tape may measure as little as 32.3 mm there and a seam as much as 50.9 "
         "mm: to be told apart they must differ by more than that error, 8.5 mm); expected a "
         "look-ahead of 0.47 m or less for this camera (set "
         "perception.edges.look_ahead_m: 0.47 or auto in a --config file, or use a higher "
         "resolution)", 0.47),
        # the same with no look-ahead set (auto) at 160x120 works (0.47 m, see below); a 19 mm
        # tape with auto: nothing in view resolves it
        ((160, 120), {"tape": {"width_m": 0.019}},
         "perception.edges.look_ahead_m = auto: at 160x120 no distance in view (0.36 m on) "
         "tells the 19 mm tape (tape.width_m) from seams up to 9.5 mm (one pixel covers at least "
         "4.1 mm of floor across the tape); expected a higher resolution, a narrower lens, a "
         "lower camera, a wider tape or, if the lane is in fact narrower, its true width "
         "(perception.lane.width_m: the tapes nearer the middle of the view)", None),
        # a 19 mm tape at 160x120: nowhere in view
        ((160, 120), {"tape": {"width_m": 0.019}, "edges": {"look_ahead_m": 0.45}},
         "no distance in view (0.36 m on) resolves them: expected a higher resolution, a "
         "narrower lens, a lower camera, a wider tape or, if the lane is in fact narrower, its "
         "true width (perception.lane.width_m: the tapes nearer the middle of the view)", None),
        # closer than the image's bottom row (0.36 m ahead): the advice is what auto would pick
        ((640, 480), {"edges": {"look_ahead_m": 0.2}}, "perception.edges.look_ahead_m = 0.2: "
         "outside the camera's view at 640x480; expected a distance within the floor the "
         "camera sees, 0.36 m to 3.25 m ahead of the robot's centre; this camera tells tape "
         "from seam up to 0.87 m (set perception.edges.look_ahead_m: 0.87 or auto in a "
         "--config file)", 0.87),
        ((640, 480), {"roi": {"near_m": 5.0, "far_m": 6.0}, "edges": {"look_ahead_m": 5.5}},
         "perception.roi (near_m 5, far_m 6, lateral_m 0.65): this floor is not in the "
         "camera's view at 640x480", None),
    ],
)
def test_a_camera_that_cannot_tell_tape_from_seam_is_refused_at_start_up(
    size: tuple[int, int], overrides: dict[str, object], message: str, suggested: float | None
) -> None:
    config = PerceptionConfig.model_validate(overrides)
    with pytest.raises(PerceptionConfigError) as info:
        LaneDetector(config, ground=default_ground_model(size))
    assert message in str(info.value)
    assert "\n" not in str(info.value)
    # Exactly the advised value, as the user types it (a whole centimetre, no rounding error).
    assert info.value.suggested_look_ahead_m == suggested


def test_a_camera_looking_above_the_horizon_is_refused_saying_so() -> None:
    """A calibration edited to pitch the camera 60 degrees UP: no row sees the floor. The
    message had read "the floor the camera sees, nan m to the horizon ahead"."""
    from lanewarden.perception.ground import CameraPose, GroundModel

    up = GroundModel.from_fov(70.0, (640, 480), CameraPose(height_m=0.4, pitch_deg=-60.0))
    with pytest.raises(PerceptionConfigError) as info:
        LaneDetector(PerceptionConfig(), ground=up)
    assert str(info.value).endswith(
        "this floor is not in the camera's view at 640x480; expected a region overlapping the "
        "floor, but this camera sees none: even its bottom row looks at or above the horizon "
        "(check the calibration's ground_pitch_deg: positive looks down)")


def test_the_suggested_look_ahead_works() -> None:
    config = PerceptionConfig.model_validate({"edges": {"look_ahead_m": 0.47}})
    setup = LaneDetector(config, ground=default_ground_model((160, 120))).setup_for(160, 120)
    assert setup.at_look_ahead.resolvable
    # ... and is what auto chooses for this camera, saying so.
    auto = LaneDetector(PerceptionConfig(), ground=default_ground_model((160, 120)))
    assert auto.setup_for(160, 120).look_ahead_m == 0.47
    assert "160x120: look-ahead 0.47 m (auto: the farthest where this camera tells tape from " \
        "seam)" in auto.describe_ground()


@pytest.mark.parametrize("height_m", [0.20, 0.23, 0.26, 0.29, 0.32, 0.35, 0.38, 0.41, 0.44])
@pytest.mark.parametrize("tape_m", [0.019, 0.025, 0.048])
def test_an_advised_look_ahead_is_never_refused(height_m: float, tape_m: float) -> None:
    """Whatever a refusal advises is accepted as given: the advice is found by the very check
    that judges it, on whole centimetres (it used to be rounded up from 0.2799 to 0.28 and
    refused in turn)."""
    ground = GroundModel.from_fov(70.0, (320, 240), CameraPose(height_m=height_m, pitch_deg=30.0,
                                                               forward_m=0.1))
    too_far = PerceptionConfig.model_validate(
        {"tape": {"width_m": tape_m}, "edges": {"look_ahead_m": 1.6}, "roi": {"far_m": 1.6}})
    try:
        LaneDetector(too_far, ground=ground)
    except PerceptionConfigError as exc:
        advised = exc.suggested_look_ahead_m
        if advised is None:
            assert "no distance in view" in str(exc)
            return
        assert advised == round(advised, 2)
        config = PerceptionConfig.model_validate(
            {"tape": {"width_m": tape_m}, "edges": {"look_ahead_m": advised}})
        assert LaneDetector(config, ground=ground).setup_for(320, 240).look_ahead_m == advised


def test_a_floor_in_view_from_behind_the_robots_centre_is_not_a_negative_distance() -> None:
    """A low camera steeply down sees the floor from just behind the robot's centre: the
    refusal had read 'no distance in view (-0.01 m on)'."""
    from lanewarden.perception.size_setup import _from_text

    assert _from_text(0.36) == "0.36 m on"
    assert _from_text(-0.01) == _from_text(0.0) == "from the robot's centre on"
