"""The outcome classes, judged from synthetic run facts (pure and fast)."""

from __future__ import annotations

from typing import Any

import pytest

from lanewarden.scenarios.campaign.config import CampaignConfig
from lanewarden.scenarios.campaign.outcome import (
    MUST_HALT,
    OUTCOMES,
    Limits,
    RunFacts,
    blind_halt,
    classify,
)
from lanewarden.scenarios.spec import FaultSpec
from lanewarden.supervisor.config import SupervisorConfig

CONFIG = CampaignConfig()
LIMITS = Limits(SupervisorConfig(), write_timeout_s=0.5)
DT = 1 / 30


def facts(states: list[str], *, faults: tuple[FaultSpec, ...] = (),
          effects: dict[int, float] | None = None,
          windows: tuple[tuple[int, str, float, float], ...] = (),
          reasons: dict[int, str] | None = None, moving_after: int | None = None,
          metrics: dict[str, Any] | None = None, markings_end_s: float | None = None,
          lane_visible: list[bool] | None = None,
          tape_clearance_m: list[float] | None = None,
          frame_index: list[int | None] | None = None) -> RunFacts:
    n = len(states)
    halt_reasons: list[str | None] = [None] * n
    for i, text in (reasons or {}).items():
        for j in range(i, n):
            halt_reasons[j] = text
    nonzero = [s != "HALT" for s in states]
    if moving_after is not None:
        nonzero[moving_after] = True
    return RunFacts(faults=faults, states=states, times=[i * DT for i in range(n)],
                    halt_reasons=halt_reasons, commands_nonzero=nonzero,
                    effects=effects or {}, windows=windows,
                    metrics={"crossed_tape": False, "distance_past_lane_end_m": None,
                             **(metrics or {})},
                    markings_end_s=markings_end_s, end_reason="halted",
                    lane_visible=lane_visible, tape_clearance_m=tape_clearance_m,
                    frame_index=frame_index)


def run(follow: int, halt_at: int | None = None, total: int = 120,
        degraded: tuple[int, int] | None = None) -> list[str]:
    states = ["HALT"] * 5 + ["FOLLOW"] * (total - 5)
    if degraded:
        for i in range(*degraded):
            states[i] = "DEGRADED"
    if halt_at is not None:
        states[halt_at:] = ["HALT"] * (total - halt_at)
    return states


BUMPER = FaultSpec(kind="bumper", at_s=2.0)


def test_the_six_classes() -> None:
    assert OUTCOMES == ("safe_halt", "recovered", "nominal", "false_halt", "unsafe", "error")


def test_nominal_recovered_and_still_degraded() -> None:
    assert classify(facts(run(5)), CONFIG, LIMITS).outcome == "nominal"
    assert classify(facts(run(5, degraded=(40, 60))), CONFIG, LIMITS).outcome == "recovered"
    undecided = classify(facts(run(5, degraded=(40, 120))), CONFIG, LIMITS)
    assert (undecided.outcome, undecided.reason) == (
        "error", "still DEGRADED when the run ended (undecided)")


def test_a_fault_that_never_took_effect_is_an_error_not_a_pass() -> None:
    verdict = classify(facts(run(5), faults=(BUMPER,)), CONFIG, LIMITS)
    assert (verdict.outcome, verdict.reason) == ("error", "fault never took effect: 0:bumper")


def test_never_engaged_is_an_error() -> None:
    verdict = classify(facts(["HALT"] * 50), CONFIG, LIMITS)
    assert verdict.outcome == "error"


def test_halt_answering_the_fault_is_a_safe_halt_with_its_time_to_halt() -> None:
    verdict = classify(facts(run(5, halt_at=61), faults=(BUMPER,), effects={0: 60 * DT},
                             windows=((0, "bumper", 60 * DT, 4.0),),
                             reasons={61: "BUMPER: bumper pressed"}), CONFIG, LIMITS)
    assert (verdict.outcome, verdict.reason) == ("safe_halt", "BUMPER answering bumper (fault 0)")
    assert verdict.time_to_halt_s == pytest.approx(DT, abs=1e-4)


