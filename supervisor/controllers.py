"""Choosing a controller by name (`--controller supervised|lecture` wherever one can be chosen), and
the bring-up tool's fixed command. Each runs behind a SafetyGate (built in lanewarden/assembly.py).
"""

from __future__ import annotations

from collections.abc import Callable
from types import MappingProxyType

from lanewarden.actuation.base import VelocityCommand
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, Controller, ControlOutput
from lanewarden.supervisor.controller import SupervisedController
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.events import ordered
from lanewarden.supervisor.lecture import LectureController

CONTROLLERS: MappingProxyType[str, Callable[[SupervisorConfig], Controller]] = MappingProxyType(
    {"supervised": SupervisedController, "lecture": LectureController}
)
DEFAULT_CONTROLLER = "supervised"


def controller_factory(name: str) -> Callable[[SupervisorConfig], Controller]:
    """The controller class called `name`; SupervisorError (one line) for an unknown name."""
    try:
        return CONTROLLERS[name]
    except KeyError:
        choices = ", ".join(CONTROLLERS)
        raise SupervisorError(
            f"--controller: unknown controller {name!r}, expected one of: {choices}"
        ) from None


def make_controller(name: str, config: SupervisorConfig) -> Controller:
    """A fresh controller for one run; SupervisorError (one line) for an unknown name."""
    return controller_factory(name)(config)


class FixedCommand:
    """`lanewarden base drive`: always wants the same command (state BRING_UP). The gate still
    holds it until start, ramps it, and halts it on a hazard."""

    STATE = "BRING_UP"

    def __init__(self, command: VelocityCommand) -> None:
        self.command = command

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        return ControlOutput(command=self.command, state=self.STATE, events=ordered(inputs.events))
