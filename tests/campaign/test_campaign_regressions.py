"""Runs of the 1000-run default campaign (seed 0) that once went wrong, drawn again from the
spec and run without their faults: each must follow its lane (nominal, or recovered after a
brief DEGRADED), not halt."""

from __future__ import annotations

import pytest

from lanewarden.assembly import build_stack
from lanewarden.scenarios.campaign.cases import draw_case, load_campaign_spec
from lanewarden.scenarios.campaign.run_case import run_case


@pytest.mark.parametrize(("index", "drawn"), [
    # one-edge-gap, the scenario's own tape and floor, 320x240: LANE_LOST at 10.8 s as the
    # right tape's 40 cm gap came into view, its inner edge's line then half in the gap (its
    # median step said "no contrast"; perception/lines.py `_vote`).
    (194, ("one-edge-gap", "320x240", "scenario", "scenario")),
])
def test_a_run_that_once_false_halted_follows_its_lane(
        index: int, drawn: tuple[str, str, str, str]) -> None:
    spec, path = load_campaign_spec("default")
    case = draw_case(spec, path, 0, index, {}, 0.2)
    assert (case.scenario["name"], case.camera, case.tape, case.floor) == drawn
    case = case.model_copy(update={"scenario": {**case.scenario, "faults": []}})
    row = run_case(case.model_dump_json(), build_stack)
    assert row["outcome"] in {"nominal", "recovered"}, row["reason"]