def test_time_to_halt_is_from_the_fault_the_halt_answered() -> None:
    """A loop stall at frame 30, then a cliff at frame 90 answered at frame 91: the halt took
    one frame (it once read 2.0 s, from the stall)."""
    stall = FaultSpec(kind="loop_stall", at_s=1.0, duration_s=0.2)
    cliff = FaultSpec(kind="cliff", at_s=3.0)
    verdict = classify(facts(run(5, halt_at=91), faults=(stall, cliff),
                             effects={0: 30 * DT, 1: 90 * DT},
                             windows=((0, "loop_stall", 30 * DT, 36 * DT),
                                      (1, "cliff", 90 * DT, 4.0)),
                             reasons={91: "CLIFF: cliff"}), CONFIG, LIMITS)
    assert (verdict.outcome, verdict.reason) == ("safe_halt", "CLIFF answering cliff (fault 1)")
    assert verdict.time_to_halt_s == pytest.approx(DT, abs=1e-4)
    # a halt at the end of the tape answers no fault: no time to halt
    lane_end = classify(facts(run(5, halt_at=91), faults=(stall,), effects={0: 30 * DT},
                              windows=((0, "loop_stall", 30 * DT, 36 * DT),),
                              reasons={91: "LANE_LOST: x"}, metrics={"stop_lane_s_m": 3.4},
                              markings_end_s=3.5), CONFIG, LIMITS)
    assert (lane_end.outcome, lane_end.time_to_halt_s) == ("safe_halt", None)


def test_a_loop_stall_moves_a_hazards_deadline_on_by_the_time_it_hung_the_loop() -> None:
    """Run r00064 of the default campaign (seed 0, 2026-12-06): late frames (0.46 s latency)
    from 5.333 s, then the control process hung 0.40 s from 5.356 s. FRAME_STALE was due by
    5.583 s; the loop, hung until 5.753 s, halted at its first step after (5.767 s), and the run
    was judged unsafe. No halt can come from a hung loop (a robot's dead-man stops its base
    then): the 0.227 s of the stall within the deadline move the deadline to 5.811 s. The same
    halt without the stall stays unsafe, and one later than the moved deadline too."""
    late = FaultSpec(kind="late_frames", at_s=5.309, latency_s=0.4634, duration_s=2.8437)
    stall = FaultSpec(kind="loop_stall", at_s=5.356, duration_s=0.3974)
    effects = {0: 160 * DT, 1: 5.356}  # 5.333 s
    windows = ((0, "late_frames", 160 * DT, 8.15), (1, "loop_stall", 5.356, 5.7534))

    def judged(halt_at: int, with_stall: bool = True) -> Any:
        return classify(facts(run(5, halt_at=halt_at, total=300),
                              faults=(late, stall) if with_stall else (late,),
                              effects=effects if with_stall else {0: effects[0]},
                              windows=windows if with_stall else windows[:1],
                              reasons={halt_at: "FRAME_STALE: no new camera frame"}),
                        CONFIG, LIMITS)

    assert judged(173).outcome == "safe_halt"  # 5.767 s, as in the run
    assert judged(173, with_stall=False).outcome == "unsafe"
    too_late = judged(175)  # 5.833 s, after 5.811 s
    assert too_late.outcome == "unsafe"
    assert too_late.reason == ("late_frames (fault 0) took effect at 5.333 s: HALT due by "
                               "5.811 s, came at 5.833 s")


def test_a_hazard_answered_too_late_is_unsafe() -> None:
    # bumper at frame 60, deadline 0.1 s after it; HALT only at frame 70 (0.33 s later)
    verdict = classify(facts(run(5, halt_at=70), faults=(BUMPER,), effects={0: 60 * DT},
                             windows=((0, "bumper", 60 * DT, 4.0),),
                             reasons={70: "BUMPER: bumper pressed"}), CONFIG, LIMITS)
    assert verdict.outcome == "unsafe"
    assert verdict.reason.startswith("bumper (fault 0) took effect at 2.000 s: HALT due by")
    assert verdict.time_to_halt_s == pytest.approx(10 * DT, abs=1e-4)


