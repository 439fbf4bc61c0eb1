"""The state machine: every state x every event, engaging, latching, hysteresis, DEGRADED."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from lanewarden.actuation.base import STOP
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.events import EVENT_TABLE, Event, Response
from lanewarden.supervisor.state_machine import (
    TRANSITIONS,
    StepFacts,
    SupervisorState,
    SupervisorStateMachine,
)
from tests.supervisor.rig import DT, Rig

CONFIG = SupervisorConfig()


def _follow() -> tuple[Rig, float]:
    rig = Rig()
    rig.engage()
    rig.run(15)
    return rig, 0.0


def _turn(sign: float) -> Callable[[], tuple[Rig, float]]:
    def reach() -> tuple[Rig, float]:
        rig = Rig()
        rig.engage()
        rig.run(10)
        target = "TURN_LEFT" if sign > 0 else "TURN_RIGHT"
        for _ in range(60):
            if rig.step(slope_sum=sign * 8.0).state == target:
                return rig, sign * 8.0
        raise AssertionError(f"never reached {target}")

    return reach


def _degraded() -> tuple[Rig, float]:
    rig, _ = _follow()
    assert rig.step(left=False, confidence=0.5).state == "DEGRADED"
    return rig, 0.0


def _halt_latched() -> tuple[Rig, float]:
    rig, _ = _follow()
    assert rig.step(events={Event.OPERATOR_STOP}).state == "HALT"
    rig.run(CONFIG.engage_confident_frames + 2)  # confident lane, but nobody asked to resume
    assert rig.state == "HALT"
    return rig, 0.0


REACH: dict[str, Callable[[], tuple[Rig, float]]] = {
    "FOLLOW": _follow,
    "TURN_LEFT": _turn(+1.0),
    "TURN_RIGHT": _turn(-1.0),
    "DEGRADED": _degraded,
    "HALT": _halt_latched,
}


def _expected_state(state: str, response: Response) -> str:
    if state == "HALT" or response is Response.HALT:
        return "HALT"
    if response is Response.DEGRADE:
        return "DEGRADED"
    return state


def test_reach_covers_every_state() -> None:
    assert set(REACH) == {s.value for s in SupervisorState}


@pytest.mark.parametrize("state", list(REACH))
@pytest.mark.parametrize("event", list(Event), ids=lambda e: e.value)
def test_every_state_x_every_event(state: str, event: Event) -> None:
    rig, slope_sum = REACH[state]()
    twin, _ = REACH[state]()
    assert rig.state == twin.state == state
    out = rig.step(slope_sum=slope_sum, events={event})
    reference = twin.step(slope_sum=slope_sum)  # the same step without the event
    response = EVENT_TABLE[event].response
    expected = _expected_state(state, response)
    assert out.state == expected
    assert event in out.events
    if expected == "HALT":
        assert out.command == STOP  # zero in the same step, from any state
        assert out.halt_reason is not None
        if response is Response.HALT:
            assert out.halt_reason.startswith(event.value)
    elif expected == "DEGRADED":
        assert (
            0.0 < out.command.linear_m_s <= CONFIG.follow_speed_m_s * CONFIG.degraded_speed_fraction
        )
        assert abs(out.command.angular_rad_s) <= CONFIG.degraded_max_angular_rad_s
    else:  # a warning changes nothing about the drive
        assert out.command == reference.command
        assert out.command.linear_m_s > 0.0


# --- engagement and latching -----------------------------------------------------------------


def test_halt_is_initial_and_start_alone_does_not_engage() -> None:
    rig = Rig()
    out = rig.step(start=True, confidence=0.2)  # start, but the lane is not confident
    assert out.state == "HALT" and out.command == STOP
    for _ in range(30):
        assert rig.step(confidence=0.5).state == "HALT"


def test_confident_frames_alone_do_not_engage() -> None:
    rig = Rig()
    for _ in range(3 * CONFIG.engage_confident_frames):
        out = rig.step()
        assert out.state == "HALT" and out.command == STOP


def test_engages_after_exactly_n_confident_frames_and_a_start() -> None:
    rig = Rig()
    n = CONFIG.engage_confident_frames
    states = [rig.step(start=(i == 0)).state for i in range(n + 1)]
    assert states[: n - 1] == ["HALT"] * (n - 1)
    assert states[n - 1] == "FOLLOW"


def test_start_before_confident_lane_waits_and_an_unconfident_frame_restarts_the_count() -> None:
    rig = Rig()
    rig.step(start=True, left=False, confidence=0.0)
    n = CONFIG.engage_confident_frames
    for _ in range(n - 1):
        assert rig.step().state == "HALT"
    assert rig.step(confidence=0.5).state == "HALT"  # below confident: count restarts
    for _ in range(n - 1):
        assert rig.step().state == "HALT"
    assert rig.step().state == "FOLLOW"


def test_halt_is_latched_until_resume_and_a_confident_lane() -> None:
    rig, _ = _follow()
    rig.step(events={Event.BUMPER})
    assert rig.state == "HALT"
    rig.run(3 * CONFIG.engage_confident_frames)
    assert rig.state == "HALT"
    rig.step(resume=True)
    n = CONFIG.engage_confident_frames
    # the confident frames before the resume count: the lane has been good all along
    assert rig.state == "FOLLOW"
    rig.step(events={Event.CLIFF})
    rig.step(resume=True, left=False, right=False, confidence=0.0)
    for _ in range(n - 1):
        assert rig.step().state == "HALT"
    assert rig.step().state == "FOLLOW"


def test_a_new_fault_while_halted_disarms_a_pending_resume() -> None:
    rig, _ = _follow()
    rig.step(events={Event.OPERATOR_STOP})
    rig.step(resume=True, confidence=0.3)  # armed, waiting for a confident lane
    out = rig.step(events={Event.WHEEL_DROP})
    assert out.halt_reason is not None and out.halt_reason.startswith("WHEEL_DROP")
    rig.run(3 * CONFIG.engage_confident_frames)
    assert rig.state == "HALT"


def test_resume_in_the_same_step_as_a_fault_does_not_count() -> None:
    rig, _ = _follow()
    rig.step(events={Event.OPERATOR_STOP})
    rig.step(resume=True, events={Event.BUMPER})
    rig.run(3 * CONFIG.engage_confident_frames)
    assert rig.state == "HALT"


def test_lane_loss_halt_needs_resume_by_default() -> None:
    rig, _ = _follow()
    rig.run(10, left=False, right=False, confidence=0.0)
    assert rig.state == "HALT"
    assert rig.controller.halt_reason is not None
    assert rig.controller.halt_reason.startswith("LANE_LOST")
    rig.run(3 * CONFIG.engage_confident_frames)
    assert rig.state == "HALT"


def test_auto_resume_after_lane_loss_is_opt_in_and_only_for_lane_loss() -> None:
    config = SupervisorConfig(auto_resume_after_lane_loss=True)
    rig = Rig(config)
    rig.engage()
    rig.run(10, left=False, right=False, confidence=0.0)
    assert rig.state == "HALT"
    rig.run(config.engage_confident_frames)
    assert rig.state == "FOLLOW"
    rig.step(events={Event.BUMPER})
    rig.run(3 * config.engage_confident_frames)
    assert rig.state == "HALT"


# --- turning hysteresis --------------------------------------------------------------------


def test_turn_hysteresis_enters_at_enter_and_leaves_below_exit() -> None:
    machine = SupervisorStateMachine(CONFIG)
    t = 0.0

    def tick(slope_sum: float, **kw: object) -> str:
        nonlocal t
        t += DT
        facts = StepFacts(now=t, lane_seen_at_s=t, slope_sum=slope_sum, frame_confident=True, **kw)  # type: ignore[arg-type]
        machine.step(facts)
        return machine.state.value

    tick(0.0, engage_requested=True)
    for _ in range(CONFIG.engage_confident_frames):
        tick(0.0)
    assert machine.state is SupervisorState.FOLLOW
    enter, exit_ = CONFIG.turn_enter_slope_sum, CONFIG.turn_exit_slope_sum
    assert tick(enter - 0.01) == "FOLLOW"
    assert tick(enter) == "TURN_LEFT"
    assert tick(exit_ + 0.01) == "TURN_LEFT"  # inside the band: stays
    assert tick(exit_ - 0.01) == "FOLLOW"
    assert tick(-enter + 0.01) == "FOLLOW"
    assert tick(-enter) == "TURN_RIGHT"
    assert tick(-exit_ - 0.01) == "TURN_RIGHT"
    assert tick(enter + 1.0) == "TURN_LEFT"  # a sign flip goes straight across
    assert tick(-enter - 1.0) == "TURN_RIGHT"
    assert tick(0.0) == "FOLLOW"


def test_transition_table_has_one_trigger_and_no_automatic_transitions() -> None:
    machine = SupervisorStateMachine(CONFIG)
    assert {row["trigger"] for row in TRANSITIONS} == {"tick"}
    assert not hasattr(machine, "to_FOLLOW")
    assert machine.state is SupervisorState.HALT


# --- DEGRADED: recovery and budget ------------------------------------------------------------


def test_degraded_recovers_after_m_confident_frames() -> None:
    rig, _ = _degraded()
    m = CONFIG.recover_confident_frames
    states = [rig.step().state for _ in range(m)]
    assert states == ["DEGRADED"] * (m - 1) + ["FOLLOW"]


def test_degraded_needs_the_higher_confidence_to_recover() -> None:
    rig, _ = _degraded()
    between = (CONFIG.confidence_degrade_below + CONFIG.confidence_confident_min) / 2
    rig.run(3 * CONFIG.recover_confident_frames, confidence=between)
    assert rig.state == "DEGRADED"


def test_degraded_time_budget_halts() -> None:
    rig, _ = _degraded()
    entered = rig.clock.now()
    while rig.step(left=False, confidence=0.5).state == "DEGRADED":
        pass
    assert rig.controller.halt_reason is not None
    assert rig.controller.halt_reason.startswith("DEGRADED_BUDGET_EXHAUSTED")
    spent = rig.clock.now() - entered
    assert CONFIG.degraded_budget_s < spent <= CONFIG.degraded_budget_s + DT + 1e-9


def test_degraded_distance_budget_halts_first_when_it_is_shorter() -> None:
    config = SupervisorConfig(degraded_budget_m=0.025, degraded_budget_s=10.0)
    rig = Rig(config)
    rig.engage()
    rig.run(30)
    rig.step(left=False, confidence=0.5)
    assert rig.state == "DEGRADED"
    travelled = 0.0
    while rig.state == "DEGRADED":
        travelled += rig.outputs[-1].command.linear_m_s * DT
        rig.step(left=False, confidence=0.5)
    assert rig.controller.halt_reason is not None
    assert rig.controller.halt_reason.startswith("DEGRADED_BUDGET_EXHAUSTED")
    assert config.degraded_budget_m < travelled < config.degraded_budget_m + 0.01
