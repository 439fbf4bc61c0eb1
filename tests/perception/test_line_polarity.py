"""A line's polarity (perception/lines.py `_polarity`): the sign of the brightness step across it,
read at 18 points along it (3 x `tape.polarity_samples`). Drawn here: a light floor (180) with
a dark tape (60) right of a vertical line at x = 100, present only on some of the line's rows
(the rest is a gap in the tape: floor on both sides, no step)."""

from __future__ import annotations

import numpy as np
import pytest

from lanewarden.perception.floor_config import TapeConfig
from lanewarden.perception.lines import _polarity

TAPE = TapeConfig()
HEIGHT, WIDTH = 240, 320
TOP, BOTTOM = 40, 220  # the line runs from (100, 220) up to (100, 40)


def polarity_of(image: np.ndarray) -> float:
    one = np.array
    return float(_polarity(image, one([100.0]), one([float(BOTTOM)]), one([100.0]),
                           one([float(TOP)]), one([0.0]), one([-1.0]), TAPE)[0][0])


def tape_on(share: float) -> np.ndarray:
    """The tape covers the nearest `share` of the line (from its bottom end), a gap the rest."""
    image = np.full((HEIGHT, WIDTH), 180, np.uint8)
    first_row = round(BOTTOM - share * (BOTTOM - TOP))
    image[first_row:BOTTOM + 1, 100:130] = 60
    return image


@pytest.mark.parametrize(("share", "expected"), [
    (1.0, -1.0),   # light to dark going right
    (0.6, -1.0),   # the median of the 18 steps says so
    (0.4, -1.0),   # a gap over more than half the line: the median says 0, the vote -1
    (0.3, -1.0),   # 5 or 6 of 18 points with a clear step, none the other way
    (0.15, 0.0),   # under a quarter of the points: no polarity
    (0.0, 0.0),    # no tape at all
])
def test_a_gap_in_the_tape_keeps_its_edges_polarity_while_a_quarter_shows_it(
        share: float, expected: float) -> None:
    assert polarity_of(tape_on(share)) == expected


def test_a_step_of_each_sign_on_a_third_of_the_line_is_no_polarity() -> None:
    """A third of the line dark to the right, a third light to the right: neither sign has four
    times as many points as the other (a line across a mottled floor, not an edge)."""
    image = tape_on(1 / 3)
    image[TOP:round(TOP + (BOTTOM - TOP) / 3), 100:130] = 250
    assert polarity_of(image) == 0.0


def test_a_textured_floor_gives_a_line_of_no_contrast_no_polarity() -> None:
    """Seeded speckle (sd 12 levels, unblurred: about a third of the steps are clear ones of
    each sign, scattered along the line) on both sides: no sign has a quarter of the points in
    one unbroken run (counted without the run, 6 of 20 such lines got a polarity)."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        image = np.clip(150 + rng.normal(0.0, 12.0, (HEIGHT, WIDTH)), 0, 255).astype(np.uint8)
        assert polarity_of(image) == 0.0


def test_a_dark_patch_beside_the_middle_of_a_line_is_no_polarity() -> None:
    """A dark patch (a darker slat, a chip) beside the middle 40 % of a line whose ends show no
    step: a tape cut by a gap reaches one end of the line, so a mid-line run votes nothing."""
    image = np.full((HEIGHT, WIDTH), 180, np.uint8)
    image[round(TOP + 0.3 * (BOTTOM - TOP)):round(TOP + 0.7 * (BOTTOM - TOP)), 100:130] = 60
    assert polarity_of(image) == 0.0
    # The same patch reaching the line's far end (a tape beyond a gap) is the tape's edge.
    image[TOP:BOTTOM - round(0.3 * (BOTTOM - TOP)), 100:130] = 60
    assert polarity_of(image) == -1.0


def test_the_vote_needs_four_times_the_other_sign() -> None:
    """The nearest 40 % of the line steps light to dark (7 of the 18 points); a light patch at
    the far end steps the other way: over its farthest 12 % (2 points) there are fewer than
    four times as many, no polarity (twice as many would have given one); over 5 % (1 point)
    the vote stands."""

    def with_light_far_end(share: float) -> np.ndarray:
        image = tape_on(0.4)
        image[TOP:round(TOP + share * (BOTTOM - TOP)) + 1, 100:130] = 250
        return image

    assert polarity_of(with_light_far_end(0.12)) == 0.0
    assert polarity_of(with_light_far_end(0.05)) == -1.0


@pytest.mark.parametrize(("gap_points", "expected"), [(2, -1.0), (3, 0.0)])
def test_a_gap_of_two_points_in_the_run_is_bridged_not_three(gap_points: int,
                                                             expected: float) -> None:
    """Campaign scenario road-lines: the far end of a yellow dash read no clear step at two of
    its points (it is a few pixels wide there), which broke the dash's run, left its inner edge
    without polarity and the lane without its left tape for 7 frames. The tape covers the
    nearest 45 % of the line (points 0-7 of 18), with floor over points 1 to `gap_points`: a gap
    of two points in the run is bridged (the run from the near end holds: 6 clear points), a gap
    of three breaks it (5 clear points, still a quarter, but no run); the median has no say."""
    image = tape_on(0.45)
    spacing = (BOTTOM - TOP) / 18  # sample i lies at (i + 0.5) spacings above the bottom end
    image[round(BOTTOM - (gap_points + 1) * spacing):round(BOTTOM - spacing), 100:130] = 180
    assert polarity_of(image) == expected


def along_line(pattern: str) -> np.ndarray:
    """The tape's side of the line, sample by sample from the near end (18 letters): `U` the
    unlit tape (60), `L` the tape under a mirrored ceiling light (230, lighter than the floor),
    `P` the light's rim (180, as light as the floor), `F` floor (180)."""
    image = np.full((HEIGHT, WIDTH), 180, np.uint8)
    spacing = (BOTTOM - TOP) / 18
    shade = {"U": 60, "L": 230, "P": 180, "F": 180}
    for i, letter in enumerate(pattern):
        rows = slice(round(BOTTOM - (i + 1) * spacing), round(BOTTOM - i * spacing) + 1)
        image[rows, 100:130] = shade[letter]
    return image


@pytest.mark.parametrize(("pattern", "expected"), [
    # Campaign runs r00412 and r00718 (the ninth run, glossy black tape): a row of ceiling
    # lights mirrored along the tape. 8 unlit points step light to dark, 7 lit ones the other
    # way, 3 show nothing: the median says 0, the vote 0 (fewer than four times as many). Where
    # the tape is least lit, 8 of the 9 points step light to dark, along both halves of the
    # line, and light only adds light: the edge's polarity is the unlit tape's.
    ("UULLPUULLPUULLPUUL", -1.0),
    # The same counts, but the unlit tape only along the near half and the far half lit or
    # bare: no tape edge shows along the whole line (a dark patch beside a light one), none.
    ("UUUUUUUUPLLLLLLLPP", 0.0),
    # Unlit tape along both halves but one lit point: too little light to be what hid the
    # median (gaps did, the vote's case, and no run reaches an end), none.
    ("UUFFFUUFFFUUFFFUUL", 0.0),
])
def test_a_row_of_lights_mirrored_along_a_tape_keeps_its_edges_polarity(
        pattern: str, expected: float) -> None:
    assert len(pattern) == 18
    assert polarity_of(along_line(pattern)) == expected