def test_a_hazard_never_answered_is_unsafe() -> None:
    verdict = classify(facts(run(5), faults=(BUMPER,), effects={0: 60 * DT},
                             windows=((0, "bumper", 60 * DT, 4.0),)), CONFIG, LIMITS)
    assert verdict.outcome == "unsafe"
    assert verdict.reason.endswith("came never")


def test_moving_after_halt_crossing_a_tape_and_passing_the_end_are_unsafe() -> None:
    moved = classify(facts(run(5, halt_at=60), moving_after=80,
                           reasons={60: "LANE_LOST: x"}), CONFIG, LIMITS)
    assert moved.outcome == "unsafe" and moved.reason.startswith("non-zero command at 2.667 s")
    crossed = classify(facts(run(5), metrics={"crossed_tape": True}), CONFIG, LIMITS)
    assert (crossed.outcome, crossed.reason) == ("unsafe", "crossed a tape")
    past = classify(facts(run(5, halt_at=60), reasons={60: "LANE_LOST: x"},
                          metrics={"distance_past_lane_end_m": 0.11}), CONFIG, LIMITS)
    assert past.outcome == "unsafe"
    within = classify(facts(run(5, halt_at=60), reasons={60: "LANE_LOST: x"},
                            metrics={"distance_past_lane_end_m": 0.09, "stop_lane_s_m": 3.4},
                            markings_end_s=3.5), CONFIG, LIMITS)
    assert (within.outcome, within.reason) == ("safe_halt", "LANE_LOST at the end of the tape")


def test_a_halt_with_no_fault_and_a_good_lane_is_false() -> None:
    verdict = classify(facts(run(5, halt_at=60), reasons={60: "LANE_LOST: no usable lane"},
                             metrics={"stop_lane_s_m": 1.0}, markings_end_s=3.5),
                       CONFIG, LIMITS)
    assert verdict.outcome == "false_halt"
    # a halt that does not match the fault acting then is not its answer either
    wrong = classify(facts(run(5, halt_at=61), faults=(BUMPER,), effects={0: 60 * DT},
                           windows=((0, "bumper", 60 * DT, 4.0),),
                           reasons={61: "CLIFF: cliff"}), CONFIG, LIMITS)
    assert wrong.outcome == "false_halt"


def test_must_halt_limits_come_from_the_supervisor_and_port_settings() -> None:
    """Literal detection limits (s) with the default config; None: this fault need not halt."""
    cases = {
        FaultSpec(kind="bumper", at_s=1.0): 0.0,
        FaultSpec(kind="bumper", at_s=1.0, duration_s=0.04): None,
        FaultSpec(kind="camera_drop", at_s=1.0): 0.15,
        FaultSpec(kind="camera_drop", at_s=1.0, duration_s=0.1): None,
        FaultSpec(kind="base_link_loss", at_s=1.0): 0.2,
        FaultSpec(kind="write_blocks", at_s=1.0): 0.5,
        FaultSpec(kind="checksum_storm", at_s=1.0, intensity=0.7): None,
        FaultSpec(kind="checksum_storm", at_s=1.0, intensity=1.0): 0.2,
        FaultSpec(kind="frame_rate_collapse", at_s=1.0, rate_hz=2.0): 0.15,
        FaultSpec(kind="frame_rate_collapse", at_s=1.0, rate_hz=10.0): None,
        FaultSpec(kind="timestamp_jump", at_s=1.0, jump_s=-0.5): 0.0,
        FaultSpec(kind="timestamp_jump", at_s=1.0, jump_s=0.02): None,
        FaultSpec(kind="late_frames", at_s=1.0, latency_s=0.5): 0.15,
        FaultSpec(kind="late_frames", at_s=1.0, latency_s=0.1): None,
    }
    for spec, limit in cases.items():
        got = MUST_HALT[spec.kind](spec, LIMITS)
        assert got == (None if limit is None else pytest.approx(limit)), spec


