"""`perception.tape.kind`: the user's word that the lane's tapes are darker than the floor
(`dark`: black tape on a light floor) or lighter (`light`). With it, a band of the other kind is
never a tape: not as a verified pair, not as a lone edge's profile, and a lone edge whose sign
says the other kind is not chosen while a line of the right kind or of no sign is there (campaign
run r00706: at a corner of the lecture's course on parquet, two light slats, each between darker
slats, passed for the lane's two tapes at confidence 0.74 while the lane's tapes were black, and
the supervisor halted on a departure from that lane). `any`, the default, is the rule as before.

Whole frames: the synthetic test scenes (tests/perception/synthetic.py); rules on their own: the
floor pictures and lines of test_tape_rules.py (the default camera at 640x480, metres)."""

from __future__ import annotations

import pytest

from lanewarden.config import config_from_mapping
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.edge_choice import choose_edges
from lanewarden.perception.ground import default_ground_model
from lanewarden.perception.tape_rules import tape_profile_fraction
from tests.perception import synthetic as syn
from tests.perception.test_tape_rules import DARK, GROUND, VIEW, along, floor_line, floor_picture

LIGHT = 245  # a light tape (or a light slat) on the floor of 180
TAPE_LO, TAPE_HI = 0.276, 0.324  # a tape 0.276..0.324 m left of the robot's centre line


def with_kind(kind: str) -> PerceptionConfig:
    return config_from_mapping({"perception": {"tape": {"kind": kind}}}, "test").perception


def detect(scene: syn.Scene, kind: str, size: tuple[int, int]):  # type: ignore[no-untyped-def]
    detector = LaneDetector(with_kind(kind), ground=default_ground_model(size))
    return detector.detect(syn.render(scene, *size), 0, 0.0)


SIZES = [(640, 480), (320, 240)]


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize(("scene", "kind"), [(syn.DARK_ON_LIGHT, "dark"),
                                             (syn.LIGHT_ON_DARK, "light")])
def test_the_lane_of_the_configured_kind_reads_as_without_it(
    scene: syn.Scene, kind: str, size: tuple[int, int]
) -> None:
    said, unsaid = detect(scene, kind, size), detect(scene, "any", size)
    assert said.confidence >= 0.9
    assert (said.left, said.right, said.confidence) == (unsaid.left, unsaid.right,
                                                        unsaid.confidence)


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize(("scene", "kind"), [(syn.DARK_ON_LIGHT, "light"),
                                             (syn.LIGHT_ON_DARK, "dark")])
def test_tapes_of_the_other_kind_are_no_tapes(
    scene: syn.Scene, kind: str, size: tuple[int, int]
) -> None:
    """The same clean lanes, the user having said the other kind: no verified tape, no lane."""
    assert detect(scene, "any", size).confidence >= 0.9
    observation = detect(scene, kind, size)
    assert observation.components["verified_tape"] == 0.0
    assert observation.confidence == 0.0


@pytest.mark.parametrize(
    ("band", "kind", "fraction"),
    [
        (DARK, "any", 1.0), (DARK, "dark", 1.0), (DARK, "light", 0.0),
        (LIGHT, "any", 1.0), (LIGHT, "light", 1.0), (LIGHT, "dark", 0.0),
    ],
)
def test_a_lone_edge_is_a_tape_edge_only_beside_a_band_of_the_configured_kind(
    band: int, kind: str, fraction: float
) -> None:
    """The tape's inner edge alone (Hough missed its outer edge), a band of a tape's width
    beyond it, darker or lighter than the floor."""
    picture = floor_picture([(TAPE_LO, TAPE_HI, band)])
    edge = along(TAPE_LO, 1.0 if band == DARK else -1.0)
    tape = with_kind(kind).tape
    assert tape_profile_fraction(picture, [edge], (0,), "left", VIEW, tape) == fraction


def test_a_lone_edge_whose_sign_says_the_other_kind_is_not_chosen() -> None:
    """On the left: the dark tape's inner edge alone (its profile says tape), and a longer line
    at the image's left border whose sign says a LIGHT tape lies beyond it (its far side is
    outside the image, so its profile cannot refute it: `unverifiable_score`). Without a kind
    the border line wins on its length; with `dark` it is not a candidate."""
    picture = floor_picture([(TAPE_LO, TAPE_HI, DARK)])
    tape_edge = along(TAPE_LO, 1.0, support=100.0, line_id=0)
    border = floor_line(VIEW.to_floor(150.0, 470.0), VIEW.to_floor(0.0, 250.0), -1.0,
                        support=400.0, line_id=1)
    rows = [tape_edge, border]
    for kind, chosen in (("any", 1), ("dark", 0)):
        config = with_kind(kind)
        setup = LaneDetector(config, ground=GROUND).setup_for(640, 480)
        left, _ = choose_edges(rows, picture, setup, config)
        assert left is not None and left.chain[0] == chosen, kind


def test_a_side_with_only_lines_of_the_other_kind_has_no_edge() -> None:
    """The border line alone (its sign says a light tape): without a kind it is the side's edge
    (unverifiable); with `dark` the side has none. The strongest line of any sign had stood in
    for a side without signed lines, so a line of the other kind came back through it."""
    picture = floor_picture([])
    border = floor_line(VIEW.to_floor(150.0, 470.0), VIEW.to_floor(0.0, 250.0), -1.0,
                        support=400.0, line_id=0)
    for kind, expected in (("any", (0,)), ("dark", None)):
        config = with_kind(kind)
        setup = LaneDetector(config, ground=GROUND).setup_for(640, 480)
        left, _ = choose_edges([border], picture, setup, config)
        assert (None if left is None else left.chain) == expected, kind
