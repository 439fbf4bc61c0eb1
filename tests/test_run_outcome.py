"""Why a robot run ended, and its exit code (lanewarden.run_outcome), on literal step sequences:
the one decision every place shows (status line, summary, stderr, summary.json, replay, live
page)."""

from __future__ import annotations

import pytest

from lanewarden.run_outcome import (
    CUT_SHORT,
    EndReason,
    LoopEnd,
    LoopEndKind,
    RunWatch,
    end_reason,
    end_reason_of,
    recorded_loop_end,
)

LANE_LOST = "LANE_LOST: no usable lane for longer than lane_lost_halt_s"
STALE = "FRAME_STALE: newest camera frame older than frame_stale_s"
CAMERA = "CAMERA_ERROR: CameraLost: end of the recorded clip after 75 frames"
BUMPER = "BUMPER: bumper pressed"
OPERATOR = "OPERATOR_STOP: operator stop"
NOT_STARTED = "not engaged yet: waiting for start and a confident lane"

OPERATOR_END = LoopEnd(LoopEndKind.OPERATOR, "operator stop (SIGINT)")
TERM_END = LoopEnd(LoopEndKind.OPERATOR, "operator stop (SIGTERM)")
DURATION_END = LoopEnd(LoopEndKind.DURATION, "--duration 5 s reached")
CLIP_END = LoopEnd(LoopEndKind.CLIP, "end of the clip")

# (state, halt reason, step time, newest frame's capture time) per step
Steps = list[tuple[str, str | None, float, float | None]]
ENGAGED: Steps = [("HALT", NOT_STARTED, 0.0, 0.0), ("FOLLOW", None, 0.1, 0.1)]


def _end(steps: Steps, end: LoopEnd) -> EndReason:
    watch = RunWatch()
    watch.observe_all(steps)
    return end_reason(watch, end)


@pytest.mark.parametrize(("steps", "end", "expected"), [
    # normal ends: still engaged, never engaged, the operator's own stop
    (ENGAGED, DURATION_END,
     ("--duration 5 s reached", None, "FOLLOW", None, True)),
    ([("HALT", NOT_STARTED, 0.0, 0.0), ("HALT", STALE, 0.5, 0.0)], OPERATOR_END,
     ("operator stop (SIGINT)", None, "HALT", STALE, False)),
    (ENGAGED + [("HALT", OPERATOR, 0.2, 0.2), ("HALT", STALE, 0.9, 0.2)], TERM_END,
     ("operator stop (SIGTERM)", None, "HALT", OPERATOR, True)),
    # a clip whose lane ends: the halt that stopped the engaged robot and still holds, not the
    # clip's own end after it (CAMERA_ERROR) or later re-halts
    (ENGAGED + [("HALT", LANE_LOST, 0.4, 0.4), ("HALT", STALE, 0.9, 0.4),
                ("HALT", CAMERA, 1.0, 0.4)], CLIP_END,
     ("end of the clip", LANE_LOST, "HALT", LANE_LOST, True)),
    (ENGAGED + [("HALT", LANE_LOST, 0.4, 0.4)], DURATION_END,
     ("--duration 5 s reached", LANE_LOST, "HALT", LANE_LOST, True)),
    # a bumper held when the clip ended
    (ENGAGED + [("HALT", BUMPER, 0.4, 0.4), ("HALT", CAMERA, 1.0, 0.9)], CLIP_END,
     ("end of the clip", BUMPER, "HALT", BUMPER, True)),
    # a bumper pressed between the clip's last frame and its end is a safety stop, not the end
    (ENGAGED + [("HALT", BUMPER, 0.15, 0.1), ("HALT", CAMERA, 0.2, 0.1)], CLIP_END,
     ("end of the clip", BUMPER, "HALT", BUMPER, True)),
    # halted, then engaged again (auto-resume), then a normal end
    (ENGAGED + [("HALT", LANE_LOST, 0.4, 0.4), ("FOLLOW", None, 0.6, 0.6)], DURATION_END,
     ("--duration 5 s reached", None, "FOLLOW", None, True)),
    # a clip that ends while following: its end (CAMERA_ERROR, or a stale frame, after the last
    # frame) is the run's end in the state before it, not a halt
    (ENGAGED + [("HALT", CAMERA, 0.5, 0.1)], CLIP_END,
     ("end of the clip", None, "FOLLOW", None, True)),
    (ENGAGED + [("TURN_LEFT", None, 0.2, 0.2), ("HALT", STALE, 0.5, 0.2)], CLIP_END,
     ("end of the clip", None, "TURN_LEFT", None, True)),
    # ...but not a stale frame before the last frame, nor one while a live camera runs
    (ENGAGED + [("HALT", STALE, 0.5, 0.1), ("HALT", STALE, 0.6, 0.6)], CLIP_END,
     ("end of the clip", STALE, "HALT", STALE, True)),
    (ENGAGED + [("HALT", STALE, 0.5, 0.1)], OPERATOR_END,
     ("operator stop (SIGINT)", STALE, "HALT", STALE, True)),
])
def test_end_reason(steps: Steps, end: LoopEnd,
                    expected: tuple[str, str | None, str, str | None, bool]) -> None:
    reason = _end(steps, end)
    assert (reason.ended_by, reason.safety_stop, reason.state, reason.halt_reason,
            reason.engaged) == expected


