"""Each condition of the band and lone-edge rules on its own (perception/tape_rules.py), with a
case that only that condition refuses: the mutation run (tests/mutation/mutants.toml) drops or
weakens each one and one of these must fail. One case is the other way round: a tape on a
floor shaded across it (`FLOOR_SHADE`) must pass; it fails with the factor at 1. The cases use
the floor pictures and lines of test_tape_rules.py (the default camera, geometry in metres)."""

from __future__ import annotations

from lanewarden.perception.lines import LineRow
from lanewarden.perception.tape_rules import band_is_tape, tape_profile_fraction
from tests.perception.test_tape_rules import (
    DARK,
    TAPE,
    VIEW,
    along,
    floor_line,
    floor_picture,
)

# A tape 0.276..0.324 m left of the robot, between its two edges.
TAPE_LO, TAPE_HI = 0.276, 0.324


def _band_rows(a: LineRow, b: LineRow) -> tuple[float, float]:
    return max(a.far_y, b.far_y), min(a.near_y, b.near_y)


def test_a_dark_band_between_a_floor_and_a_darker_floor_is_not_tape() -> None:
    """Darker than both sides by 35 grey levels (45 between 80 and 180), but the two sides
    differ by 100, more than twice that: two floors, not one floor shaded."""
    picture = floor_picture([(TAPE_LO, TAPE_HI, DARK), (0.15, TAPE_LO, 80)])
    a, b = along(TAPE_LO, 1.0), along(TAPE_HI, -1.0)
    assert band_is_tape(picture, a, b, *_band_rows(a, b), TAPE) is False
    even = floor_picture([(TAPE_LO, TAPE_HI, DARK), (0.15, TAPE_LO, 170)])  # one floor: tape
    assert band_is_tape(even, a, b, *_band_rows(a, b), TAPE) is True


def test_a_tape_on_a_shaded_floor_is_tape() -> None:
    """The JetBot set's left tape, in levels: a band of 45 between the lane's floor (120) and a
    floor darkened towards the picture's side (75). The sides differ by 45, more than the band's
    step (30) but less than twice it: one floor, shaded."""
    picture = floor_picture([(TAPE_LO, TAPE_HI, DARK), (0.15, TAPE_LO, 120), (TAPE_HI, 0.6, 75)])
    a, b = along(TAPE_LO, 1.0), along(TAPE_HI, -1.0)
    assert band_is_tape(picture, a, b, *_band_rows(a, b), TAPE) is True


def test_a_band_darker_than_one_side_only_is_not_tape() -> None:
    """The band (100) is 80 levels darker than the floor on one side, 4 on the other."""
    picture = floor_picture([(TAPE_LO, TAPE_HI, 100), (0.15, TAPE_LO, 104)])
    a, b = along(TAPE_LO, 1.0), along(TAPE_HI, -1.0)
    assert band_is_tape(picture, a, b, *_band_rows(a, b), TAPE) is False


def test_one_tape_like_sample_of_six_is_not_enough() -> None:
    """Only the rows around the first of the six samples show the tape (1/6 < 0.3)."""
    a, b = along(TAPE_LO, 1.0), along(TAPE_HI, -1.0)
    y_lo, y_hi = _band_rows(a, b)
    first = round(y_lo + (y_hi - y_lo) / (TAPE.polarity_samples + 1))
    picture = floor_picture([])
    picture[first - 3:first + 4] = floor_picture([(TAPE_LO, TAPE_HI, DARK)])[first - 3:first + 4]
    assert band_is_tape(picture, a, b, y_lo, y_hi, TAPE) is False
    rows = [round(y_lo + (y_hi - y_lo) * k / (TAPE.polarity_samples + 1)) for k in (1, 2)]
    for row in rows:  # two of six: enough
        picture[row - 3:row + 4] = floor_picture([(TAPE_LO, TAPE_HI, DARK)])[row - 3:row + 4]
    assert band_is_tape(picture, a, b, y_lo, y_hi, TAPE) is True


def test_a_lone_edge_beside_a_two_shade_strip_is_not_a_tape_edge() -> None:
    """Beyond the edge a strip of a tape's width whose halves differ (45, then 130): darker than
    the floor on both sides, but not uniform."""
    picture = floor_picture([(TAPE_LO, 0.300, DARK), (0.300, TAPE_HI, 130)])
    edge = along(TAPE_LO, 1.0)
    assert tape_profile_fraction(picture, [edge], (0,), "left", VIEW, TAPE) == 0.0
    assert tape_profile_fraction(floor_picture([(TAPE_LO, TAPE_HI, DARK)]), [edge], (0,), "left",
                                 VIEW, TAPE) == 1.0


def test_a_lone_edge_between_two_floors_is_not_a_tape_edge() -> None:
    """A tape-wide dark strip (45) beyond the edge, but the lane floor inside (180) and the
    floor beyond the strip (60) differ by 120, more than twice the strip's step (15)."""
    picture = floor_picture([(TAPE_LO, TAPE_HI, DARK), (TAPE_HI, 0.6, 60)])
    edge = along(TAPE_LO, 1.0)
    assert tape_profile_fraction(picture, [edge], (0,), "left", VIEW, TAPE) == 0.0


def test_a_lone_edge_mostly_beyond_the_image_border_is_unverifiable() -> None:
    """A floor line from column 150 at the bottom to the left border at row 250: most of the
    samples 1.75 tape widths beyond it are outside the image, a few are not."""
    edge = floor_line(VIEW.to_floor(150.0, 470.0), VIEW.to_floor(0.0, 250.0), 1.0)
    assert tape_profile_fraction(floor_picture([]), [edge], (0,), "left", VIEW, TAPE) is None
