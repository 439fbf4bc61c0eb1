"""The clock abstraction: a fake clock moves only when told, and never backwards."""

from __future__ import annotations

import math

import pytest

from lanewarden.supervisor.clock import Clock, FakeClock, MonotonicClock


def test_fake_clock_moves_only_when_advanced() -> None:
    clock: Clock = FakeClock(start=5.0)
    assert clock.now() == clock.now() == 5.0
    assert isinstance(clock, FakeClock)
    assert clock.advance(0.25) == 5.25 and clock.now() == 5.25
    assert clock.advance(0.0) == 5.25


@pytest.mark.parametrize("bad", [-0.001, math.nan, math.inf])
def test_fake_clock_refuses_bad_steps(bad: float) -> None:
    clock = FakeClock()
    with pytest.raises(ValueError, match="dt must be finite and >= 0"):
        clock.advance(bad)
    assert clock.now() == 0.0


def test_monotonic_clock_never_goes_back() -> None:
    clock: Clock = MonotonicClock()
    readings = [clock.now() for _ in range(100)]
    assert readings == sorted(readings)
