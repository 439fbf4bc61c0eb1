"""One contract, two bases: SimBase (fake clock) and KobukiBase over a pty stand-in (real time).

Each harness gives the same handles: `base`, `now()`, `tick()` (one feedback period passes),
`mark()` + `saw_command(predicate)` (did the motors get a command satisfying it since the mark),
and `set_sensors(...)` (the base's bumper/cliff/wheel-drop bits).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from typing import Protocol

import pytest

from lanewarden.actuation.base import STOP, Base, BaseFeedback, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.actuation.kobuki_base import KobukiBase
from lanewarden.actuation.sim_base import SimBase
from tests.actuation.kobuki_standin import KobukiStandIn

MOVE = VelocityCommand(0.2, 0.0)
DEADLINE_S = 5.0


class Harness(Protocol):
    base: Base

    def now(self) -> float: ...
    def tick(self) -> None: ...
    def mark(self) -> None: ...
    def saw_command(self, predicate: Callable[[VelocityCommand], bool]) -> bool: ...
    def set_sensors(self, bumper: int, cliff: int, wheel_drop: int) -> None: ...


class SimHarness:
    def __init__(self) -> None:
        self.sim = SimBase()
        self.base: Base = self.sim
        self.clock = 100.0

    def now(self) -> float:
        return self.clock

    def tick(self) -> None:
        self.clock += 0.02
        self.sim.advance_to(self.clock)

    def mark(self) -> None:
        pass

    def saw_command(self, predicate: Callable[[VelocityCommand], bool]) -> bool:
        return predicate(self.sim.commanded)

    def set_sensors(self, bumper: int, cliff: int, wheel_drop: int) -> None:
        self.sim.inject(bumper=bumper, cliff=cliff, wheel_drop=wheel_drop)


def as_velocity(speed_mm_s: int, radius_mm: int) -> VelocityCommand:
    """Invert the Kobuki's (speed, radius) roughly, enough to check stop and direction."""
    if radius_mm == 0:
        return VelocityCommand(speed_mm_s / 1000.0, 0.0)
    if radius_mm == 1:
        return VelocityCommand(0.0, speed_mm_s / 115.0)
    omega = speed_mm_s / (radius_mm + math.copysign(115.0, radius_mm))
    return VelocityCommand(omega * radius_mm / 1000.0, omega)


class KobukiHarness:
    def __init__(self, standin: KobukiStandIn) -> None:
        self.standin = standin
        self.kobuki = KobukiBase.open(standin.port)
        self.base: Base = self.kobuki
        self._mark = 0

    def now(self) -> float:
        return time.monotonic()

    def tick(self) -> None:
        seen = self.kobuki.packets_received
        assert self.kobuki.wait_for(lambda b: b.packets_received > seen, DEADLINE_S)

    def mark(self) -> None:
        self._mark = len(self.standin.snapshot())

    def saw_command(self, predicate: Callable[[VelocityCommand], bool]) -> bool:
        def seen(packets: list) -> bool:  # type: ignore[type-arg]
            controls = [p.base_control for p in packets[self._mark:]]
            return any(c is not None and predicate(as_velocity(*c)) for c in controls)
        return self.standin.wait_for(seen, DEADLINE_S)

    def set_sensors(self, bumper: int, cliff: int, wheel_drop: int) -> None:
        self.standin.set_sensors(bumper=bumper, cliff=cliff, wheel_drop=wheel_drop)


@pytest.fixture(params=["sim", "kobuki"])
def harness(request: pytest.FixtureRequest) -> Iterator[Harness]:
    if request.param == "sim":
        yield SimHarness()
        return
    with KobukiStandIn() as standin:
        kobuki = KobukiHarness(standin)
        try:
            yield kobuki
        finally:
            kobuki.kobuki.close()