def test_a_failure_that_ends_the_run_wins_even_before_engaging() -> None:
    fault = "CAMERA_LOST: --camera 0: the camera stopped delivering frames"
    reason = _end([("HALT", NOT_STARTED, 0.0, 0.0)], LoopEnd(LoopEndKind.FAILURE, fault))
    assert (reason.safety_stop, reason.text, reason.exit_code) == (
        fault, f"safety stop: {fault}", 3)


def test_what_every_place_shows() -> None:
    lane = _end(ENGAGED + [("HALT", LANE_LOST, 0.4, 0.4), ("HALT", CAMERA, 1.0, 0.4)], CLIP_END)
    assert lane.text == f"safety stop: {LANE_LOST}"
    assert lane.name == "LANE_LOST"
    assert lane.state_text == f"HALT ({LANE_LOST})"
    assert lane.stop_line == f"halted: {LANE_LOST}"
    assert lane.exit_code == 3
    clip = _end(ENGAGED + [("HALT", CAMERA, 0.5, 0.1)], CLIP_END)
    assert (clip.text, clip.name, clip.state_text, clip.exit_code) == (
        "end of the clip", "end of the clip", "FOLLOW", 0)
    assert clip.stop_line == "stopped by the end of the run (end of the clip) while FOLLOW"
    never = _end([("HALT", NOT_STARTED, 0.0, 0.0)], CLIP_END)
    assert (never.text, never.stop_line, never.exit_code) == (
        "end of the clip", "never engaged", 0)
    assert clip.as_json() == {"text": "end of the clip", "name": "end of the clip",
                              "safety_stop": None, "ended_by": "end of the clip",
                              "state": "FOLLOW", "halt_reason": None, "engaged": True}


def test_a_failure_that_stops_a_following_robot_reads_as_a_halt() -> None:
    """A dead-man trip (or a lost link or camera) while FOLLOW is a safety stop: the summary's
    first line says `halted:` as for every safety stop, naming the state it stopped, never "the
    end of the run" (a new user's review: `stopped by the end of the run (DEADMAN_TRIPPED: ...)
    while FOLLOW`)."""
    trip = "DEADMAN_TRIPPED: the dead-man stopped the base (no heartbeat for 0.20 s)"
    reason = _end(ENGAGED + [("FOLLOW", None, 0.2, 0.2)], LoopEnd(LoopEndKind.FAILURE, trip))
    assert (reason.state, reason.exit_code) == ("FOLLOW", 3)
    assert reason.stop_line == (
        "halted: DEADMAN_TRIPPED: the dead-man stopped the base (no heartbeat for 0.20 s) "
        "(while FOLLOW)")


def test_the_runners_closing_stop_is_not_looked_at() -> None:
    """A recorded run ends with the runner's own stop (OPERATOR_STOP); `steps` says where the
    loop ended, so a replay decides as the run did: engaged (FOLLOW) when Ctrl-C came."""
    recorded = ENGAGED + [("FOLLOW", None, 0.2, 0.2), ("HALT", OPERATOR, 0.21, 0.2)]
    reason = end_reason_of(recorded, OPERATOR_END.with_steps(3))
    assert (reason.text, reason.state, reason.stop_line) == (
        "operator stop (SIGINT)", "FOLLOW",
        "stopped by the end of the run (operator stop (SIGINT)) while FOLLOW")
    everything = end_reason_of(recorded, OPERATOR_END)
    assert everything.state_text == f"HALT ({OPERATOR})"


def test_what_ended_a_recorded_run_is_read_from_its_summary() -> None:
    ended_by = {"kind": "clip", "text": "end of the clip", "steps": 75}
    assert recorded_loop_end({"ended_by": ended_by}) == CLIP_END.with_steps(75)
    assert LoopEnd.from_json(CLIP_END.with_steps(75).as_json()) == CLIP_END.with_steps(75)
    for broken in ({"ended_by": "end of the clip"}, {"ended_by": {**ended_by, "kind": "x"}},
                   {"ended_by": {**ended_by, "steps": -1}},
                   {"ended_by": {**ended_by, "steps": True}}, {"end_reason": "end of the clip"}):
        end = recorded_loop_end(broken)  # where the steps stop, not "no summary"
        assert (end.kind, end.text, end.steps) == (
            LoopEndKind.CUT_SHORT,
            "the recording stops here (its summary does not say what ended the run)", None)
    assert recorded_loop_end({}) == recorded_loop_end(None) == CUT_SHORT


@pytest.mark.parametrize(("reason", "code"), [
    (EndReason("end of the clip", None, "FOLLOW"), 0),
    (EndReason("--duration 1 s reached", LANE_LOST, "HALT", LANE_LOST), 3),
])
def test_exit_codes(reason: EndReason, code: int) -> None:
    assert reason.exit_code == code
