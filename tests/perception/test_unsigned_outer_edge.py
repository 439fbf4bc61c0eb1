"""A tape whose outer edge has no sign (issue 20's glossy tape, campaign run r00412): a ceiling
light mirrored over the near half of a glossy black tape leaves its outer edge's Hough line
without a polarity, and the tape's inner edge fails its lone-edge profile there (the tape looks
light beyond it). With no tape pair of opposite signs on that side, a signed INNER edge and an
unsigned outer edge whose width and band say tape are taken as the tape (`_side_choice`'s
fallback, `tape_candidates(unsigned_outer=True)`), but never an unsigned inner edge, and never
instead of a lone edge whose profile says tape (campaign run r00003: a band of terrazzo chips
0.41 m out would otherwise have been taken for the lane's left tape).

Lines and pictures as in test_tape_rules.py (the default camera at 640x480, metres)."""

from __future__ import annotations

import numpy as np

from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.edge_choice import SideChoice, choose_edges, tape_candidates
from lanewarden.perception.lines import LineRow
from tests.perception.test_tape_rules import (
    CONFIG,
    DARK,
    GROUND,
    along,
    floor_at_pixels,
    floor_picture,
)

SETUP = LaneDetector(CONFIG, ground=GROUND).setup_for(640, 480)
LIGHT = 250  # a ceiling light mirrored in glossy tape: lighter than the floor (180)
# The left tape, 0.276..0.324 m left of the robot's centre line, from 0.55 m to 1.2 m ahead.
TAPE_LO, TAPE_HI = 0.276, 0.324


def glossy_tape(light_to_m: float) -> np.ndarray:
    """The left tape (dark) on the floor, a light mirrored in it from the image's bottom to
    `light_to_m` ahead."""
    picture = floor_picture([(TAPE_LO, TAPE_HI, DARK)])
    floor = floor_at_pixels(GROUND)
    ahead, lateral = floor[:, :, 0], floor[:, :, 1]
    picture[(lateral > 0.5 * (TAPE_LO + TAPE_HI)) & (lateral < TAPE_HI + 0.03)
            & (ahead < light_to_m)] = LIGHT
    return picture


def left_choice(rows: list[LineRow], picture: np.ndarray) -> SideChoice | None:
    left, _ = choose_edges(rows, picture, SETUP, CONFIG)
    return left


# A plank seam 0.24 m left, inside the lane, longer than the tape's lines: where r00412's left
# side fell when its tape had no pair.
SEAM_Y = 0.24


def seam(line_id: int) -> LineRow:
    return along(SEAM_Y, -1.0, support=300.0, line_id=line_id)


def test_a_glossy_tape_whose_outer_edge_lost_its_sign_is_still_the_tape() -> None:
    """The light covers the outer half of the tape and the floor beyond it up to 0.85 m ahead:
    the outer edge has no sign, the inner edge's profile fails there (the tape is light on one
    half, dark on the other), the band beyond 0.85 m is tape. The tape is verified, its inner
    edge reported; without its unsigned outer edge the side falls to the seam."""
    picture = glossy_tape(0.85)
    inner, outer = along(TAPE_LO, 1.0, line_id=0), along(TAPE_HI, 0.0, line_id=1)
    choice = left_choice([inner, outer, seam(2)], picture)
    assert choice is not None
    assert (choice.chain[0], choice.partner, choice.verified, choice.tape_dark) == (0, 1, True,
                                                                                    True)
    assert choice.tape_width_m is not None and abs(choice.tape_width_m - 0.048) < 0.002
    alone = left_choice([inner, seam(1)], picture)
    assert alone is not None
    assert (alone.chain[0], alone.verified, alone.tape_score) == (1, False, 0.0)


def test_a_light_over_the_whole_tape_leaves_no_tape() -> None:
    """The light over the tape's whole near and far part (to 1.0 m, past the lines' end): the
    band is not tape anywhere, so the unsigned pair is not a tape either."""
    picture = glossy_tape(1.0)
    choice = left_choice([along(TAPE_LO, 1.0, line_id=0), along(TAPE_HI, 0.0, line_id=1),
                          seam(2)], picture)
    assert choice is not None
    assert (choice.chain[0], choice.verified) == (2, False)


def test_an_unsigned_inner_edge_does_not_make_a_tape() -> None:
    """A dark tape whose INNER edge has no sign and whose outer edge has: not taken (the inner
    edge's sign is what says which side of the reported edge is floor). The side keeps its best
    lone edge, the seam."""
    picture = floor_picture([(TAPE_LO, TAPE_HI, DARK)])
    choice = left_choice([along(TAPE_LO, 0.0, line_id=0), along(TAPE_HI, -1.0, line_id=1),
                          seam(2)], picture)
    assert choice is not None
    assert (choice.chain[0], choice.partner, choice.verified) == (2, None, False)


def test_a_lone_tape_edge_beats_an_unsigned_pair_farther_out() -> None:
    """Campaign run r00003 (terrazzo): the tape's inner edge alone (no outer edge found), its
    profile says tape; 0.41 m out a band of dark chips a tape's width wide, one edge signed, the
    other not. The lone tape edge is kept, not the chip band."""
    picture = floor_picture([(TAPE_LO, TAPE_HI, DARK), (0.41, 0.458, DARK)])
    rows = [along(TAPE_LO, 1.0, line_id=0), along(0.41, 1.0, line_id=1),
            along(0.458, 0.0, line_id=2)]
    choice = left_choice(rows, picture)
    assert choice is not None
    assert (choice.chain[0], choice.partner, choice.verified) == (0, None, False)
    assert choice.tape_score == 1.0
    # The chip band is a candidate tape with an unsigned outer edge (width and all): the lone
    # edge's profile is what keeps it out.
    band = tape_candidates(rows, "left", SETUP.view, CONFIG, SETUP.look_ahead_m,
                           unsigned_outer=True)
    assert [(t.inner.line_id, t.outer.line_id) for t in band] == [(1, 2)]
    assert band[0].band_is_tape(picture, CONFIG)