def drive_until(harness: Harness, command: VelocityCommand,
                predicate: Callable[[BaseFeedback], bool], ticks: int = 250) -> BaseFeedback:
    """Send `command` every tick (a control loop's heartbeat) until the feedback satisfies it."""
    for _ in range(ticks):
        harness.base.send(command, harness.now())
        harness.tick()
        feedback = harness.base.feedback(harness.now())
        if predicate(feedback):
            return feedback
    pytest.fail(f"feedback never satisfied the condition while sending {command}")


def test_initial_command_is_stop(harness: Harness) -> None:
    for _ in range(5):
        harness.tick()
    assert harness.saw_command(lambda c: c.is_stop)
    if isinstance(harness, SimHarness):
        assert harness.sim.commanded == STOP and harness.sim.velocity == STOP
    if isinstance(harness, KobukiHarness):
        assert harness.standin.wait_for(
            lambda pkts: sum(p.base_control is not None for p in pkts) >= 3, DEADLINE_S)
        assert {c for _, c in harness.standin.base_controls()} == {(0, 0)}


def test_send_moves_and_stop_stops(harness: Harness) -> None:
    harness.mark()
    for _ in range(25):  # a control loop's heartbeat for 0.5 s: longer than any start ramp
        harness.base.send(MOVE, harness.now())
        harness.tick()
    assert harness.saw_command(lambda c: c.linear_m_s == pytest.approx(0.2, abs=1e-3))
    harness.mark()
    harness.base.send(STOP, harness.now())
    assert harness.saw_command(lambda c: c.is_stop)


def test_feedback_type_and_monotonic_time(harness: Harness) -> None:
    harness.tick()
    times = []
    for _ in range(5):
        feedback = harness.base.feedback(harness.now())
        assert isinstance(feedback, BaseFeedback)
        assert feedback.received_at_s is not None
        times.append(feedback.received_at_s)
        harness.tick()
    assert times == sorted(times) and times[-1] > times[0]
    assert feedback.battery_v is not None and feedback.battery_v > 0.0


@pytest.mark.parametrize("bits", [{"bumper": 5, "cliff": 0, "wheel_drop": 0},
                                  {"bumper": 0, "cliff": 2, "wheel_drop": 0},
                                  {"bumper": 0, "cliff": 0, "wheel_drop": 3}])
def test_injected_hazards_show_in_feedback_until_cleared(harness: Harness,
                                                         bits: dict[str, int]) -> None:
    def shows(fb: BaseFeedback) -> bool:
        return (fb.bumper, fb.cliff, fb.wheel_drop) == (
            bits["bumper"], bits["cliff"], bits["wheel_drop"])

    harness.set_sensors(**bits)
    drive_until(harness, STOP, shows)
    harness.set_sensors(bumper=0, cliff=0, wheel_drop=0)
    drive_until(harness, STOP, lambda fb: (fb.bumper, fb.cliff, fb.wheel_drop) == (0, 0, 0))


def test_driving_forward_advances_odometry(harness: Harness) -> None:
    feedback = drive_until(harness, MOVE, lambda fb: fb.odometry.x_m > 0.01)
    assert abs(feedback.odometry.y_m) < 1e-3 and abs(feedback.odometry.theta_rad) < 1e-3
    harness.base.send(STOP, harness.now())


def test_non_finite_command_stops_and_raises(harness: Harness) -> None:
    harness.mark()
    harness.base.send(MOVE, harness.now())
    assert harness.saw_command(lambda c: not c.is_stop)
    harness.mark()
    with pytest.raises(ActuationError, match="linear_m_s = nan"):
        harness.base.send(VelocityCommand(math.nan, 0.0), harness.now())
    assert harness.saw_command(lambda c: c.is_stop)


def test_close_stops_and_is_idempotent(harness: Harness) -> None:
    harness.mark()
    harness.base.send(MOVE, harness.now())
    assert harness.saw_command(lambda c: not c.is_stop)
    harness.mark()
    harness.base.close()
    assert harness.saw_command(lambda c: c.is_stop)
    harness.base.close()
    with pytest.raises(ActuationError, match="closed"):
        harness.base.send(MOVE, harness.now())
