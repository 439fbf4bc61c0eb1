"""The summary of what perception gave the supervisor before a halt (scenarios/before_halt.py):
hand-built step records at 30 Hz, every count written out."""

from __future__ import annotations

from dataclasses import replace
from types import MappingProxyType

from lanewarden.actuation.base import STOP
from lanewarden.commands.sim import _summary_lines
from lanewarden.perception.observation import LaneObservation
from lanewarden.scenarios.before_halt import RecentSteps, before_halt, describe
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.loop import StepRecord
from tests.supervisor.rig import DT, LEFT_EDGE, observation

CONFIG = SupervisorConfig()  # confident from 0.6, usable from 0.2 (the defaults)
CAP = 12.0


def step(index: int, obs: LaneObservation | None, *events: str,
         state: str = "DEGRADED") -> StepRecord:
    return StepRecord(frame_index=index, time_s=index * DT, observation=obs,
                      filtered_slope_sum=0.0, slope_sum_variance=0.1, state=state,
                      events=tuple(events), command=STOP, halt_reason=None)


def seen(index: int, confidence: float, **components: float) -> LaneObservation:
    obs = observation(index, index * DT, confidence=confidence)
    return replace(obs, components=MappingProxyType({"both_sides": 1.0, **components}))


def upright(index: int) -> LaneObservation:
    """A confident frame whose left edge stands upright in the image: slope at the cap."""
    obs = seen(index, 0.9)
    return replace(obs, left=replace(LEFT_EDGE, slope=CAP), slope_sum=CAP - 1.6)


def test_counts_grades_runs_and_the_weakest_components_of_the_last_two_seconds() -> None:
    assert CONFIG.confidence_confident_min == 0.6 and CONFIG.confidence_usable_min == 0.2
    records = [step(i, seen(i, 0.9)) for i in range(10)]  # 0.000-0.300 s: outside the window
    records += [
        step(10, seen(10, 0.9)), step(11, seen(11, 0.9)), step(12, seen(12, 0.9)),
        step(13, seen(13, 0.0, lane_width=0.0, parallel=0.4)),
        step(14, seen(14, 0.9)), step(15, upright(15), "INNOVATION_OUTLIER"),
        step(16, seen(16, 0.9)), step(17, seen(17, 0.9)),
        step(18, seen(18, 0.9), "REPEATED_OUTLIERS"),
        step(19, seen(19, 0.4, consistency=0.4)),
        step(20, None),
        step(21, seen(21, 0.1, lane_width=0.1, consistency=0.5)),
        step(22, seen(22, 0.0, parallel=0.0, lane_width=0.0)),
        step(23, seen(23, 0.9)),
    ]
    records += [step(24, seen(24, 0.9), "DEGRADED_BUDGET_EXHAUSTED", state="HALT")]
    # a window of 0.49 s ending at step 24 (0.8 s) holds steps 10-24 (from 0.333 s)
    summary = before_halt(records, 24, CONFIG, CAP, window_s=0.49)
    assert summary == {
        "window_s": 0.49, "frames": 14,
        # confident: 10-12, 14-18, 23, 24; usable: 19; unusable: 13, 21, 22
        "confident": 10, "usable": 1, "unusable": 3, "jumped": 0,
        # lane_width the weakest in 13 and 21; in 22 parallel, the first of two at 0
        "weakest": {"lane_width": 2, "parallel": 1},
        # 10-12: 3 in a row; then 14 (the outlier 15 does not count), 16-17 (18's
        # REPEATED_OUTLIERS wipes them), 23 (24's halt wipes it)
        "longest_confident_run": 3,
        "at_slope_cap": 1, "outliers": 1, "no_frame": 1,
    }
    assert describe(summary) == (
        "last 0.49 s: 14 frames, 10 confident (at most 3 in a row), 1 usable but not confident, "
        "3 unusable (lane_width 2, parallel 1); 1 at the slope cap; 1 outlier; 1 step without a "
        "frame")


def test_a_clean_window_says_only_the_counts() -> None:
    records = [step(i, seen(i, 0.9)) for i in range(70)]
    summary = before_halt(records, 69, CONFIG, CAP, window_s=1.99)  # steps 10-69
    assert summary["frames"] == 60 and summary["confident"] == 60
    assert summary["longest_confident_run"] == 60
    assert describe(summary) == ("last 1.99 s: 60 frames, 60 confident (at most 60 in a row), "
                                 "0 usable but not confident, 0 unusable")


