"""The robot's real-time pace (`lanewarden.ticker.Ticker`), on a fake clock whose "sleep" only
advances it: a tick's wait, an overrun, and a wait a stop signal cuts short."""

from __future__ import annotations

import pytest

from lanewarden.supervisor.clock import FakeClock
from lanewarden.ticker import WAKE_SLICE_S, Ticker


def _ticker(period_s: float) -> tuple[Ticker, FakeClock, list[float]]:
    clock = FakeClock(100.0)
    slept: list[float] = []

    def sleep(seconds: float) -> None:
        slept.append(seconds)
        clock.advance(seconds)

    return Ticker(period_s, clock, sleep), clock, slept


def test_a_wait_sleeps_to_the_next_tick_and_an_overrun_restarts_the_schedule() -> None:
    ticker, clock, slept = _ticker(0.05)
    clock.advance(0.01)  # the step took 10 ms
    assert ticker.wait() is False
    assert slept == [pytest.approx(0.04)] and clock.now() == pytest.approx(100.05)
    clock.advance(0.08)  # an overrun: the next tick (100.10) is past
    slept.clear()
    assert ticker.wait() is False
    assert slept == [] and clock.now() == pytest.approx(100.13)
    clock.advance(0.02)
    ticker.wait()  # the schedule restarted at 100.13: the next tick is 100.18
    assert clock.now() == pytest.approx(100.18)


def test_a_stop_signal_ends_the_wait_within_a_slice() -> None:
    """`base drive` waits 50 ms a tick: a Ctrl-C 12 ms into it is acted on by 15 ms (the
    third slice), not at 50 ms."""
    ticker, clock, slept = _ticker(0.05)
    start = clock.now()
    assert ticker.wait(interrupted=lambda: clock.now() - start > 0.012) is True
    assert clock.now() - start == pytest.approx(0.015)
    assert max(slept) <= WAKE_SLICE_S
    # a signal before the wait: no sleep at all
    slept.clear()
    assert ticker.wait(interrupted=lambda: True) is True
    assert slept == []
    # none: the whole tick, in slices
    ticker.restart()
    start = clock.now()
    assert ticker.wait(interrupted=lambda: False) is False
    assert clock.now() - start == pytest.approx(0.05)
