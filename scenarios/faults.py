"""Fault injection: a scenario's `faults:` list turned into actions at the right simulated time.

Each fault kind acts on the real part a real fault would hit, never on the supervisor's logic:
camera faults change what the simulated camera delivers (`SimCamera`), base faults change what the
simulated base reports (`SimBase.inject`, `SimBase.set_link_alive`), an operator stop is the
control loop's own `operator_stop(now)`, and a loop stall makes the simulator skip steps (as a hung
control process would). The supervisor must notice and respond by itself.

`FaultSchedule.apply(now, ...)` is called once per tick before the loop steps; it returns the
names of the faults that began or ended at this tick (for logs). Never reads a clock.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from lanewarden.scenarios.sim_camera import SimCamera
from lanewarden.scenarios.spec import FaultSpec

_BASE_BITS = ("bumper", "cliff", "wheel_drop")


class FaultableBase(Protocol):
    def inject(self, bumper: int = 0, cliff: int = 0, wheel_drop: int = 0) -> None: ...

    def set_link_alive(self, alive: bool) -> None: ...


class OperatorStoppable(Protocol):
    def operator_stop(self, now: float) -> object: ...


@dataclass
class _Active:
    spec: FaultSpec
    started: bool = False
    ended: bool = False

    @property
    def end_s(self) -> float:
        return math.inf if self.spec.duration_s is None else self.spec.at_s + self.spec.duration_s


def camera_pool_size(faults: Sequence[FaultSpec], camera_rate_hz: float) -> int:
    """Frames the simulated camera must keep so the largest injected latency can be served."""
    latency = max((f.latency_s for f in faults if f.kind == "late_frames"), default=0.0)
    return max(4, math.ceil(latency * camera_rate_hz) + 4)


class FaultSchedule:
    """The scenario's faults, started and ended on the simulated clock."""

    def __init__(self, faults: Sequence[FaultSpec]) -> None:
        self._faults = [_Active(f) for f in sorted(faults, key=lambda f: f.at_s)]

    def apply(self, now: float, camera: SimCamera, base: FaultableBase,
              loop: OperatorStoppable) -> list[str]:
        changed: list[str] = []
        eps = 1e-9
        for fault in self._faults:
            if not fault.started and now + eps >= fault.spec.at_s:
                fault.started = True
                changed.append(f"{fault.spec.kind} begins")
                if fault.spec.kind == "operator_stop":
                    loop.operator_stop(now)
                    fault.ended = True
            if fault.started and not fault.ended and now + eps >= fault.end_s:
                fault.ended = True
                changed.append(f"{fault.spec.kind} ends")
        if changed:
            self._set_state(camera, base)
        return changed

    def _active(self, kind: str) -> list[FaultSpec]:
        return [f.spec for f in self._faults if f.started and not f.ended and f.spec.kind == kind]

    def _set_state(self, camera: SimCamera, base: FaultableBase) -> None:
        camera.dropping = bool(self._active("camera_drop"))
        late = self._active("late_frames")
        camera.latency_s = max((f.latency_s for f in late), default=0.0)
        camera.corrupt = bool(self._active("perception_exception"))
        camera.failing = bool(self._active("camera_error"))
        camera.future_s = max((f.latency_s for f in self._active("frame_from_future")),
                              default=0.0)
        frozen = bool(self._active("camera_freeze"))
        if frozen != (camera.frozen):
            camera.freeze(frozen)
        bits = {name: 0 for name in _BASE_BITS}
        for name in _BASE_BITS:
            for spec in self._active(name):
                bits[name] |= spec.bits
        base.inject(**bits)
        base.set_link_alive(not self._active("base_link_loss"))

    @property
    def loop_stalled(self) -> bool:
        """The control process is hung (`loop_stall`): the simulator must not step the loop."""
        return bool(self._active("loop_stall"))

    def active_kinds(self) -> list[str]:
        return sorted({f.spec.kind for f in self._faults if f.started and not f.ended})