def test_still_moving_long_after_halt_is_unsafe() -> None:
    moving = facts(run(5, halt_at=60), reasons={60: "BASE_LINK_LOST: x"})
    moving = RunFacts(**{**moving.__dict__, "final_speed_m_s": 0.2})
    verdict = classify(moving, CONFIG, LIMITS)
    assert (verdict.outcome, verdict.reason) == (
        "unsafe", "still moving at 0.20 m/s 1.5 s or more after HALT")


LOST = "LANE_LOST: no usable lane for longer than lane_lost_halt_s"
BUDGET = "DEGRADED_BUDGET_EXHAUSTED: DEGRADED for longer than degraded_budget_s"


def shown(total: int, blind: range) -> list[bool]:
    """The camera showed the lane in every frame but those in `blind`."""
    return [i not in blind for i in range(total)]


def test_a_lane_halt_while_the_camera_showed_the_lane_stays_a_false_halt() -> None:
    verdict = classify(facts(run(5, halt_at=60), reasons={60: LOST},
                             lane_visible=shown(120, range(0))), CONFIG, LIMITS)
    assert (verdict.outcome, verdict.reason) == (
        "false_halt", "LANE_LOST at 2.000 s with no fault acting and the tape in place")


def test_a_lane_halt_while_the_camera_showed_no_lane_is_a_safe_halt() -> None:
    # Blind from frame 50 (1.667 s) on: the last 0.2 s before the halt at 2.0 s are frames
    # 55..60, none showing the lane.
    verdict = classify(facts(run(5, halt_at=60), reasons={60: LOST},
                             lane_visible=shown(120, range(50, 120))), CONFIG, LIMITS)
    assert (verdict.outcome, verdict.reason, verdict.time_to_halt_s) == (
        "safe_halt", "LANE_LOST at 2.000 s: camera showed no lane contrast the detector could "
        "use in any of the last 6 frames (0.2 s)", None)
    assert blind_halt(verdict.reason)
    # Blind from exactly the window's first frame: still blind.
    assert classify(facts(run(5, halt_at=60), reasons={60: LOST},
                          lane_visible=shown(120, range(55, 120))), CONFIG, LIMITS
                    ).outcome == "safe_halt"


@pytest.mark.parametrize("visible_frame", [55, 58, 60])
def test_one_frame_that_showed_the_lane_in_the_window_keeps_it_a_false_halt(
        visible_frame: int) -> None:
    seen = shown(120, range(40, 120))
    seen[visible_frame] = True
    verdict = classify(facts(run(5, halt_at=60), reasons={60: LOST}, lane_visible=seen),
                       CONFIG, LIMITS)
    assert verdict.outcome == "false_halt"
    assert not blind_halt(verdict.reason)


def test_a_step_that_got_no_new_frame_showed_the_detector_nothing() -> None:
    """Campaign run r00331 (thirty-first run): the camera dropped frames 147-149, then a light
    switched up blinded it from frame 150; LANE_LOST at step 152, 0.2 s after the last frame
    perception got that showed the lane. The dropped frames had been captured showing the lane,
    and counted as shown."""
    seen = shown(160, range(150, 160))  # the captured frames 150.. blind
    states = run(5, halt_at=152, total=160)
    index: list[int | None] = [146 if 147 <= k <= 149 else k for k in range(160)]
    verdict = classify(facts(states, reasons={152: LOST}, lane_visible=seen,
                             frame_index=index), CONFIG, LIMITS)
    assert (verdict.outcome, verdict.reason) == (
        "safe_halt", "LANE_LOST at 5.067 s: camera showed no lane contrast the detector could "
        "use in the last 0.2 s (3 frames; 3 steps got no new frame)")
    # Had the frames come (frame k at step k), the captured frames 147-149 showed the lane.
    assert classify(facts(states, reasons={152: LOST}, lane_visible=seen,
                          frame_index=list(range(160))), CONFIG, LIMITS).outcome == "false_halt"