def test_a_lane_placed_from_one_tape_is_usable_never_confident() -> None:
    """`sides_seen` 1 (perception.one_side: both edges, both_sides 0.5), as the supervisor
    grades it (supervisor.lane_evidence.frame_grade)."""
    placed = replace(seen(0, 0.5), components=MappingProxyType({"both_sides": 0.5}))
    summary = before_halt([step(0, placed)], 0, CONFIG, CAP)
    assert (summary["confident"], summary["usable"], summary["unusable"]) == (0, 1, 0)


def test_a_placed_lane_the_supervisor_called_untrusted_is_unusable_and_said_so() -> None:
    """A lane placed from one tape that jumped where the robot could not have moved it: usable
    by its confidence (0.45), but the supervisor raised LANE_UNTRUSTED on it and took it as no
    lane (supervisor.lane_evidence); the summary counts it as the supervisor did, apart from the
    weakest components."""
    placed = replace(seen(0, 0.45), components=MappingProxyType({"both_sides": 0.5}))
    records = [step(0, placed, "ONE_EDGE_LOST"),
               step(1, replace(placed, frame_index=1, time_s=DT), "ONE_EDGE_LOST",
                    "LANE_UNTRUSTED"),
               step(2, replace(placed, frame_index=2, time_s=2 * DT), "ONE_EDGE_LOST",
                    "LANE_UNTRUSTED"),
               step(3, seen(3, 0.1, lane_width=0.1), "LANE_UNTRUSTED", state="HALT")]
    summary = before_halt(records, 3, CONFIG, CAP)
    assert (summary["confident"], summary["usable"], summary["unusable"]) == (0, 1, 3)
    assert summary["jumped"] == 2 and summary["weakest"] == {"lane_width": 1}
    assert describe(summary) == ("last 2 s: 4 frames, 0 confident (at most 0 in a row), "
                                 "1 usable but not confident, 3 unusable (lane_width 1, "
                                 "placed lane jumped 2)")


def test_sim_prints_the_summary_under_the_halt_and_only_for_a_halt() -> None:
    summary = {"window_s": 2.0, "frames": 60, "confident": 0, "usable": 0, "unusable": 60,
               "weakest": {"both_sides": 60}, "longest_confident_run": 0, "at_slope_cap": 0,
               "outliers": 0, "no_frame": 0}
    metrics = {"scenario": "lane-ends", "controller": "supervised", "seed": 0, "frames": 300,
               "sim_time_s": 10.0, "wall_time_s": 4.0, "halted": True,
               "halt_reason": "LANE_LOST", "halt_position": {"x_m": 1.0, "y_m": 0.0},
               "states_visited": ["HALT", "FOLLOW"], "turns_completed": [],
               "max_cross_track_error_m": 0.01, "crossed_tape": False, "before_halt": summary}
    lines = _summary_lines(metrics)
    assert lines[3] == ("  before the halt: last 2 s: 60 frames, 0 confident (at most 0 in a "
                        "row), 0 usable but not confident, 60 unusable (both_sides 60)")
    never = {**metrics, "halted": False, "halt_reason": None, "before_halt": None}
    assert not any("before the halt" in line for line in _summary_lines(never))


def test_recent_steps_keep_the_window_before_each_halt_after_engaging() -> None:
    """The robot runner keeps no list of its records: RecentSteps keeps the last window_s of
    them, and a copy at each halt after engaging (the run's own; then the closing stop's)."""
    recent = RecentSteps(window_s=0.49)
    states = ["HALT"] * 3 + ["FOLLOW"] * 20 + ["HALT"] * 5 + ["FOLLOW"] * 2 + ["HALT"]
    for i, state in enumerate(states):
        recent.observe(step(i, seen(i, 0.9), state=state))
    # halts at steps 23 (the run's) and 30 (say, the closing stop after a loop of 30 steps)
    window = recent.before_halt(30)
    assert window is not None and [r.frame_index for r in window] == list(range(9, 24))
    latest = recent.before_halt(None)
    assert latest is not None and latest[-1].frame_index == 30
    assert recent.before_halt(23) is None  # no halt within the first 23 steps
    never = RecentSteps()
    never.observe(step(0, seen(0, 0.9), state="HALT"))  # halted from the start: no halt
    assert never.before_halt(None) is None
