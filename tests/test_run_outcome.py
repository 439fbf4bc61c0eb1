"""Why a robot run ended and its exit code (lanewarden.run_outcome), on literal step sequences."""

from __future__ import annotations

import pytest

from lanewarden.run_outcome import RunOutcome, RunWatch

LANE_LOST = "LANE_LOST: no usable lane for longer than lane_lost_halt_s"
STALE = "FRAME_STALE: no new camera frame within the watchdog limit"
OPERATOR = "OPERATOR_STOP: operator stop"
NOT_STARTED = "not engaged yet: waiting for start and a confident lane"

# (state, halt reason, step time, newest frame's capture time) per step
Steps = list[tuple[str, str | None, float, float | None]]
ENGAGED: Steps = [("HALT", NOT_STARTED, 0.0, 0.0), ("FOLLOW", None, 0.1, 0.1)]


def _watch(steps: Steps) -> RunWatch:
    watch = RunWatch()
    for step in steps:
        watch.observe(*step)
    return watch


@pytest.mark.parametrize(("steps", "ended_by", "clip_ended", "expected"), [
    # normal ends: still engaged, never engaged, the operator's own stop
    (ENGAGED, "--duration 5 s reached", False, RunOutcome("--duration 5 s reached")),
    ([("HALT", NOT_STARTED, 0.0, 0.0), ("HALT", STALE, 0.5, 0.0)], "operator stop (SIGINT)",
     False, RunOutcome("operator stop (SIGINT)")),
    (ENGAGED + [("HALT", OPERATOR, 0.2, 0.2), ("HALT", STALE, 0.9, 0.2)],
     "operator stop (SIGTERM)", False, RunOutcome("operator stop (SIGTERM)")),
    # a halt that stopped the engaged robot and still holds: the first one, not later re-halts
    (ENGAGED + [("HALT", LANE_LOST, 0.4, 0.4), ("HALT", STALE, 0.9, 0.4)], "end of the clip",
     True, RunOutcome("end of the clip", LANE_LOST)),
    (ENGAGED + [("HALT", LANE_LOST, 0.4, 0.4)], "--duration 1 s reached", False,
     RunOutcome("--duration 1 s reached", LANE_LOST)),
    # halted, then engaged again (auto-resume), then a normal end
    (ENGAGED + [("HALT", LANE_LOST, 0.4, 0.4), ("FOLLOW", None, 0.6, 0.6)],
     "--duration 1 s reached", False, RunOutcome("--duration 1 s reached")),
    # a stale frame after the clip's last frame is the clip's end...
    (ENGAGED + [("HALT", STALE, 0.5, 0.1)], "end of the clip", True,
     RunOutcome("end of the clip")),
    # ...but not before it, and not for a live camera
    (ENGAGED + [("HALT", STALE, 0.5, 0.1), ("HALT", STALE, 0.6, 0.6)], "end of the clip", True,
     RunOutcome("end of the clip", STALE)),
    (ENGAGED + [("HALT", STALE, 0.5, 0.1)], "operator stop (SIGINT)", False,
     RunOutcome("operator stop (SIGINT)", STALE)),
])
def test_outcome(steps: Steps, ended_by: str, clip_ended: bool, expected: RunOutcome) -> None:
    assert _watch(steps).outcome(ended_by, clip_ended=clip_ended) == expected


def test_a_failure_that_ends_the_run_wins_even_before_engaging() -> None:
    fault = "CAMERA_LOST: --camera 0: the camera stopped delivering frames"
    outcome = _watch([("HALT", NOT_STARTED, 0.0, 0.0)]).outcome("an error", fault=fault)
    assert outcome == RunOutcome(fault, fault)
    assert outcome.exit_code == 3


@pytest.mark.parametrize(("outcome", "code"), [
    (RunOutcome("end of the clip"), 0),
    (RunOutcome("--duration 1 s reached", LANE_LOST), 3),
])
def test_exit_codes(outcome: RunOutcome, code: int) -> None:
    assert outcome.exit_code == code