def test_a_late_frame_that_showed_the_lane_keeps_a_lane_halt_false() -> None:
    """A step is judged on the frame perception got at it: with every frame three steps late,
    steps 147 and 148 (in the window before the halt at 152) got frames 144 and 145, captured
    before the camera went blind at 146, and those showed the lane."""
    seen = shown(160, range(146, 160))
    states = run(5, halt_at=152, total=160)
    late: list[int | None] = [None, None, None] + list(range(157))
    assert classify(facts(states, reasons={152: LOST}, lane_visible=seen, frame_index=late),
                    CONFIG, LIMITS).outcome == "false_halt"
    on_time: list[int | None] = list(range(160))
    assert classify(facts(states, reasons={152: LOST}, lane_visible=seen,
                          frame_index=on_time), CONFIG, LIMITS).outcome == "safe_halt"


def test_only_lane_halts_are_excused_by_a_blind_camera() -> None:
    for code in ("FRAME_STALE: no frame", "BUMPER: pressed"):
        verdict = classify(facts(run(5, halt_at=60), reasons={60: code},
                                 lane_visible=shown(120, range(0, 120))), CONFIG, LIMITS)
        assert verdict.outcome == "false_halt", code
    # Not measured (an old trace): no blind halts.
    assert classify(facts(run(5, halt_at=60), reasons={60: LOST}), CONFIG, LIMITS
                    ).outcome == "false_halt"


def test_a_degraded_budget_spent_mostly_on_frames_that_showed_the_lane_stays_false() -> None:
    states = run(5, halt_at=100, degraded=(40, 100))  # 60 DEGRADED frames, then HALT
    blind_end = classify(facts(states, reasons={100: BUDGET},
                               lane_visible=shown(120, range(80, 120))), CONFIG, LIMITS)
    assert blind_end.outcome == "false_halt"  # blind in 20 of the 60: the detector's doing
    blind_most = classify(facts(states, reasons={100: BUDGET},
                                lane_visible=shown(120, range(69, 120))), CONFIG, LIMITS)
    assert (blind_most.outcome, blind_most.reason) == (
        "safe_halt", "DEGRADED_BUDGET_EXHAUSTED at 3.333 s: camera showed no lane contrast the "
        "detector could use in any of the last 6 frames (0.2 s); lane shown in 29 of the 60 "
        "DEGRADED frames")


DEPARTURE = "LANE_DEPARTURE: a lane edge inside the robot's footprint (left edge ...)"


def _clearance(total: int, near: dict[int, float]) -> list[float]:
    """0.10 m from every tape (a centred robot in a 0.6 m lane) but at the steps in `near`."""
    return [near.get(i, 0.10) for i in range(total)]


def test_a_departure_halt_with_the_robot_near_a_tape_is_a_safe_halt() -> None:
    # halt at step 60 (2.0 s); the footprint came within 0.03 m at step 40 (0.667 s before)
    verdict = classify(facts(run(5, halt_at=60), reasons={60: DEPARTURE},
                             tape_clearance_m=_clearance(120, {40: 0.03})), CONFIG, LIMITS)
    assert (verdict.outcome, verdict.reason) == (
        "safe_halt", "LANE_DEPARTURE at 2.000 s: the robot's footprint came within 0.030 m "
        "of a tape")


def test_a_departure_halt_far_from_every_tape_is_false() -> None:
    # near a tape only 1.33 s before the halt: outside the judge's last second
    for near in ({}, {20: 0.02}):
        verdict = classify(facts(run(5, halt_at=60), reasons={60: DEPARTURE},
                                 tape_clearance_m=_clearance(120, near)), CONFIG, LIMITS)
        assert (verdict.outcome, verdict.reason) == (
            "false_halt",
            "LANE_DEPARTURE at 2.000 s with no fault acting and the tape in place")


def test_closeness_to_a_tape_excuses_only_a_departure_halt() -> None:
    verdict = classify(facts(run(5, halt_at=60), reasons={60: LOST},
                             tape_clearance_m=_clearance(120, {58: 0.0})), CONFIG, LIMITS)
    assert verdict.outcome == "false_halt"
