"""Runs of the 1000-run default campaign (seed 0) that once went wrong, drawn again from the
spec and run without their faults: each must follow its lane (nominal, or recovered after a
brief DEGRADED), not halt. Drawn from the default spec they were found with
(`default_spec_2026_12_05.yaml`, before camera_ring joined it and changed every draw)."""

from __future__ import annotations

from pathlib import Path

import pytest

from lanewarden.assembly import build_stack
from lanewarden.scenarios.campaign.cases import draw_case, load_campaign_spec
from lanewarden.scenarios.campaign.run_case import run_case

#: The default spec these runs were found with.
FOUND_WITH = str(Path(__file__).with_name("default_spec_2026_12_05.yaml"))
#: The default spec with camera_ring in it (the seed-3 campaign of 2026-12-07).
FOUND_WITH_RING = str(Path(__file__).with_name("default_spec_2026_12_07.yaml"))


@pytest.mark.parametrize(("index", "drawn"), [
    # one-edge-gap, the scenario's own tape and floor, 320x240: LANE_LOST at 10.8 s as the
    # right tape's 40 cm gap came into view, its inner edge's line then half in the gap (its
    # median step said "no contrast"; perception/lines.py `_vote`).
    (194, ("one-edge-gap", "320x240", "scenario", "scenario")),
])
def test_a_run_that_once_false_halted_follows_its_lane(
        index: int, drawn: tuple[str, str, str, str]) -> None:
    spec, path = load_campaign_spec(FOUND_WITH)
    case = draw_case(spec, path, 0, index, {}, 0.2)
    assert (case.scenario["name"], case.camera, case.tape, case.floor) == drawn
    case = case.model_copy(update={"scenario": {**case.scenario, "faults": []}})
    row = run_case(case.model_dump_json(), build_stack)
    assert row["outcome"] in {"nominal", "recovered"}, row["reason"]


@pytest.mark.parametrize(("index", "drawn"), [
    # lecture, the scenario's floor and tape, dim room: a tape patch 0.38 m right of the centre
    # line at corner A taken for the inner tape; LANE_LOST 0.2 mm over the outer tape, stopped
    # 1.8 mm over it (docs/campaigns.md, "Twentieth run")
    (665, ("lecture", "320x240", "scenario", "scenario")),
    # lecture, yellow dashes beside white on parquet: in DEGRADED on lanes placed from one tape,
    # over the outer tape for 1.2 s, LANE_DEPARTURE 66 mm over it
    (910, ("lecture", "320x240", "yellow-dashed-white", "parquet")),
])
def test_a_tape_patch_at_the_lectures_corner_does_not_take_the_robot_over_a_tape(
        index: int, drawn: tuple[str, str, str, str]) -> None:
    """The departure rule as it was (confident frames only, the footprint's bare radius, the
    edge read along the robot's y axis) let both cross the tape (docs/supervisor.md)."""
    spec, path = load_campaign_spec(FOUND_WITH)
    case = draw_case(spec, path, 4, index, {}, 0.2)
    assert (case.scenario["name"], case.camera, case.tape, case.floor) == drawn
    assert [f["kind"] for f in case.scenario["faults"]] == ["tape_patch"]
    row = run_case(case.model_dump_json(), build_stack)
    assert row["outcome"] != "unsafe", row["reason"]


@pytest.mark.parametrize(("index", "drawn"), [
    # terrazzo: the right edge flickering between the tape (-7 degrees) and texture lines at
    # +-40 degrees, read square to them 0.18 m from a robot 7 cm clear of the tape
    (89, ("lecture", "320x240", "black-matte", "terrazzo")),
    # the inner tape of the lecture's tight corner, its chord at 40-48 degrees opening away
    # from the robot: its line read back behind where it is seen cuts the corner of the bend
    (623, ("lecture", "320x240", "black-glossy", "terrazzo")),
    (932, ("lecture", "320x240", "black-matte", "wood-planks")),
])
def test_a_steep_edge_near_the_robot_is_no_false_departure(
        index: int, drawn: tuple[str, str, str, str]) -> None:
    """Seed 1 runs the first version of today's departure rule (usable frames, the distance
    read square to every edge) halted LANE_DEPARTURE 52-88 mm from the tape
    (docs/campaigns.md, "Twenty-first run")."""
    spec, path = load_campaign_spec(FOUND_WITH)
    case = draw_case(spec, path, 1, index, {}, 0.2)
    assert (case.scenario["name"], case.camera, case.tape, case.floor) == drawn
    row = run_case(case.model_dump_json(), build_stack)
    assert row["outcome"] != "false_halt", row["reason"]
    assert row["outcome"] != "unsafe", row["reason"]


@pytest.mark.parametrize(("seed", "index", "drawn"), [
    # an s-curve on terrazzo, glossy tape, the high wide camera at 320x240: LANE_LOST at 4.2 s
    # entering the left bend, HoughLinesP's lines through the chips having taken the left
    # tape's edges (its left edge flickering between the tape and texture lines at -1.2 rad)
    (1, 144, ("s-curve", "high-wide-320", "black-glossy", "terrazzo")),
    # the one-edge gap and an s-curve, worn tape: LANE_LOST (r00191 at 11.4 s) and the degraded
    # budget used up (r00105 at 12.9 s), the tapes' edges in pieces among the chips' lines
    (4, 191, ("one-edge-gap", "320x240", "black-worn", "terrazzo")),
    (7, 105, ("s-curve", "320x240", "black-worn", "terrazzo")),
])
def test_a_lane_on_terrazzo_at_320x240_keeps_it(
        seed: int, index: int, drawn: tuple[str, str, str, str]) -> None:
    """The twenty-ninth run's three false halts on terrazzo (docs/campaigns.md): Canny's edges
    covered a fifth of the floor; with the edge budget (`perception.canny.max_edge_share`) each
    follows its lane. (With `max_edge_share: 1` each halts as it did.)"""
    spec, path = load_campaign_spec(FOUND_WITH)
    case = draw_case(spec, path, seed, index, {}, 0.2)
    assert (case.scenario["name"], case.camera, case.tape, case.floor) == drawn
    row = run_case(case.model_dump_json(), build_stack)
    assert row["outcome"] != "false_halt", row["reason"]
    assert row["outcome"] != "unsafe", row["reason"]


def test_a_camera_ring_during_a_frame_rate_collapse_halts_on_its_first_replayed_image() -> None:
    """Seed 3 run r00194 (glare on ceramic, 640x480): the frame rate collapses to 6.5 Hz at
    7.96 s, and at 8.46 s the driver starts re-delivering its last buffers. The simulated
    camera once let the frames it did not deliver overwrite the buffers of those it did, so
    the ring replayed renders the loop had never seen; FRAME_FROZEN came with the third
    replayed image, at 8.93 s, 83 ms after the judge's deadline (unsafe). The buffers now
    hold what the camera delivered: the first replayed image, at 8.60 s, is one the watchdog
    has seen, 0.153 s after the last new one."""
    spec, path = load_campaign_spec(FOUND_WITH_RING)
    case = draw_case(spec, path, 3, 194, {}, 0.2)
    assert (case.scenario["name"], case.camera, case.floor) == ("glare", "640x480", "ceramic")
    assert case.fault_kinds == ["camera_ring", "frame_rate_collapse"]
    row = run_case(case.model_dump_json(), build_stack)
    assert row["outcome"] == "safe_halt", row["reason"]
    assert row["reason"].startswith("FRAME_FROZEN"), row["reason"]
